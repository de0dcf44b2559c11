"""The link against a simulator running 10x faster than the ground station's clock.

The link's own clock here is the simulator's time divided by 10, exactly what a wall clock reads
beside a simulator at ``--speedup 10``. The vehicle judges the GCS heartbeat (FS_GCS_TIMEOUT 5 s)
and the RC override (RC_OVERRIDE_TIME 3 s) in its own time, so both must keep to it.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from chaser_bt.vehicle import LinkConfig, VehicleLink, byte_pipe
from chaser_bt.vehicle.cadence import Cadence
from sitl.simulator import Simulator
from sitl.vehicle.setup import BootParams
from sitl.world.scenario import load_scenario

PATROL = Path(__file__).resolve().parents[2] / "sitl" / "scenarios" / "patrol.yaml"
SPEEDUP = 10.0


def _flying_at_speedup(timers_on_vehicle_time: bool):
    scenario = dataclasses.replace(load_scenario(PATROL), boot=BootParams(1.0, 2.0, 3.0))
    sim = Simulator(scenario, seed=5)
    assert sim.autopilot.params.get("FS_GCS_ENABLE") == 1
    a, b = byte_pipe()
    sim.attach(b)
    config = LinkConfig(target_sysid=sim.endpoint.sysid, timers_on_vehicle_time=timers_on_vehicle_time)
    link = VehicleLink.over_pipe(a, config, monotonic=lambda: sim.time_s / SPEEDUP)
    sent: dict[str, list[float]] = {"HEARTBEAT": [], "RC_CHANNELS_OVERRIDE": []}
    link.add_listener(on_send=lambda m: sent.get(m.get_type(), []).append(sim.time_s))

    def step() -> None:
        sim.step()
        link.poll()

    link.wait(link.set_mode("GUIDED"), 30.0, pump=step)
    link.wait(link.arm(), 30.0, pump=step)
    link.wait(link.takeoff(10.0), 30.0, pump=step)
    # Up to 10 m, or into GCS failsafe on the way (the take-off waits out ArduCopter's arming delay,
    # long enough for a link on its own clock alone to miss the vehicle's heartbeat timeout).
    link.wait(lambda s: s.alt_rel_m > 9.0 or sim.autopilot.fs_gcs, 10.0, pump=step)
    return sim, link, sent, step


def _gaps(times: list[float]) -> list[float]:
    return [b - a for a, b in zip(times, times[1:])]


def test_heartbeat_keeps_the_vehicles_time_at_10x_and_no_gcs_failsafe():
    sim, link, sent, step = _flying_at_speedup(True)
    start = sim.time_s
    while sim.time_s < start + 30.0:
        step()
    assert not sim.autopilot.fs_gcs and link.state.mode == "GUIDED"
    beats = [t for t in sent["HEARTBEAT"] if t >= start - 1.0]
    assert max(_gaps(beats)) <= 1.0 + 0.1  # a period of vehicle time, to the next 20 ms step (+ poll)
    assert len(beats) >= 29


def test_rc_override_resent_at_5hz_of_vehicle_time_at_10x():
    sim, link, sent, step = _flying_at_speedup(True)
    link.wait(link.set_mode("ALT_HOLD"), 10.0, pump=step)
    link.rc_override(1500, 1500, 1500, 1500)
    start = sim.time_s
    while sim.time_s < start + 10.0:
        step()
    resends = [t for t in sent["RC_CHANNELS_OVERRIDE"] if t >= start]
    assert max(_gaps(resends)) <= 0.2 + 0.05
    assert link.state.mode == "ALT_HOLD" and not sim.autopilot.fs_gcs


def test_on_the_link_clock_alone_the_vehicle_sees_a_heartbeat_every_10_s():
    """What the option is for: without it the 10x vehicle goes into GCS failsafe (RTL)."""
    sim, _, _, step = _flying_at_speedup(False)
    start = sim.time_s
    while sim.time_s < start + 15.0 and not sim.autopilot.fs_gcs:
        step()
    assert sim.autopilot.fs_gcs


# -- the cadence on its own, against hand-worked schedules --------------------------------------


def test_cadence_on_the_link_clock_alone_keeps_a_fixed_grid():
    c = Cadence(1.0, link_t=0.0)
    fired = [t for t in (0.0, 0.5, 1.05, 1.9, 2.0, 2.5, 6.2, 6.9, 7.2) if c.fire(t)]
    assert fired == [0.0, 1.05, 2.0, 6.2, 7.2]  # late polls keep the grid; a long pause restarts it


def test_cadence_fires_on_whichever_clock_first_reaches_its_period():
    c = Cadence(1.0, link_t=0.0)
    assert c.fire(0.0, math.nan)  # the vehicle's time not known yet: the link's clock
    assert not c.fire(0.01, 0.0)  # first vehicle time seen: counting starts there
    assert not c.fire(0.05, 0.9)
    assert c.fire(0.1, 1.0)  # a second of vehicle time at 10x
    assert not c.fire(0.15, 1.5) and c.fire(0.2, 2.0)
    # The vehicle's time stalls (a quiet vehicle): the link's clock keeps the heartbeat going.
    assert not c.fire(1.1, 2.0) and c.fire(1.2, 2.0) and not c.fire(2.1, 2.0) and c.fire(2.2, 2.0)


def test_cadence_restarts_when_the_vehicle_reboots_and_after_an_out_of_turn_send():
    c = Cadence(1.0, link_t=0.0)
    assert c.fire(0.0, 100.0) is True
    assert not c.fire(0.1, 0.5)  # vehicle time went back: count from 0.5
    assert c.fire(0.2, 1.5)
    c.restart(0.3, 1.7)
    assert not c.fire(0.4, 2.6) and c.fire(0.5, 2.7)


def test_cadence_rejects_a_non_positive_period():
    with pytest.raises(ValueError, match="period_s"):
        Cadence(0.0, 0.0)
