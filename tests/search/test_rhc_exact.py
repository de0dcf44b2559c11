"""RHC returns the brute-force optimum of Algorithm 2 (property test on small grids)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from chaser_bt.search import GridSpec, MaxBeliefPlanner, RecedingHorizonPlanner, SensorModel
from chaser_bt.vision import CameraModel


def brute_force(belief, spec, camera, start, yaw0, h, gamma, threshold, blocked):
    """Algorithm 2 written out plainly: every move sequence, the belief lowered along each path.

    The footprint comes from CameraModel.visible on every cell centre (not the planner's stencils).
    """
    b0 = belief / belief.sum()
    centers = spec.centers().reshape(-1, 3)
    cache = {}

    def look(cell, yaw):
        key = (tuple(cell), round(yaw, 9))
        if key not in cache:
            att = Rotation.from_euler("z", yaw)
            cache[key] = np.flatnonzero(camera.visible(centers, spec.center_of(cell), att))
        return cache[key]

    moves = [(dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1) if (dx, dy, dz) != (0, 0, 0)]
    best = [0.0, None]  # P starts as {(p_0, 0)}

    def extend(path, yaw, b, g, t):
        if t > h:
            return
        for d in moves:
            cell = path[-1] + np.array(d)
            if np.any(cell < 0) or np.any(cell >= spec.shape) or blocked[tuple(cell)]:
                continue
            new_yaw = math.atan2(d[1], d[0]) if (d[0], d[1]) != (0, 0) else yaw
            seen = look(cell, new_yaw)
            g_new = g + gamma**t * camera.p_detect * b[seen].sum()
            if g_new > threshold:
                if g_new > best[0]:
                    best[0], best[1] = g_new, path + [cell]
                b_new = b.copy()
                b_new[seen] *= 1.0 - camera.p_detect
                extend(path + [cell], new_yaw, b_new, g_new, t + 1)

    extend([np.asarray(start)], yaw0, b0.reshape(-1).copy(), 0.0, 1)
    return best[0], best[1]


def path_gain(path, belief, spec, camera, yaw0, gamma):
    """Recompute a path's discounted gain independently (for checking the planner's reported value)."""
    b = (belief / belief.sum()).reshape(-1).copy()
    centers, yaw, g = spec.centers().reshape(-1, 3), yaw0, 0.0
    for t in range(1, len(path)):
        d = path[t] - path[t - 1]
        assert np.max(np.abs(d)) == 1, "moves are to adjacent cells"
        if d[0] or d[1]:
            yaw = math.atan2(d[1], d[0])
        seen = np.flatnonzero(camera.visible(centers, spec.center_of(path[t]), Rotation.from_euler("z", yaw)))
        g += gamma**t * camera.p_detect * b[seen].sum()
        b[seen] *= 1.0 - camera.p_detect
    return g


@st.composite
def problems(draw):
    shape = (draw(st.integers(3, 6)), draw(st.integers(3, 6)), draw(st.integers(1, 3)))
    h = draw(st.integers(1, 3))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["uniform01", "sparse", "peaked"]))
    if kind == "uniform01":
        belief = rng.random(shape)
    elif kind == "sparse":
        belief = rng.random(shape) * (rng.random(shape) < 0.3)
        belief.flat[rng.integers(belief.size)] += 1.0
    else:
        belief = np.exp(-3.0 * rng.random(shape) ** 2 * rng.integers(1, 6))
    camera = CameraModel(
        max_range_m=draw(st.sampled_from([25.0, 35.0, 50.0])),
        tilt_rad=math.radians(draw(st.sampled_from([0.0, 10.0, 30.0]))),
        p_detect=draw(st.sampled_from([1.0, 0.9, 0.5])),
    )
    gamma = draw(st.sampled_from([0.5, 0.9, 1.0]))
    threshold = draw(st.sampled_from([0.0, 1e-3, 0.05]))
    start = np.array([rng.integers(n) for n in shape])
    yaw0 = draw(st.floats(-math.pi, math.pi))
    blocked = rng.random(shape) < draw(st.sampled_from([0.0, 0.2]))
    blocked[tuple(start)] = False
    return GridSpec((0.0, 0.0, 0.0), 20.0, shape), belief, camera, start, yaw0, h, gamma, threshold, blocked


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(problems())
def test_rhc_returns_the_brute_force_optimum(problem):
    spec, belief, camera, start, yaw0, h, gamma, threshold, blocked = problem
    planner = RecedingHorizonPlanner(SensorModel(camera, spec), horizon=h, gamma=gamma, threshold=threshold)
    result = planner.plan(belief, spec.center_of(start), yaw0, blocked)
    best_gain, best_path = brute_force(belief, spec, camera, start, yaw0, h, gamma, threshold, blocked)
    if best_path is None:
        assert result.fell_back  # nothing passed the threshold: go to the belief maximum
        np.testing.assert_allclose(result.target_enu, spec.center_of(np.unravel_index(np.argmax(belief), spec.shape)))
        return
    assert not result.fell_back
    assert result.gain == pytest.approx(best_gain, rel=1e-9, abs=1e-12)
    # The reported gain is the path's true gain, and the path is legal.
    assert path_gain(result.path, belief, spec, camera, yaw0, gamma) == pytest.approx(result.gain, rel=1e-9, abs=1e-12)
    assert not any(blocked[tuple(c)] for c in result.path[1:])
    np.testing.assert_allclose(result.target_enu, spec.center_of(result.path[1]))


def test_rhc_matches_brute_force_at_horizon_four_with_a_discount():
    rng = np.random.default_rng(3)
    spec = GridSpec((0.0, 0.0, 0.0), 20.0, (5, 5, 2))
    camera = CameraModel(max_range_m=35.0, p_detect=0.8)
    belief = rng.random(spec.shape) ** 4
    start, blocked = np.array([2, 2, 0]), np.zeros(spec.shape, bool)
    planner = RecedingHorizonPlanner(SensorModel(camera, spec), horizon=4, gamma=0.7, threshold=1e-3)
    result = planner.plan(belief, spec.center_of(start), 0.4, blocked)
    best_gain, best_path = brute_force(belief, spec, camera, start, 0.4, 4, 0.7, 1e-3, blocked)
    assert result.gain == pytest.approx(best_gain, rel=1e-9)
    assert len(result.path) == 5


def test_a_path_through_a_blob_beats_standing_still_by_a_hand_computed_gain():
    # One 1 x 3 x 1 corridor; the camera looks 25 m ahead only; all belief in the far cell.
    spec = GridSpec((0.0, 0.0, 0.0), 20.0, (1, 3, 1))
    camera = CameraModel(max_range_m=25.0, p_detect=1.0, tilt_rad=0.0)
    belief = np.array([0.0, 0.0, 1.0]).reshape(1, 3, 1)
    planner = RecedingHorizonPlanner(SensorModel(camera, spec), horizon=1, gamma=0.9)
    # Facing north from cell 0: moving north to cell 1 sees cell 2 (20 m ahead): gain 0.9 * 1.
    result = planner.plan(belief, spec.center_of([0, 0, 0]), math.pi / 2)
    assert result.gain == pytest.approx(0.9)
    np.testing.assert_array_equal(result.path, [[0, 0, 0], [0, 1, 0]])
    assert result.yaw_enu_rad == pytest.approx(math.pi / 2)


def test_rhc_falls_back_to_the_belief_maximum_when_no_path_passes_the_threshold():
    spec = GridSpec((0.0, 0.0, 0.0), 20.0, (12, 12, 1))
    belief = np.zeros(spec.shape)
    belief[11, 11, 0] = 1.0  # far beyond any 1-move look
    planner = RecedingHorizonPlanner(SensorModel(CameraModel(max_range_m=30.0), spec), horizon=2)
    result = planner.plan(belief, spec.center_of([0, 0, 0]), 0.0)
    assert result.fell_back
    np.testing.assert_allclose(result.target_enu, spec.center_of([11, 11, 0]))


def test_max_belief_goes_straight_to_the_most_probable_cell():
    spec = GridSpec((-100.0, -100.0, 0.0), 20.0, (11, 11, 3))
    belief = np.ones(spec.shape)
    belief[8, 2, 1] = 5.0
    result = MaxBeliefPlanner(spec).plan(belief, np.zeros(3), 0.0)
    np.testing.assert_allclose(result.target_enu, [60.0, -60.0, 20.0])
    assert result.yaw_enu_rad == pytest.approx(math.atan2(-60.0, 60.0))


def test_a_node_budget_gives_an_approximate_answer_flagged_as_such():
    rng = np.random.default_rng(11)
    spec = GridSpec((0.0, 0.0, 0.0), 20.0, (9, 9, 3))
    belief = rng.random(spec.shape)
    sensor = SensorModel(CameraModel(max_range_m=45.0), spec)
    exact = RecedingHorizonPlanner(sensor, horizon=4, gamma=1.0).plan(belief, spec.center_of([4, 4, 1]), 0.0)
    capped = RecedingHorizonPlanner(sensor, horizon=4, gamma=1.0, node_budget=2).plan(belief, spec.center_of([4, 4, 1]), 0.0)
    assert exact.exact and exact.nodes > 2
    assert not capped.exact and capped.nodes == 2
    assert capped.gain <= exact.gain + 1e-15


@st.composite
def long_horizon_problems(draw):
    """Horizons 4 and 5 on grids small enough for the brute force (one or two layers)."""
    spec, belief, camera, start, yaw0, _, gamma, threshold, blocked = draw(problems())
    shape = (draw(st.integers(3, 4)), draw(st.integers(3, 4)), draw(st.integers(1, 2)))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    belief = rng.random(shape) ** draw(st.sampled_from([1, 4]))
    start = np.array([rng.integers(n) for n in shape])
    blocked = rng.random(shape) < 0.15
    blocked[tuple(start)] = False
    h = draw(st.integers(4, 5)) if shape[2] == 1 else 4
    return GridSpec((0.0, 0.0, 0.0), 20.0, shape), belief, camera, start, yaw0, h, gamma, threshold, blocked


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(long_horizon_problems())
def test_rhc_returns_the_brute_force_optimum_at_horizons_four_and_five(problem):
    test_rhc_returns_the_brute_force_optimum.hypothesis.inner_test(problem)
