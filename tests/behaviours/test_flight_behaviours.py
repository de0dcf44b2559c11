"""Each flight behaviour flown against the simulator, judged by the simulator's ground truth."""

from __future__ import annotations

import numpy as np
import py_trees
import pytest
from flight_helpers import fly, runner_for, take_off

from chaser_bt.vehicle import LinkConfig
from sitl.bench.in_process import InProcessVehicle

Status = py_trees.common.Status


def horizontal(pos) -> np.ndarray:
    return np.asarray(pos, dtype=float)[:2]


def test_arm_and_takeoff_waits_for_readiness_then_climbs(vehicle, scenario):
    status, runner = fly(vehicle, "ArmAndTakeoff: {altitude_m: 15}", timeout_s=150)
    assert status == Status.SUCCESS, runner.tip_message()
    # The vehicle boots not ready to arm; the link waited for the pre-arm bit instead of failing.
    assert vehicle.sim.time_s > scenario.boot.prearm_ok_s
    assert vehicle.sim.truth.pos_enu[2] == pytest.approx(15.0, abs=1.5)
    assert vehicle.link.state.mode == "GUIDED" and vehicle.link.state.armed


def test_arm_and_takeoff_fails_with_a_reason_when_never_ready(scenario):
    impatient = InProcessVehicle(scenario, seed=7, link_config=LinkConfig(ready_timeout_s=5.0))
    status, runner = fly(impatient, "ArmAndTakeoff: {altitude_m: 15}", timeout_s=60)
    assert status == Status.FAILURE
    # The bounded wait for readiness ran out before GUIDED could even be entered; the reason says so.
    assert "failed" in runner.tree.root.feedback_message and "EKF" in runner.tree.root.feedback_message
    assert not impatient.sim.autopilot.armed


def test_goto_reaches_an_enu_waypoint(vehicle):
    take_off(vehicle, 12)
    status, runner = fly(vehicle, "GoTo: {waypoint: [40, -25, 18], acceptance_radius_m: 1.5}", timeout_s=90)
    assert status == Status.SUCCESS, runner.tip_message()
    np.testing.assert_allclose(vehicle.sim.truth.pos_enu, [40, -25, 18], atol=2.5)


def test_goto_speed_holds_after_velocity_control(vehicle):
    """A GoTo's speed_mps reaches the autopilot after its first position target: ArduCopter (and the
    simulator, like it) sets the speed back to WPNAV_SPEED, 10 m/s, on entering position control from
    velocity control, so a speed sent first would be lost and the leg flown at 10 m/s."""
    take_off(vehicle, 12)
    vehicle.link.velocity_enu([3.0, 0.0, 0.0])  # velocity control, as after a follow or a launch
    vehicle.run_until(lambda: False, 2.0)
    runner = runner_for(vehicle, "GoTo: {waypoint: [400, 0, 12], speed_mps: 14}")
    speeds = []

    def tick() -> bool:
        runner.tick_if_due()
        speeds.append(float(np.hypot(*vehicle.sim.truth.vel_enu[:2])))
        return runner.finished

    vehicle.run_until(tick, 20.0)
    assert max(speeds) == pytest.approx(14.0, abs=0.6)


def test_goto_reaches_a_global_waypoint(vehicle, scenario):
    take_off(vehicle, 12)
    target = vehicle.sim.autopilot.frame.to_geodetic((-30.0, 35.0, 0.0))  # 30 m west, 35 m north of home
    body = f"GoTo: {{frame: global, waypoint: [{target.lat_deg:.8f}, {target.lon_deg:.8f}, 15]}}"
    status, runner = fly(vehicle, body, timeout_s=90)
    assert status == Status.SUCCESS, runner.tip_message()
    np.testing.assert_allclose(vehicle.sim.truth.pos_enu, [-30, 35, 15], atol=2.5)


def test_goto_fails_when_the_vehicle_leaves_guided(vehicle):
    take_off(vehicle, 12)
    runner = runner_for(vehicle, "GoTo: {waypoint: [150, 0, 12]}")
    assert vehicle.fly(runner, 3.0) == Status.RUNNING  # under way
    vehicle.link.set_mode("BRAKE")  # the pilot takes over
    assert vehicle.fly(runner, 10.0) == Status.FAILURE
    assert "BRAKE" in runner.tree.root.feedback_message


