"""The hand-back at the end of a run: the hold is sent, and seen to take effect, or the run says it was not."""

from __future__ import annotations

import dataclasses

import numpy as np
import py_trees
from flight_helpers import runner_for, take_off

from sitl.bench.in_process import InProcessVehicle
from sitl.vehicle.setup import Fault

Status = py_trees.common.Status


def _mid_leg(vehicle: InProcessVehicle):
    take_off(vehicle, 15)
    runner = runner_for(vehicle, "GoTo: {waypoint: [150, 0, 15]}")
    assert vehicle.fly(runner, 6.0) == Status.RUNNING
    assert np.hypot(*vehicle.sim.truth.vel_enu[:2]) > 3.0  # under way
    return runner


def test_a_stop_mid_leg_is_seen_to_hold(vehicle):
    runner = _mid_leg(vehicle)
    runner.stop("interrupted by the operator")
    seen = runner.confirm_hold(idle=vehicle.step)
    assert seen.startswith("hold confirmed: GUIDED at"), seen
    assert np.hypot(*vehicle.sim.truth.vel_enu[:2]) < 1.5  # the truth agrees: braking done
    stopped_at = vehicle.sim.truth.pos_enu.copy()
    assert vehicle.run_until(lambda: False, 10.0) is False  # ten more seconds, no new command
    assert np.linalg.norm(vehicle.sim.truth.pos_enu[:2] - stopped_at[:2]) < 3.0  # it stays


def test_a_hold_that_cannot_reach_the_vehicle_is_reported_not_confirmed(scenario):
    # The radio dies as the operator stops the run: no hold arrives, and the run must not claim one.
    v = InProcessVehicle(dataclasses.replace(scenario, faults=(Fault(57.0, "link_loss"),)), seed=7)
    runner = _mid_leg(v)
    assert v.sim.time_s >= 57.0
    runner.stop("interrupted by the operator")
    seen = runner.confirm_hold(idle=v.step)
    assert seen.startswith("hold NOT confirmed"), seen
