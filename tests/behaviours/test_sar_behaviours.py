"""OperatorCue, ReportFind and LoiterOverFind flown against the simulator inside tiny trees."""

from __future__ import annotations

import math

import numpy as np
import py_trees
import pytest

from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.find import Find
from chaser_bt.geo import GeoPoint, LocalFrame

from flight_helpers import fly, runner_for, take_off

Status = py_trees.common.Status
BB = py_trees.blackboard.Blackboard


def tick_for(vehicle, runner, seconds: float) -> list[py_trees.common.Status]:
    """Tick for ``seconds`` of sim time; the root's status after each tick."""
    statuses = []

    def step() -> bool:
        if runner.tick_if_due():
            statuses.append(runner.status)
        return False

    vehicle.run_until(step, seconds)
    return statuses


def test_operator_cue_is_live_until_reached_then_spent(vehicle):
    take_off(vehicle, 15)
    runner = runner_for(vehicle, "OperatorCue: {position: [60, 0, 15], sigma_m: 30, sigma_up_m: 2, reached_m: 8}")
    statuses = tick_for(vehicle, runner, 1.0)
    assert set(statuses) == {Status.SUCCESS}
    cue: TargetCue = BB.get("/target/cue")
    assert cue.source == "operator" and cue.t == pytest.approx(vehicle.clock.now(), abs=0.15)  # re-written each tick
    np.testing.assert_array_equal(cue.position_enu, [60, 0, 15])
    np.testing.assert_array_equal(cue.covariance_enu, np.diag([900.0, 900.0, 4.0]))
    assert runner.tree.root.feedback_message == "last-known position 60 m away"  # the vehicle hovers over home
    # Fly there (the cue node is not ticked meanwhile); at the first tick within 8 m it is spent.
    status, _ = fly(vehicle, "GoTo: {waypoint: [60, 0, 15], acceptance_radius_m: 3}", timeout_s=60)
    assert status == Status.SUCCESS
    arrived = vehicle.clock.now()
    statuses = tick_for(vehicle, runner, 0.5)
    assert set(statuses) == {Status.FAILURE} and "spent" in runner.tree.root.feedback_message
    # The last cue is the one written at arrival; it is not written again, so it goes stale from there.
    spent_cue = BB.get("/target/cue")
    assert spent_cue.t == pytest.approx(arrived, abs=0.15)
    # Spent stays spent even when the vehicle leaves.
    fly(vehicle, "GoTo: {waypoint: [0, 0, 15], acceptance_radius_m: 3}", timeout_s=60)
    assert set(tick_for(vehicle, runner, 0.5)) == {Status.FAILURE}
    assert BB.get("/target/cue") is spent_cue


def test_operator_cue_in_latitude_and_longitude(vehicle):
    vehicle.run_until(lambda: vehicle.link.frame is not None, 30)
    home = vehicle.link.state.home
    # 0.001 deg north of home is 111 m north (1 deg of latitude ~ 111.05 km at 42.5 deg), 10 m up.
    runner = runner_for(vehicle, f"OperatorCue: {{frame: global, position: [{home.lat_deg + 0.001}, {home.lon_deg}, 10]}}")
    assert set(tick_for(vehicle, runner, 0.5)) == {Status.SUCCESS}
    np.testing.assert_allclose(BB.get("/target/cue").position_enu, [0.0, 111.05, 10.0], atol=0.2)


