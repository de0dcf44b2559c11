"""Radar-camera association: a cue's offset from a line of sight, and the running fit that gives up a
track the trackers slid onto another drone."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from chaser_bt.cue import sight_offset_sigma
from chaser_bt.vision.cue_fit import CueFit

X = np.array([1.0, 0.0, 0.0])


def test_isotropic_error_is_the_perpendicular_distance_in_sigma():
    # The cue 3 m north and 4 m up of a ray along east: 5 m off it; sigma 2 m -> 2.5.
    assert math.isclose(sight_offset_sigma(np.zeros(3), X, np.array([10.0, 3.0, 4.0]), 4.0 * np.eye(3)), 2.5)


def test_the_range_along_the_ray_is_free():
    # Anywhere along the line of sight, near or far, the cue fits it exactly.
    for r in (5.0, 50.0, 500.0):
        assert sight_offset_sigma(np.zeros(3), X, r * X, np.diag([1.0, 9.0, 25.0])) < 1e-9


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-50, 50), min_size=3, max_size=3), st.lists(st.floats(-1, 1), min_size=3, max_size=3),
       st.lists(st.floats(0.5, 10.0), min_size=3, max_size=3), st.floats(0, math.pi))
def test_matches_a_numerical_search_along_the_line(cue, direction, sigmas, angle):
    b = np.asarray(direction, float)
    if np.linalg.norm(b) < 0.1:
        b = X
    b /= np.linalg.norm(b)
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # a covariance not aligned with the axes
    cov = rot @ np.diag(np.square(sigmas)) @ rot.T
    inv = np.linalg.inv(cov)
    cam, cue = np.array([1.0, -2.0, 3.0]), np.asarray(cue, float)

    def maha(r: float) -> float:
        d = cam + r * b - cue
        return float(d @ inv @ d)

    best = minimize_scalar(maha)  # Brent's method along the line: no use of the closed form
    assert math.isclose(sight_offset_sigma(cam, b, cue, cov), math.sqrt(max(best.fun, 0.0)), rel_tol=1e-4, abs_tol=1e-4)


def _bearing(offset_m: float) -> np.ndarray:
    """The bearing from the origin to a point 20 m east, ``offset_m`` north."""
    v = np.array([20.0, offset_m, 0.0])
    return v / np.linalg.norm(v)


def test_the_followed_track_is_given_up_once_its_running_offset_passes_the_threshold():
    # The cue 20 m east, error 2 m (+1 m floor on each axis: sigma sqrt(5)). Track 1 (followed) sits on
    # it until t = 0, then slides onto a drone 5*sqrt(5) m north (5 sigma off the cue); track 2 stays on
    # the cue. The running mean with tau 1 s: 5 (1 - exp(-t)) > 2.5 first at the frame t = 0.7 s (0.1 s frames).
    fit = CueFit(tau_s=1.0, switch_sigma=2.5, margin_sigma=1.0, floor_m=1.0)
    cue, cov = np.array([20.0, 0.0, 0.0]), 4.0 * np.eye(3)
    off = 5.0 * math.sqrt(5.0) * 20.0 / math.sqrt(20.0**2 - (5.0 * math.sqrt(5.0)) ** 2)  # 5 sigma from the cue
    first = None
    for k in range(0, 21):
        t = k / 10
        fit.update(t, np.zeros(3), {1: _bearing(0.0 if k == 0 else off), 2: _bearing(0.0)}, cue, cov)
        if first is None and fit.better_than(1, [1, 2]) == 2:
            first = t
    assert first == 0.7
    assert math.isclose(fit.offset(1), 5.0 * (1 - math.exp(-2.0)), rel_tol=1e-6)


def test_no_switch_without_a_clearly_better_track_or_while_the_followed_one_fits():
    fit = CueFit(tau_s=1.0, switch_sigma=2.5, margin_sigma=1.0, floor_m=0.0)
    cue, cov = np.array([20.0, 0.0, 0.0]), np.eye(3)
    # Both 3 m off (3 sigma): the followed one is off the cue, but the other is no better.
    fit.update(0.0, np.zeros(3), {1: _bearing(3.0 * 20.0 / math.sqrt(391.0)), 2: _bearing(-3.0 * 20.0 / math.sqrt(391.0))},
               cue, cov)
    assert fit.better_than(1, [1, 2]) is None
    # The followed one fits (2 sigma): kept even though the other fits exactly.
    fit.reset()
    fit.update(0.0, np.zeros(3), {1: _bearing(2.0 * 20.0 / math.sqrt(396.0)), 2: _bearing(0.0)}, cue, cov)
    assert fit.better_than(1, [1, 2]) is None
    # A track that is no longer live is forgotten.
    fit.update(0.1, np.zeros(3), {2: _bearing(0.0)}, cue, cov)
    assert fit.offset(1) is None and fit.offset(2) is not None
