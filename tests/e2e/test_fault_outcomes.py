"""The fault battery: the patrol flown on the built-in simulator with one fault each, judged twice.

The mission's own outcome (``mission_outcome``, from telemetry) must say what happened; the
simulator's truth (the report's ``outcome``, ``landed_dist_m``) says where the aircraft ended. A
false success, or an aircraft left unsafe, fails the test.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from sitl.bench.rehearsal import rehearse
from sitl.vehicle.setup import Fault, GroundStationEvent
from sitl.world.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
TREE = ROOT / "trees" / "patrol.yaml"
FAULT_AT_S = 62.0  # the first leg: airborne at 20 m from about 55 s


def _patrol_with(**changes):
    return dataclasses.replace(load_scenario(ROOT / "sitl" / "scenarios" / "patrol.yaml"), **changes)


def test_no_fault_completes_and_lands_at_home():
    report = rehearse(TREE, _patrol_with(), seed=1)
    assert report.mission_outcome == "completed" and report.outcome == "landed", report.message
    assert report.landed_dist_m < 1.0 and report.final_state == "landed" and report.t_safe_s is None


def test_a_forced_disarm_in_the_air_is_a_crash_never_a_landing():
    report = rehearse(TREE, _patrol_with(faults=(Fault(FAULT_AT_S, "disarm"),)), seed=1)
    assert report.outcome == "crashed"  # the truth: it fell
    assert report.mission_outcome == "crashed", report.message


def test_the_autopilots_battery_failsafe_sends_the_patrol_home_early():
    # A failing cell: the voltage failsafe fires with ArduCopter's default action, none
    # (BATT_FS_LOW_ACT 0), while the remaining percentage still reads high; the patrol's guard takes it home.
    report = rehearse(TREE, _patrol_with(faults=(Fault(FAULT_AT_S, "battery_drop"),), params={"BATT_FS_LOW_ACT": 0}), seed=1)
    assert report.mission_outcome == "returned early", report.message
    assert report.outcome == "landed" and report.landed_dist_m < 1.0
    assert report.final_state == "landed" and 0.0 < report.t_safe_s < 120.0  # from the fault to the touchdown


def test_an_ekf_failsafe_is_the_autopilots_abort_and_its_land_is_left_alone():
    seen = {}
    report = rehearse(TREE, _patrol_with(faults=(Fault(FAULT_AT_S, "gps_loss"),)), seed=1,
                      on_start=lambda runner, vehicle, resources: seen.update(runner=runner))
    assert report.mission_outcome == "aborted by the autopilot", report.message
    assert any("EKF Failsafe" in text for _, text in seen["runner"].witness.texts)
    # The failsafe's LAND, not overridden by a hold, brings it down where it was: on the first leg, not at home.
    assert report.outcome == "failsafe" and report.final_state == "landed"
    assert report.landed_dist_m > 5.0


def test_a_ground_stations_mode_change_is_a_take_over():
    report = rehearse(TREE, _patrol_with(ground_station=(GroundStationEvent(FAULT_AT_S, "LOITER"),)), seed=1)
    assert report.mission_outcome == "taken over", report.message
    assert report.final_state not in ("moving", "falling", "crashed")


def test_a_lost_link_is_link_lost_and_the_autopilot_brings_it_home():
    report = rehearse(TREE, _patrol_with(faults=(Fault(FAULT_AT_S, "link_loss"),)), seed=1)
    assert report.mission_outcome == "link lost", report.message
    assert report.outcome == "failsafe" and report.landed_dist_m < 5.0  # the GCS failsafe's RTL
    assert report.final_state == "landed"


def test_a_fence_that_refuses_the_leg_fails_it_with_the_cause_instead_of_waiting_for_the_battery():
    # ArduCopter's GUIDED refuses a target outside an enabled fence and holds: the 100 m square
    # does not fit in a 60 m circle.
    report = rehearse(TREE, _patrol_with(params={"FENCE_ENABLE": 1, "FENCE_RADIUS": 60}), seed=1)
    assert report.mission_outcome == "failed", report.message
    assert "no progress for 30 s with 100 m to go" in report.message
    assert report.sim_time_s < 120.0  # within the stall bound of the first leg, not the battery's
    assert report.final_state == "holding"  # the failed leg's hold took


def test_a_lost_transmitter_is_the_autopilots_radio_failsafe_and_its_rtl_lands_at_home():
    # ArduCopter's FS_THR_ENABLE 1: RC silent for RC_FS_TIMEOUT while flying GUIDED -> "Radio Failsafe", RTL.
    seen = {}
    report = rehearse(TREE, _patrol_with(faults=(Fault(FAULT_AT_S, "rc_loss"),)), seed=1,
                      on_start=lambda runner, vehicle, resources: seen.update(runner=runner))
    assert report.mission_outcome == "aborted by the autopilot", report.message
    assert [text for _, text in seen["runner"].witness.texts][0] == "Radio Failsafe"  # then the GCS's, once `run` ended
    assert report.outcome == "failsafe" and report.landed_dist_m < 5.0 and report.final_state == "landed"


def test_a_transmitter_lost_with_guided_allowed_to_continue_completes_the_patrol():
    # FS_OPTIONS bit 2: the radio failsafe leaves GUIDED flying; the mission goes on and says what happened.
    seen = {}
    report = rehearse(TREE, _patrol_with(faults=(Fault(FAULT_AT_S, "rc_loss"),), params={"FS_OPTIONS": 4}), seed=1,
                      on_start=lambda runner, vehicle, resources: seen.update(runner=runner))
    assert report.mission_outcome == "completed", report.message
    assert report.outcome == "landed" and report.landed_dist_m < 1.0
    assert [text for _, text in seen["runner"].witness.texts] == ["Radio Failsafe - Continuing Guided Mode"]




def test_a_rehearsal_cut_by_its_time_limit_stops_the_mission_where_it_was(tmp_path):
    """The time limit ends the mission as an operator would, by halting the tree: its hold is sent, so the
    aircraft is not left flying on along the leg it was on (10 m/s towards a waypoint 600 m east)."""
    tree = tmp_path / "long_leg.yaml"
    tree.write_text("version: 1\nmain: LongLeg\ntrees:\n  LongLeg:\n    Sequence:\n      children:\n"
                    "        - ArmAndTakeoff: {altitude_m: 20}\n        - GoTo: {waypoint: [600.0, 0.0, 20.0]}\n")
    seen = {}
    report = rehearse(tree, _patrol_with(time_limit_s=FAULT_AT_S + 10.0), seed=1,
                      on_start=lambda runner, vehicle, resources: seen.update(sim=vehicle.sim))
    assert report.outcome == "timeout" and report.mission_outcome == "interrupted", report.message
    sim = seen["sim"]  # the settle's end, 10 s after the cut: back towards where the hold was sent
    assert 100.0 < sim.truth.pos_enu[0] < 200.0 and math.hypot(*sim.truth.vel_enu[:2]) < 3.0