def test_report_find_fixes_the_person_from_camera_bearings(vehicle):
    vehicle.run_until(lambda: vehicle.link.frame is not None, 30)
    runner = runner_for(vehicle, "ReportFind: {min_fixes: 3, min_span_s: 0.2, plane_z_m: 0.5, min_confidence: 0.4}")
    person = np.array([30.0, 40.0, 0.5])
    camera = np.array([0.0, 0.0, 20.5])
    b = (person - camera) / np.linalg.norm(person - camera)
    statuses = []
    for k, confidence in enumerate([0.9, 0.2, 0.9, 0.9]):  # the 0.2 one is below min_confidence
        now = vehicle.clock.now()
        BB.set("/target/estimate", TargetEstimate(t=now, position_enu=camera + 12.0 * b, bearing_enu=b, range_m=12.0,
                                                  confidence=confidence))
        statuses += tick_for(vehicle, runner, 0.15)
    # Three usable estimates; the find comes with the third, and no estimate is counted twice.
    assert statuses[-1] == Status.SUCCESS and Status.FAILURE in statuses
    find: Find = BB.get("/sar/find")
    assert find.fixes == 3
    np.testing.assert_allclose(find.position_enu, person, atol=1e-6)
    frame = LocalFrame(vehicle.link.state.home)
    expected = frame.to_geodetic(person)
    assert (find.geodetic.lat_deg, find.geodetic.lon_deg) == pytest.approx((expected.lat_deg, expected.lon_deg))
    assert "3 fixes" in runner.tree.root.feedback_message


def test_report_find_ignores_stale_estimates(vehicle):
    vehicle.run_until(lambda: vehicle.link.frame is not None, 30)
    runner = runner_for(vehicle, "ReportFind: {min_fixes: 1, min_span_s: 0, max_age_s: 0.5}")
    b = np.array([0.0, math.sqrt(0.5), -math.sqrt(0.5)])
    BB.set("/target/estimate", TargetEstimate(t=vehicle.clock.now() - 2.0, position_enu=[0, 10, 10], bearing_enu=b,
                                              range_m=14.14, confidence=1.0))
    assert set(tick_for(vehicle, runner, 0.5)) == {Status.FAILURE}
    assert "0 ground fix" in runner.tree.root.feedback_message


def _see(vehicle, runner, point, camera, seconds, confidence=0.9):
    """Write a fresh person estimate of ``point`` seen from ``camera`` before each tick for ``seconds``."""
    point, camera = np.asarray(point, float), np.asarray(camera, float)
    b = (point - camera) / np.linalg.norm(point - camera)
    statuses = []

    def step() -> bool:
        now = vehicle.clock.now()
        BB.set("/target/estimate", TargetEstimate(t=now, position_enu=camera + 10.0 * b, bearing_enu=b, range_m=10.0,
                                                  confidence=confidence))
        if runner.tick_if_due():
            statuses.append(runner.status)
        return False

    vehicle.run_until(step, seconds)
    return statuses


CHECKED = "ReportFind: {min_fixes: 3, min_span_s: 0.5, check_range_m: 30, check_fixes: 3, check_timeout_s: 5}"


def test_a_candidate_is_reported_only_after_a_closer_look(vehicle):
    vehicle.run_until(lambda: vehicle.link.frame is not None, 30)
    runner = runner_for(vehicle, CHECKED)
    person = np.array([100.0, 0.0, 0.5])
    # Seen from 50 m (camera at (60, -30, 20.5)): a candidate, no find; FAILURE so the tree flies closer.
    statuses = _see(vehicle, runner, person, [60.0, -30.0, 20.5], 1.0)
    assert set(statuses) == {Status.FAILURE}
    candidate: Find = BB.get("/sar/candidate")
    np.testing.assert_allclose(candidate.position_enu, person, atol=1e-6)
    assert "/sar/find" not in BB.storage and "looking closer" in runner.tree.root.feedback_message
    # Seen again from 29 m (camera 25 m off horizontally, 15 m up): confirmed once three new close fixes span 0.5 s.
    statuses = _see(vehicle, runner, person, [85.0, -20.0, 15.5], 1.0)
    assert statuses[-1] == Status.SUCCESS and statuses[0] == Status.FAILURE
    find: Find = BB.get("/sar/find")
    np.testing.assert_allclose(find.position_enu, person, atol=1e-6)
    assert "/sar/candidate" not in BB.storage  # cleared once confirmed


