"""Rehearsal scores (DESIGN §7) on hand-built timelines whose answers are worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from chaser_bt.log.trace import FlightTrace
from chaser_bt.radar.correlator import Association
from chaser_bt.search.belief import BeliefGrid, GridSpec
from chaser_bt.vision.camera import CameraModel
from sitl.bench.scoring import (
    AssociationRecorder,
    TickRecord,
    association_windows,
    belief_snapshot,
    box_iou,
    box_matches,
    estimate_matches,
    follow_geometry_errors,
    in_frustum,
    score_ticks,
)


def test_box_iou_of_half_overlapping_squares_is_one_third():
    # 10x10 squares shifted by 5: intersection 50, union 150.
    assert box_iou((0, 0, 10, 10), (5, 0, 15, 10)) == pytest.approx(1 / 3)
    assert box_iou((0, 0, 10, 10), (20, 20, 30, 30)) == 0.0


def test_box_matches_by_iou_or_by_centre_inside_the_truth():
    assert box_matches((5, 0, 15, 10), (0, 0, 10, 10))  # IoU 1/3 >= 0.3
    assert not box_matches((5, 0, 15, 10), (0, 0, 9, 10), min_iou=0.4)  # IoU 40/150, centre (10, 5) outside
    assert not box_matches((8, 8, 30, 30), (0, 0, 10, 10))  # IoU 4/580, centre (19, 19) outside
    assert box_matches((10, 10, 12, 12), (0, 0, 100, 100))  # IoU 4e-4 but centre inside
    assert not box_matches((0, 0, 4, 4), (5, 0, 15, 10), min_iou=0.3)  # apart


def test_estimate_matches_within_ten_metres_or_three_degrees_of_bearing():
    cam, target = np.zeros(3), np.array([100.0, 0.0, 0.0])
    assert estimate_matches(np.array([108.0, 0.0, 0.0]), None, cam, target)  # 8 m off, no bearing
    assert not estimate_matches(np.array([130.0, 0.0, 0.0]), None, cam, target)  # 30 m off
    # 30 m too far along the line of sight but dead on bearing: the range is the loose part.
    assert estimate_matches(np.array([130.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), cam, target)

    def bearing(deg: float) -> np.ndarray:
        return np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg)), 0.0])

    assert estimate_matches(130 * bearing(2.9), bearing(2.9), cam, target)
    assert not estimate_matches(130 * bearing(3.1), bearing(3.1), cam, target)  # 3.1 deg and 31 m off


def test_in_frustum_is_the_image_rectangle_at_any_range():
    # Identity attitude: the body looks east; the e-con camera (95 x 73 deg) is tilted 10 deg down.
    cam, att, own = CameraModel(), Rotation.identity(), np.zeros(3)
    assert in_frustum(cam, np.array([100.0, 0.0, 40.0]), own, att)  # 21.8 + 10 = 31.8 deg above the axis < 36.5
    assert not in_frustum(cam, np.array([100.0, 0.0, 60.0]), own, att)  # 31 + 10 = 41 deg > 36.5
    assert not in_frustum(cam, np.array([-100.0, 0.0, 0.0]), own, att)  # behind
    assert not in_frustum(cam, np.array([100.0, 120.0, 0.0]), own, att)  # 120 / (100 cos 10) = 1.22 > tan 47.5 = 1.09
    far = np.array([500.0, 0.0, 0.0])
    assert in_frustum(cam, far, own, att) and not cam.visible(far[None], own, att)[0]  # beyond detection range, still in view


def test_association_windows_take_the_state_held_by_a_strict_majority():
    t = np.arange(40) / 10.0  # four 1 s windows of 10 samples
    state = np.ones(40, int)
    state[10:16] = -1  # window 1: 6 wrong of 10 -> wrong
    state[20:25] = 0  # window 2: 5 right, 5 none -> no majority -> none
    counted = np.ones(40, bool)
    counted[30:36] = False  # window 3: only 4 of 10 counted -> not a window
    n, right, wrong = association_windows(t, state, counted)
    assert (n, right, wrong) == (3, pytest.approx(1 / 3), pytest.approx(1 / 3))
    assert association_windows(np.zeros(0), np.zeros(0), np.zeros(0)) == (0, None, None)


def _chase_timeline() -> list[TickRecord]:
    """A 100 s flight ticked at 10 Hz (k = tick index, t = k / 10), built so every score is known:

    validated at 10 s, take-off altitude at 25 s, autonomous 15-90 s, first matching estimate at 30 s,
    following from 31 s to 79.9 s; target in view 30-60 s and 80-90 s; a camera frame on every other
    tick, the box right from 30 s to 45 s; the ownship's radar track held except 40-42 s (wrong).
    """
    out = []
    for k in range(1000):
        autonomous = 150 <= k < 900
        out.append(TickRecord(
            t=k / 10.0, autonomous=autonomous, airborne=autonomous, validated=k >= 100, alt_reached=k >= 250,
            following=310 <= k < 800,
            in_fov=(300 <= k < 600) or (800 <= k < 900),
            acquired=True if k >= 300 and k % 10 == 0 else (False if 200 <= k < 300 else None),
            frame=k % 2 == 0, frame_matched=k % 2 == 0 and 300 <= k < 450,
            radar_state=-1 if 400 <= k < 420 else 1, radar_counted=autonomous,
        ))
    return out


def test_scores_of_a_hand_built_chase_timeline():
    s = score_ticks(_chase_timeline())
    assert s.t_validated == 10.0 and s.t_alt_reached == 25.0 and s.t_acquired == 30.0
    assert s.t_airborne_s == pytest.approx(15.0)
    assert s.t_acquire_s == pytest.approx(5.0)
    assert s.t_follow_end == pytest.approx(79.9)
    # Span 30.0 .. 79.9 s: 500 autonomous ticks, 300 with the target in view.
    assert s.target_in_fov_frac == pytest.approx(300 / 500)
    # All autonomous flight, 15.0 .. 89.9 s: 750 ticks; in view 300 (30-60 s) + 100 (80-90 s).
    assert s.target_in_fov_frac_flight == pytest.approx(400 / 750)
    # 250 frames in the span, 75 of them (30-45 s) with the right box.
    assert s.detection_frames == 250 and s.detection_frac == pytest.approx(75 / 250)
    # 75 one-second windows (15..89 s), two of them (40 s, 41 s) held on a wrong track.
    assert s.radar_windows == 75
    assert s.radar_assoc_frac == pytest.approx(73 / 75) and s.wrong_assoc_frac == pytest.approx(2 / 75)
    keys = s.report_keys()
    assert keys["t_airborne_s"] == 15.0 and keys["detection_frac"] == 0.3


def test_altitude_before_validation_and_estimates_before_the_altitude_do_not_count():
    recs = _chase_timeline()
    for r in recs[:100]:
        r.alt_reached, r.acquired = True, True  # on the ground, before the track is validated
    s = score_ticks(recs)
    assert s.t_airborne_s == pytest.approx(15.0) and s.t_acquire_s == pytest.approx(5.0)


def test_scores_that_do_not_apply_are_none():
    recs = _chase_timeline()
    for r in recs:
        r.validated = False
    s = score_ticks(recs)
    assert (s.t_airborne_s, s.t_acquire_s, s.target_in_fov_frac, s.detection_frac) == (None, None, None, None)
    assert s.target_in_fov_frac_flight == pytest.approx(400 / 750)  # flight-wide share needs no acquisition
    s = score_ticks(_chase_timeline(), has_camera=False, has_radar=False)
    assert (s.target_in_fov_frac, s.target_in_fov_frac_flight, s.detection_frac) == (None, None, None)
    assert (s.radar_assoc_frac, s.wrong_assoc_frac, s.radar_windows) == (None, None, 0)
    assert s.t_acquire_s == pytest.approx(5.0)
    assert score_ticks(_chase_timeline(), has_target=False).t_acquire_s is None
    assert score_ticks([]).t_airborne_s is None


def test_follow_span_ends_with_autonomous_flight_when_the_mission_never_follows():
    recs = _chase_timeline()
    for r in recs:
        r.following = False
    s = score_ticks(recs)
    assert s.t_follow_end == pytest.approx(89.9)
    assert s.target_in_fov_frac == pytest.approx(400 / 600)  # 30.0 .. 89.9 s: 300 + 100 in view


class _Fixed:
    def __init__(self) -> None:
        self.calls: list[str] = []
        self.name = "fixed"

    def add_ownship(self, t, position, velocity=None) -> None:
        self.calls.append("own")

    def add_tracks(self, points) -> None:
        self.calls.append("tracks")

    def associate(self, t: float) -> Association:
        self.calls.append("associate")
        return Association(t, 7, frozenset({7}), ())

    def reset(self) -> None:
        self.calls.append("reset")


def test_association_recorder_passes_everything_through_and_remembers_the_decision():
    inner = _Fixed()
    rec = AssociationRecorder(inner)
    rec.add_ownship(1.0, np.zeros(3))
    rec.add_tracks(None)
    a = rec.associate(2.5)
    assert a.associated_id == 7 and (rec.last_t, rec.last_id) == (2.5, 7)
    assert inner.calls == ["own", "tracks", "associate"] and rec.name == "fixed"


def test_belief_snapshot_is_the_normalised_belief_summed_over_altitude():
    p = np.zeros((2, 3, 2))
    p[1, 2, 0], p[1, 2, 1], p[0, 0, 1] = 2.0, 1.0, 1.0  # total 4: cell (1, 2) holds 3/4, (0, 0) 1/4
    snap = belief_snapshot(12.5, BeliefGrid(GridSpec((100.0, -50.0, 0.0), 10.0, (2, 3, 2)), p))
    assert snap.t == 12.5 and snap.x_m.tolist() == [100.0, 110.0] and snap.y_m.tolist() == [-50.0, -40.0, -30.0]
    expected = np.zeros((2, 3))
    expected[1, 2], expected[0, 0] = 0.75, 0.25
    assert np.allclose(snap.mass, expected)


def test_follow_geometry_errors_are_medians_over_the_follow_ticks_only():
    # Desired: 24 m slant range, 20 deg below. Follow ticks (target minus ownship):
    # (24, 0, 0): range error 0, depression 0 -> 20 deg off; (0, 30, 0): 6 m, 20 deg;
    # 20 m at exactly 20 deg below: 4 m, 0 deg; target unknown (NaN): left out.
    # Medians of (0, 6, 4) and (20, 20, 0): 4 m and 20 deg. The launch tick, 1 km off, does not count.
    d = math.radians(20.0)
    rel = np.array([[1000.0, 0, 0], [24.0, 0, 0], [0, 30.0, 0], [20 * math.cos(d), 0, -20 * math.sin(d)],
                    [np.nan] * 3])
    own = np.tile([5.0, -3.0, 40.0], (5, 1))
    trace = FlightTrace(t=np.arange(5) * 0.1, ownship_enu=own, target_enu=own + rel,
                        phase=["launch", "follow", "follow", "follow", "follow"],
                        desired_range_m=24.0, desired_elevation_rad=d)
    rng, elev = follow_geometry_errors(trace)
    assert rng == pytest.approx(4.0)
    assert math.degrees(elev) == pytest.approx(20.0)


def test_follow_geometry_errors_without_a_follow_phase_or_a_desired_geometry_are_none():
    own = np.zeros((2, 3))
    rel = np.array([[24.0, 0, 0], [24.0, 0, 0]])
    assert follow_geometry_errors(FlightTrace(t=np.zeros(2), ownship_enu=own, target_enu=rel, phase=["launch"] * 2,
                                              desired_range_m=24.0, desired_elevation_rad=0.3)) == (None, None)
    assert follow_geometry_errors(FlightTrace(t=np.zeros(2), ownship_enu=own, target_enu=rel,
                                              phase=["follow"] * 2)) == (None, None)


def test_a_trace_cut_in_the_middle_of_a_row_keeps_whole_rows_only():
    """Ctrl-C can land while a tick's row is half written: the trace is cut to the rows written whole."""
    from sitl.bench.scoring import RehearsalObserver, _TraceColumns

    obs = object.__new__(RehearsalObserver)
    obs._cols, obs._follow, obs.events, obs.beliefs, obs.frames = _TraceColumns(), None, [], [], None
    c = obs._cols
    for k in range(2):  # two whole rows ...
        c.t.append(0.1 * k), c.own.append(np.zeros(3)), c.yaw.append(0.0), c.target.append(np.ones(3))
        c.in_fov.append(1.0), c.detected.append(1.0), c.mode.append("GUIDED"), c.phase.append("follow"), c.tip.append("")
    c.t.append(0.2)  # ... and the first column of a third
    tr = obs.trace({})
    assert len(tr) == 2 and tr.ownship_enu.shape == (2, 3) and len(tr.phase) == 2
    assert tr.slant_range_m.shape == (2,)