def test_hover_holds_position_for_its_duration(vehicle):
    take_off(vehicle, 12)
    start_t, start_pos = vehicle.sim.time_s, horizontal(vehicle.sim.truth.pos_enu)
    status, runner = fly(vehicle, "Hover: {duration_s: 8}", timeout_s=30)
    assert status == Status.SUCCESS, runner.tip_message()
    assert vehicle.sim.time_s - start_t == pytest.approx(8.0, abs=0.6)
    assert np.linalg.norm(horizontal(vehicle.sim.truth.pos_enu) - start_pos) < 1.5


def test_halting_a_goto_leaves_the_vehicle_hovering(vehicle):
    take_off(vehicle, 12)
    # Timeout halts GoTo after 4 s; the halted leaf must replace its target with a hover.
    status, runner = fly(vehicle, "Timeout:\n  msec: 4000\n  child:\n    GoTo: {waypoint: [300, 0, 12]}", timeout_s=20)
    assert status == Status.FAILURE
    vehicle.run_until(lambda: False, 12.0)  # let it brake
    assert np.linalg.norm(vehicle.sim.truth.vel_enu) < 0.5
    assert vehicle.sim.truth.pos_enu[0] < 120  # it stopped long before the 300 m waypoint


def test_rtl_returns_home_lands_and_disarms(vehicle):
    take_off(vehicle, 12)
    status, _ = fly(vehicle, "GoTo: {waypoint: [50, 30, 12]}", timeout_s=60)
    assert status == Status.SUCCESS
    status, runner = fly(vehicle, "RTL: {wait_landed: true}", timeout_s=180)
    assert status == Status.SUCCESS, runner.tip_message()
    truth = vehicle.sim.truth
    assert truth.on_ground and not vehicle.sim.autopilot.armed
    assert np.linalg.norm(horizontal(truth.pos_enu)) < 3.0


def test_land_descends_where_it_is_and_disarms(vehicle):
    take_off(vehicle, 12)
    fly(vehicle, "GoTo: {waypoint: [-20, 25, 12]}", timeout_s=60)
    status, runner = fly(vehicle, "Land", timeout_s=120)
    assert status == Status.SUCCESS, runner.tip_message()
    assert vehicle.sim.truth.on_ground and not vehicle.sim.autopilot.armed
    np.testing.assert_allclose(horizontal(vehicle.sim.truth.pos_enu), [-20, 25], atol=2.5)


def test_rtl_without_waiting_succeeds_once_accepted(vehicle):
    take_off(vehicle, 12)
    status, _ = fly(vehicle, "RTL: {wait_landed: false}", timeout_s=10)
    assert status == Status.SUCCESS
    assert vehicle.sim.autopilot.mode == "RTL" and vehicle.sim.autopilot.armed


@pytest.mark.parametrize("body", ["RTL: {wait_landed: true}", "RTL: {wait_landed: false}", "Land"])
def test_rtl_and_land_fail_on_a_vehicle_that_never_flew(vehicle, body):
    """Disarmed on the ground, "landed and disarmed" would report a flight that never happened."""
    assert vehicle.run_until(lambda: vehicle.link.frame is not None, 30.0)
    status, runner = fly(vehicle, body, timeout_s=10)
    assert status == Status.FAILURE
    assert "disarmed on the ground" in runner.tree.root.feedback_message
    assert vehicle.sim.autopilot.mode != "RTL" and vehicle.sim.autopilot.mode != "LAND"  # nothing was commanded


def test_rtl_succeeds_for_a_vehicle_armed_on_the_ground(vehicle):
    """Armed counts as a flight: ArduCopter's RTL disarms a copter that has not taken off yet."""
    vehicle.link.wait(vehicle.link.set_mode("GUIDED"), 60.0, pump=vehicle.step)
    vehicle.link.wait(vehicle.link.arm(), 120.0, pump=vehicle.step)
    status, runner = fly(vehicle, "RTL: {wait_landed: true}", timeout_s=30)
    assert status == Status.SUCCESS, runner.tip_message()
    assert not vehicle.sim.autopilot.armed