def test_a_candidate_not_seen_again_near_the_vehicle_is_rejected_and_its_place_ignored(vehicle, caplog):
    vehicle.run_until(lambda: vehicle.link.frame is not None, 30)
    runner = runner_for(vehicle, CHECKED)
    post = np.array([20.0, 0.0, 0.5])  # 20 m from the vehicle on the ground at home: near from the start
    statuses = _see(vehicle, runner, post, [0.0, -40.0, 20.5], 1.0)
    assert set(statuses) == {Status.FAILURE} and "/sar/candidate" in BB.storage
    statuses = tick_for(vehicle, runner, 4.5)  # no more detections: still a candidate until 5 s near it
    assert "/sar/candidate" in BB.storage
    with caplog.at_level("WARNING"):
        tick_for(vehicle, runner, 1.0)
    assert "/sar/candidate" not in BB.storage and "/sar/find" not in BB.storage
    assert "rejected" in caplog.text
    # Detections there again are ignored: no candidate comes back.
    _see(vehicle, runner, post + [2.0, 0.0, 0.0], [0.0, -40.0, 20.5], 1.0)
    assert "/sar/candidate" not in BB.storage and "0 ground fix" in runner.tree.root.feedback_message


def test_find_candidate_holds_while_a_candidate_waits(vehicle):
    vehicle.run_until(lambda: vehicle.link.frame is not None, 30)
    runner = runner_for(vehicle, "FindCandidate: {}")
    assert set(tick_for(vehicle, runner, 0.3)) == {Status.FAILURE}
    BB.set("/sar/candidate", Find(t=0.0, position_enu=np.array([12.0, -3.0, 0.5]), geodetic=None, std_m=1.0,
                                  confidence=0.5, fixes=5))
    assert set(tick_for(vehicle, runner, 0.3)) == {Status.SUCCESS}
    assert runner.tree.root.feedback_message == "candidate at [12.0, -3.0] m"


def test_loiter_holds_at_the_standoff_facing_the_find(vehicle):
    take_off(vehicle, 15)
    find_enu = np.array([40.0, 30.0, 0.5])
    BB.set("/sar/find", Find(t=vehicle.clock.now(), position_enu=find_enu, geodetic=None, std_m=1.0, confidence=0.9, fixes=5))
    runner = runner_for(vehicle, "LoiterOverFind: {height_m: 12, standoff_m: 20}")
    statuses = tick_for(vehicle, runner, 30.0)
    assert set(statuses) == {Status.RUNNING}
    # From home (0, 0) the station is 20 m back along the line to the find: (40, 30) - 20 * (0.8, 0.6).
    station = np.array([24.0, 18.0, 12.0])
    truth = vehicle.sim.truth
    np.testing.assert_allclose(truth.pos_enu, station, atol=1.5)
    yaw = vehicle.link.state.yaw_enu_rad
    assert math.remainder(yaw - math.atan2(0.6, 0.8), 2 * math.pi) == pytest.approx(0.0, abs=math.radians(5))


def test_loiter_without_a_find_fails(vehicle):
    take_off(vehicle, 10)
    status, runner = fly(vehicle, "LoiterOverFind: {duration_s: 5}", timeout_s=2)
    assert status == Status.FAILURE and "no find" in runner.tree.root.feedback_message


def test_loiter_with_a_duration_succeeds_after_it(vehicle):
    take_off(vehicle, 10)
    BB.set("/sar/find", Find(t=0.0, position_enu=np.array([5.0, 0.0, 0.5]), geodetic=None, std_m=1.0, confidence=0.9,
                             fixes=5))
    status, runner = fly(vehicle, "LoiterOverFind: {duration_s: 4, height_m: 10}", timeout_s=10)
    assert status == Status.SUCCESS and "held over the find 4 s" in runner.tree.root.feedback_message