def test_two_drones_close_together_are_told_apart_by_the_bearing_not_the_boxs_range():
    from types import SimpleNamespace

    from chaser_bt.cue import TargetCue, TargetEstimate
    from sitl.bench.scoring import RehearsalObserver

    # From the camera at the origin: drone A 40 m north, drone B 4 m east of it and 8 m further
    # (5.7 deg apart). The camera looks straight at A (bearing exact) but its box-size range reads
    # 48 m, which puts the estimate's position 2.4 m from B's and 8 m from A's. A is followed.
    a, b = np.array([0.0, 40.0, 0.0]), np.array([4.0, 48.0, 0.0])
    bearing = np.array([0.0, 1.0, 0.0])
    est = TargetEstimate(t=1.0, position_enu=48.0 * bearing, covariance_enu=np.eye(3), bearing_enu=bearing, range_m=48.0)
    observer = SimpleNamespace(_objects=[("A", lambda t: a), ("B", lambda t: b)])
    assert RehearsalObserver._followed(observer, est, np.zeros(3), 1.0) == 0
    # A cue without a bearing (not the camera's) can only be judged by its position: B.
    est_no_bearing = TargetCue(t=1.0, position_enu=48.0 * bearing, covariance_enu=np.eye(3))
    assert RehearsalObserver._followed(observer, est_no_bearing, np.zeros(3), 1.0) == 1