@pytest.mark.parametrize("body", ["RTL: {wait_landed: true}", "Land"])
def test_a_disarm_in_the_air_fails_rtl_and_land_as_a_crash(scenario, body):
    """A second ground station force-disarms the aircraft at 20 m: it falls, and nothing says "landed"."""
    import dataclasses

    from sitl.vehicle.setup import Fault

    at_s = 57.0  # the climb to 20 m ends at about 53.4 s (seed 7)
    v = InProcessVehicle(dataclasses.replace(scenario, faults=(Fault(at_s, "disarm"),)), seed=7)
    take_off(v, 20)
    assert v.sim.time_s < at_s - 1.0
    runner = runner_for(v, body)
    status = v.fly(runner, 30.0)
    assert status == Status.FAILURE
    assert "disarmed in the air at" in runner.tree.root.feedback_message
    assert v.sim.time_s < at_s + 2.0  # the next heartbeat, not the impact
    assert v.run_until(lambda: v.sim.truth.on_ground, 10.0) and v.sim.truth.crashed  # the truth agrees


def test_arm_and_takeoff_joins_a_vehicle_already_flying_in_another_mode(vehicle):
    """A second run on an aircraft a first run left hovering in LOITER, before its position is known."""
    take_off(vehicle, 12)
    vehicle.link.wait(vehicle.link.set_mode("LOITER"), 10.0, pump=vehicle.step)
    start = horizontal(vehicle.sim.truth.pos_enu)
    vehicle.link.state.position_enu = np.full(3, np.nan)  # as on a fresh link: no position in the frame yet
    status, runner = fly(vehicle, "ArmAndTakeoff: {altitude_m: 25}", timeout_s=60)
    assert status == Status.SUCCESS, runner.tip_message()
    assert vehicle.sim.autopilot.mode == "GUIDED" and vehicle.sim.autopilot.armed
    assert vehicle.sim.truth.pos_enu[2] == pytest.approx(25.0, abs=1.5)
    np.testing.assert_allclose(horizontal(vehicle.sim.truth.pos_enu), start, atol=2.0)  # straight up


def test_arm_and_takeoff_fails_at_once_when_the_mode_is_taken_away(scenario):
    """The operator's ground station switches to RTL mid-climb: the climb is not ours any more."""
    import dataclasses

    from sitl.vehicle.setup import GroundStationEvent

    at_s = 48.0  # ready to arm at 40 s; climbing to 60 m at 2.5 m/s lasts well past this
    taken = dataclasses.replace(scenario, ground_station=(GroundStationEvent(at_s, "RTL"),))
    v = InProcessVehicle(taken, seed=7)
    runner = runner_for(v, "ArmAndTakeoff: {altitude_m: 60}")
    assert v.fly(runner, at_s - 0.5) == Status.RUNNING
    assert v.link.state.airborne and v.link.state.mode == "GUIDED"
    assert v.fly(runner, 2.0) == Status.FAILURE
    assert v.sim.time_s < at_s + 1.5  # the next heartbeat or two, not the disarm a minute later
    assert "mode taken away (RTL)" in runner.tree.root.feedback_message
    assert v.sim.autopilot.mode == "RTL" and v.sim.autopilot.armed  # RTL left in charge


def test_goto_refuses_a_two_number_waypoint_from_the_blackboard_and_hovers(vehicle):
    # validate cannot see a wired value; GoTo checks it against its port before sending anything.
    take_off(vehicle, 12)
    start = horizontal(vehicle.sim.truth.pos_enu)
    body = (
        "Sequence:\n  children:\n    - SetBlackboard: {output_key: wp, value: [20.0, 0.0]}\n"
        "    - GoTo: {waypoint: '{wp}'}"
    )
    status, runner = fly(vehicle, body, timeout_s=10)
    assert status == Status.FAILURE
    assert "waypoint needs 3 items, got 2: [20.0, 0.0]" in runner.tip_message()
    assert np.linalg.norm(horizontal(vehicle.sim.truth.pos_enu) - start) < 1.5


def _climb_track(vehicle, body: str) -> tuple[Status, list[np.ndarray]]:
    """Fly ``body`` to the end, sampling the true position at every tick."""
    runner = runner_for(vehicle, body)
    track: list[np.ndarray] = []
    runner.on_tick(lambda _changes: track.append(vehicle.sim.truth.pos_enu.copy()))
    status = vehicle.fly(runner, 150.0)
    assert status == Status.SUCCESS, runner.tip_message()
    return status, track


