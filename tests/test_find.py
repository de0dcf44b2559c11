"""The find of a search-and-rescue mission: ground fixes from camera bearings, their robust median, the loiter station."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from chaser_bt.cue import TargetEstimate
from chaser_bt.find import FindCheck, FindEstimator, FindVerdict, ground_fix
from chaser_bt.geo import GeoPoint, LocalFrame

S2 = math.sqrt(0.5)


def estimate(camera, bearing, range_m=30.0, t=0.0, confidence=0.8) -> TargetEstimate:
    """A camera estimate seen from ``camera`` along ``bearing`` (normalised), at ``range_m``."""
    b = np.asarray(bearing, float)
    b = b / np.linalg.norm(b)
    c = np.asarray(camera, float)
    return TargetEstimate(t=t, position_enu=c + range_m * b, bearing_enu=b, range_m=range_m, confidence=confidence)


def test_a_45_degree_look_down_from_20_m_meets_the_ground_20_m_ahead():
    # Camera 20 m up looking east 45 deg down: the ray drops 1 m per metre east, so z = 0 at x = 20.
    p = ground_fix(estimate([0, 0, 20], [S2, 0, -S2], range_m=5.0), plane_z_m=0.0, max_range_m=100.0)
    np.testing.assert_allclose(p, [20.0, 0.0, 0.0], atol=1e-9)
    # The plane at 0.5 m: 19.5 m of drop, so 19.5 m east; the box's range (5 m) does not matter.
    p = ground_fix(estimate([0, 0, 20], [S2, 0, -S2], range_m=50.0), plane_z_m=0.5, max_range_m=100.0)
    np.testing.assert_allclose(p, [19.5, 0.0, 0.5], atol=1e-9)


def test_a_ray_that_does_not_go_down_or_goes_too_far_gives_no_fix():
    assert ground_fix(estimate([0, 0, 20], [1, 0, 0]), 0.0, 100.0) is None  # level
    assert ground_fix(estimate([0, 0, 20], [1, 0, 0.2]), 0.0, 100.0) is None  # up
    # 30 deg down from 20 m: the ground is 40 m along the ray.
    look = [math.cos(math.radians(30)), 0, -math.sin(math.radians(30))]
    assert ground_fix(estimate([0, 0, 20], look), 0.0, 39.0) is None
    np.testing.assert_allclose(ground_fix(estimate([0, 0, 20], look), 0.0, 41.0), [40 * math.cos(math.radians(30)), 0, 0],
                               atol=1e-9)
    # Below the plane looking down: the plane is behind the camera.
    assert ground_fix(estimate([0, 0, 0.2], [S2, 0, -S2]), 0.5, 100.0) is None


@settings(max_examples=60, deadline=None)
@given(st.floats(-200, 200), st.floats(-200, 200), st.floats(5, 60), st.floats(-math.pi, math.pi), st.floats(0.2, 1.4))
def test_the_fix_lies_on_the_plane_and_on_the_line_of_sight(x, y, h, azimuth, depression):
    b = [math.cos(depression) * math.cos(azimuth), math.cos(depression) * math.sin(azimuth), -math.sin(depression)]
    p = ground_fix(estimate([x, y, h], b, range_m=7.0), 0.0, 1e4)
    assert p[2] == pytest.approx(0.0, abs=1e-9)
    # The horizontal distance is h / tan(depression), along the azimuth.
    d = h / math.tan(depression)
    np.testing.assert_allclose(p[:2], [x + d * math.cos(azimuth), y + d * math.sin(azimuth)], atol=1e-6)


def test_the_find_is_the_median_of_the_fixes_that_agree():
    est = FindEstimator(plane_z_m=0.0, max_range_m=200.0, gate_m=10.0, min_fixes=4)
    # Fixes (ground points) straight below-ahead of a camera at (0, 0, 20): aim the ray at each point.
    points = [(30, 40), (31, 41), (29, 42), (32, 39), (120, -50)]  # the last is a bush the tracker slid onto
    for k, (e, n) in enumerate(points[:3]):
        assert est.add(estimate([0, 0, 20], [e, n, -20], t=float(k), confidence=0.5))
        assert est.find() is None  # not enough fixes yet
    for k, (e, n) in enumerate(points[3:], start=3):
        assert est.add(estimate([0, 0, 20], [e, n, -20], t=float(k), confidence=1.0))
    f = est.find(LocalFrame(GeoPoint(42.0, -71.0, 80.0)))
    assert f is not None and f.fixes == 4
    # Median of the four agreeing points: east median(30, 31, 29, 32) = 30.5, north median(40, 41, 42, 39) = 40.5.
    np.testing.assert_allclose(f.position_enu, [30.5, 40.5, 0.0], atol=1e-9)
    # Spread: RMS horizontal distance from (30.5, 40.5) over the four, / sqrt(4).
    d2 = [(0.5**2 + 0.5**2), (0.5**2 + 0.5**2), (1.5**2 + 1.5**2), (1.5**2 + 1.5**2)]
    assert f.std_m == pytest.approx(math.sqrt(sum(d2) / 4) / 2)
    # Confidence: 4 of 5 fixes agree, their mean confidence (0.5, 0.5, 0.5, 1.0) = 0.625.
    assert f.confidence == pytest.approx(0.8 * 0.625)
    assert f.t == 3.0  # the latest agreeing fix, not the outlier's
    # The geodetic point is the ENU point in the frame: 40.5 m north is 40.5 / 111.1 km of latitude.
    assert f.geodetic.lat_deg == pytest.approx(42.0 + 40.5 / 111_050, abs=2e-6)
    assert f.to_dict()["position_enu"] == [30.5, 40.5, 0.0]


def test_scattered_fixes_give_no_find():
    est = FindEstimator(plane_z_m=0.0, max_range_m=500.0, gate_m=5.0, min_fixes=3)
    for k, (e, n) in enumerate([(0, 30), (40, 30), (80, 30), (120, 30)]):
        est.add(estimate([0, 0, 20], [e, n, -20], t=float(k)))
    assert est.find() is None


def test_only_the_latest_fixes_count():
    est = FindEstimator(plane_z_m=0.0, max_range_m=500.0, gate_m=5.0, min_fixes=2, max_fixes=3)
    for k, (e, n) in enumerate([(10, 30), (10, 30), (60, 30), (60, 30), (60, 30)]):
        est.add(estimate([0, 0, 20], [e, n, -20], t=float(k)))
    f = est.find()
    assert est.fix_count == 3
    np.testing.assert_allclose(f.position_enu[:2], [60, 30], atol=1e-9)


def test_estimator_refuses_impossible_settings():
    with pytest.raises(ValueError, match="min_fixes"):
        FindEstimator(min_fixes=0)



def test_fixes_must_span_the_minimum_time():
    est = FindEstimator(plane_z_m=0.0, max_range_m=500.0, gate_m=5.0, min_fixes=3, min_span_s=2.0)
    for t in (10.0, 10.5, 11.0, 11.9):  # four agreeing fixes over 1.9 s: one detection carried by a tracker
        est.add(estimate([0, 0, 20], [10, 30, -20], t=t))
    assert est.find() is None
    est.add(estimate([0, 0, 20], [10, 30, -20], t=12.0))  # 2.0 s: confirmed
    assert est.find().t == 12.0


def _agreeing(est, point, times, camera=(0.0, 0.0, 20.0)):
    """Add fixes of the ground ``point`` (ENU, on the plane z = 0) seen from ``camera`` at ``times``."""
    c = np.asarray(camera, float)
    for t in times:
        assert est.add(estimate(c, np.asarray(point, float) - c, t=t))


def test_support_counts_later_close_agreeing_fixes_and_their_span():
    est = FindEstimator(plane_z_m=0.0, max_range_m=500.0, gate_m=5.0, min_fixes=3)
    _agreeing(est, [40, 0, 0], [1.0, 2.0, 3.0], camera=(0, 0, 30))  # 50 m away (30-40-50 triangle)
    _agreeing(est, [40, 0, 0], [4.0, 5.5], camera=(40, -16, 12))  # 20 m away (12-16-20)
    _agreeing(est, [60, 0, 0], [6.0], camera=(40, -16, 12))  # close, but 20 m from the point: does not agree
    assert est.support([40, 0, 0], since_t=0.0, within_m=60.0) == (5, 4.5)
    assert est.support([40, 0, 0], since_t=0.0, within_m=20.5) == (2, 1.5)  # only the two close ones
    assert est.support([40, 0, 0], since_t=4.0, within_m=20.5) == (1, 0.0)  # later than 4.0 only
    assert est.support([40, 0, 0], since_t=9.0, within_m=60.0) == (0, 0.0)


def test_a_rejected_place_loses_its_fixes_and_ignores_new_ones():
    est = FindEstimator(plane_z_m=0.0, max_range_m=500.0, gate_m=5.0, min_fixes=3)
    _agreeing(est, [40, 0, 0], [1.0, 2.0, 3.0])
    _agreeing(est, [80, 30, 0], [4.0, 5.0, 6.0, 7.0])  # the person, 50 m from the post
    assert est.find().fixes == 4  # the person's four outvote the post's three
    assert est.reject([41, 1, 0]) == 3  # the three fixes of the post (within 5 m of (41, 1))
    assert est.fix_count == 4
    assert not est.add(estimate([0, 0, 20], [43, 0, -20], t=8.0))  # 2 m from the rejected place
    assert est.ignored_fixes == 1 and est.fix_count == 4
    np.testing.assert_allclose(est.find().position_enu[:2], [80, 30], atol=1e-9)


def test_a_candidate_seen_again_from_close_by_is_confirmed():
    est = FindEstimator(plane_z_m=0.0, max_range_m=500.0, gate_m=5.0, min_fixes=3)
    check = FindCheck(close_m=25.0, confirm_fixes=2, min_span_s=1.0, timeout_s=10.0, gate_m=5.0)
    _agreeing(est, [40, 0, 0], [1.0, 2.0, 3.0], camera=(0, 0, 30))  # from 50 m: a candidate
    candidate = est.find()
    assert check.update(3.0, [0, 0, 30], candidate, est) is FindVerdict.PENDING
    # Close fixes taken before the candidate was put forward would not count; these come after.
    _agreeing(est, [40, 0, 0], [4.0], camera=(40, -16, 12))  # one close fix (20 m)
    assert check.update(4.0, [40, -16, 12], est.find(), est) is FindVerdict.PENDING
    assert check.close_fixes(est.find(), est) == 1
    _agreeing(est, [40, 0, 0], [4.5], camera=(40, -16, 12))  # two, but over 0.5 s only
    assert check.update(4.5, [40, -16, 12], est.find(), est) is FindVerdict.PENDING
    _agreeing(est, [40, 0, 0], [5.0], camera=(40, -16, 12))  # three over 1.0 s
    assert check.update(5.0, [40, -16, 12], est.find(), est) is FindVerdict.CONFIRMED
    assert check.update(99.0, [500, 500, 30], est.find(), est) is FindVerdict.CONFIRMED  # latched


def test_a_candidate_not_seen_again_while_near_is_rejected_after_the_timeout():
    est = FindEstimator(plane_z_m=0.0, max_range_m=500.0, gate_m=5.0, min_fixes=3)
    check = FindCheck(close_m=25.0, confirm_fixes=2, min_span_s=0.0, timeout_s=10.0, gate_m=5.0)
    _agreeing(est, [40, 0, 0], [1.0, 2.0, 3.0], camera=(0, 0, 30))
    candidate = est.find()
    # Far away (40 m horizontally) for a long time: no verdict, the vehicle has not looked yet.
    assert check.update(3.0, [0, 0, 30], candidate, est) is FindVerdict.PENDING
    assert check.update(50.0, [0, 0, 30], candidate, est) is FindVerdict.PENDING
    # Near from t = 60 on (24 m horizontally), nothing seen: pending until 70, rejected at 70.
    assert check.update(60.0, [40, -24, 12], candidate, est) is FindVerdict.PENDING
    assert check.update(69.9, [40, -24, 12], candidate, est) is FindVerdict.PENDING
    assert check.update(70.0, [40, -24, 12], candidate, est) is FindVerdict.REJECTED
    # A candidate elsewhere (more than gate_m away) is a new one, with its own clock.
    other = FindEstimator(plane_z_m=0.0, max_range_m=500.0, gate_m=5.0, min_fixes=3)
    _agreeing(other, [40, 20, 0], [71.0, 72.0, 73.0], camera=(0, 0, 30))
    assert check.update(73.0, [40, -4, 12], other.find(), other) is FindVerdict.PENDING
    assert check.update(82.9, [40, -4, 12], other.find(), other) is FindVerdict.PENDING
    assert check.update(83.0, [40, -4, 12], other.find(), other) is FindVerdict.REJECTED


def test_find_check_refuses_impossible_settings():
    with pytest.raises(ValueError, match="timeout_s"):
        FindCheck(timeout_s=0.0)
