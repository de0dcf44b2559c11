"""VehicleLink against the built-in simulator over an in-memory pipe, on the simulator's clock."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from chaser_bt.vehicle import (
    CommandStatus,
    LandedState,
    VehicleLink,
    VehicleQuiet,
    byte_pipe,
)

sitl_scenario = pytest.importorskip("sitl.world.scenario")
sitl_simulator = pytest.importorskip("sitl.simulator")

PATROL = Path(__file__).resolve().parents[2] / "sitl" / "scenarios" / "patrol.yaml"


@pytest.fixture
def sim_link():
    sim = sitl_simulator.Simulator(sitl_scenario.load_scenario(PATROL), seed=3)
    a, b = byte_pipe()
    sim.attach(b)
    link = VehicleLink.over_pipe(a, monotonic=lambda: sim.time_s)
    return sim, link


def test_arm_issued_at_boot_waits_until_arducopter_is_ready(sim_link):
    sim, link = sim_link
    guided = link.set_mode("GUIDED")
    arm = link.arm()
    link.wait(guided, 60.0, pump=sim.step)
    assert arm.status is CommandStatus.WAITING
    link.wait(arm, 120.0, pump=sim.step)
    assert sim.time_s >= sim.scenario.boot.prearm_ok_s and arm.attempts == 1
    assert link.state.armed and link.state.ready_to_arm


def test_takeoff_refused_when_disarmed_carries_the_autopilots_answer(sim_link):
    sim, link = sim_link
    link.wait(lambda s: s.ready_to_arm, 120.0, pump=sim.step)
    link.wait(link.set_mode("GUIDED"), 5.0, pump=sim.step)
    cmd = link.takeoff(10.0)
    link.wait(lambda: cmd.done, 5.0, pump=sim.step)
    assert cmd.status is CommandStatus.FAILED and cmd.reason.startswith("MAV_RESULT_")


def test_flight_guided_goto_alt_hold_and_rtl_matches_the_simulated_truth(sim_link):
    sim, link = sim_link
    link.wait(link.set_mode("GUIDED"), 60.0, pump=sim.step)
    link.wait(link.arm(), 120.0, pump=sim.step)
    link.wait(link.takeoff(10.0), 5.0, pump=sim.step)
    link.wait(lambda s: s.alt_rel_m > 9.5, 60.0, pump=sim.step)
    assert link.state.airborne and link.state.landed_state in (LandedState.TAKEOFF, LandedState.IN_AIR)

    target = np.array([30.0, 40.0, 15.0])
    link.goto_enu(target, yaw_enu_rad=0.0)  # face east
    link.wait(lambda s: np.linalg.norm(s.position_enu - target) < 1.0, 60.0, pump=sim.step)
    sim.run_until(sim.time_s + 3.0)
    link.poll()
    # The link's ENU (origin = the home the vehicle reports) agrees with the simulator's truth.
    assert link.state.position_enu == pytest.approx(sim.truth.pos_enu, abs=0.5)
    assert link.state.yaw_enu_rad == pytest.approx(0.0, abs=math.radians(5))
    truth_nose = sim.truth.attitude.apply([1.0, 0.0, 0.0])
    assert link.state.attitude.apply([1.0, 0.0, 0.0]) == pytest.approx(truth_nose, abs=0.05)

    link.hover()
    link.wait(link.set_mode("ALT_HOLD"), 5.0, pump=sim.step)
    link.rc_override(pitch=1300, throttle=1500)  # nose down: forward, i.e. east
    sim.run_until(sim.time_s + 4.0)
    link.poll()
    assert link.state.velocity_enu[0] > 2.0 and abs(link.state.alt_rel_m - 15.0) < 2.5  # held by the throttle override

    link.hover()
    link.wait(link.rtl(), 5.0, pump=sim.step)
    link.wait(lambda s: not s.armed, 300.0, pump=sim.step)
    link.wait(lambda s: s.landed_state is LandedState.ON_GROUND, 2.0, pump=sim.step)  # EXTENDED_SYS_STATE at 2 Hz
    assert np.linalg.norm(link.state.position_enu[:2]) < 2.0
    assert link.counters.bad_packets == 0 and link.counters.unmatched_acks == 0


def test_simulated_link_loss_makes_the_link_quiet(sim_link):
    sim, link = sim_link
    link.wait(lambda s: s.home is not None, 10.0, pump=sim.step)
    sim.link_up = False
    t_cut = sim.time_s
    with pytest.raises(VehicleQuiet, match="quiet for"):
        for _ in range(int(10.0 / sim.dt)):
            sim.step()
            link.poll()
    assert sim.time_s - t_cut == pytest.approx(link.config.quiet_timeout_s, abs=0.5)