def test_climb_towards_the_cue_beside_the_take_off_once_clear_of_the_ground(scenario):
    """Paper state 2: the radar cue updates where to fly while the climb goes on."""
    from chaser_bt.cue import TargetCue

    straight = InProcessVehicle(scenario, seed=7)
    _, up = _climb_track(straight, "ArmAndTakeoff: {altitude_m: 30}")
    assert np.linalg.norm(horizontal(up[-1])) < 1.0

    cue = TargetCue(t=0.0, position_enu=np.array([0.0, 300.0, 30.0]), covariance_enu=np.eye(3), source="radar")
    for max_age, steered in ((1e6, True), (0.5, False)):  # a fresh cue, then one already stale
        v = InProcessVehicle(scenario, seed=7)
        py_trees.blackboard.Blackboard.storage["/target/cue"] = cue
        _, track = _climb_track(v, f"""
Parallel:
  success_count: 1
  failure_count: 1
  children:
    - ArmAndTakeoff: {{altitude_m: 30}}
    - ClimbTowardsCue: {{altitude_m: 30, clearance_m: 10, standoff_m: 20, speed_mps: 12, max_age_s: {max_age}}}
""")
        end = track[-1]
        assert end[2] >= 29.0
        if not steered:
            assert np.linalg.norm(horizontal(end)) < 1.0
            continue
        # Towards the cue (north), and not a metre sideways before 10 m up (give the 0.1 s tick
        # and the lean's first metre half a metre of height).
        assert end[1] > 20.0 and abs(end[0]) < 0.1 * end[1]
        first_move = next(p for p in track if np.linalg.norm(horizontal(p)) > 1.0)
        assert first_move[2] > 9.5
        # The altitude came no later than straight up: the axes are shaped independently.
        assert len(track) <= len(up) + 5


@pytest.mark.parametrize("leaf", [
    "FlyToCue: {standoff_m: 20, min_alt_m: 20, height_above_m: 0, max_age_s: 1e6, stall_s: 15}",
    "RHCSearch: {half_width_m: 400, spacing_m: 20, horizon: 3, stall_s: 15}",
])
def test_a_moving_goal_the_fence_refuses_fails_the_leaf_with_the_cause(scenario, leaf):
    # ArduCopter's fence (60 m circle) refuses GUIDED targets outside it and holds: the cue 300 m north
    # is never reached, and the leaf fails within its stall bound instead of chasing it for the battery.
    import dataclasses

    from chaser_bt.cue import TargetCue

    fenced = InProcessVehicle(dataclasses.replace(scenario, params={**scenario.params, "FENCE_ENABLE": 1,
                                                                    "FENCE_RADIUS": 60}), seed=7)
    take_off(fenced, 20)
    py_trees.blackboard.Blackboard.storage["/target/cue"] = TargetCue(
        t=fenced.clock.now(), position_enu=np.array([0.0, 300.0, 20.0]), covariance_enu=np.diag([30.0, 30.0, 10.0]) ** 2,
        source="radar")
    start = fenced.sim.time_s
    status, runner = fly(fenced, leaf, timeout_s=60)
    assert status == Status.FAILURE, runner.tip_message()
    assert fenced.sim.time_s - start < 20.0
    message = runner.tree.root.feedback_message
    assert message.startswith("no progress for 15 s") and "fence" in message, message
    assert np.hypot(*fenced.sim.truth.pos_enu[:2]) < 60.0  # it never left the fence


def test_a_cue_outside_the_command_envelope_fails_the_leaf_and_the_aircraft_holds(vehicle):
    # One radar report at range 1e7 m became a cue: the goal is never sent, the leaf says why, and its
    # exit's hold keeps the aircraft where it was.
    from chaser_bt.cue import TargetCue

    take_off(vehicle, 20)
    before = vehicle.sim.truth.pos_enu.copy()
    py_trees.blackboard.Blackboard.storage["/target/cue"] = TargetCue(
        t=vehicle.clock.now(), position_enu=np.array([0.0, 1e7, 6e6]), covariance_enu=np.eye(3), source="radar")
    sent: list = []
    vehicle.link.add_listener(on_send=sent.append)
    status, runner = fly(vehicle, "FlyToCue: {max_age_s: 1e6}", timeout_s=10)
    assert status == Status.FAILURE
    assert runner.tree.root.feedback_message.startswith("command not sent: position target 9999970 m from home")  # 30 m short
    assert runner.tree.root.feedback_message.endswith("(hover sent)")
    assert all(abs(m.alt) < 100 for m in sent if m.get_type() == "SET_POSITION_TARGET_GLOBAL_INT")
    vehicle.fly(runner_for(vehicle, "Hover: {duration_s: 5}"), 6.0)
    assert np.linalg.norm(vehicle.sim.truth.pos_enu - before) < 2.0
