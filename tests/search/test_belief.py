"""Belief grid, target dynamics and the mass ledger; bad input gets a clear error."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from chaser_bt.cue import TargetCue
from chaser_bt.search import (BeliefError, BeliefGrid, GaussianDynamics, GridSpec, SensorModel, VelocityDynamics,
                              box_mask, corridor_mask)
from chaser_bt.search.dynamics import gaussian_kernel_1d
from chaser_bt.vision import CameraModel


def small_spec(shape=(6, 5, 4), floored=True):
    return GridSpec((0.0, 0.0, 0.0), 20.0, shape, floored)


def test_paper_grid_is_41_by_41_by_11():
    spec = GridSpec.around((0.0, 0.0, 0.0))
    assert spec.shape == (41, 41, 11)
    np.testing.assert_allclose(spec.center_of([0, 0, 0]), [-400, -400, 0])
    np.testing.assert_allclose(spec.center_of([40, 40, 10]), [400, 400, 200])


def test_initial_belief_peaks_at_the_cue_with_its_covariance():
    spec = GridSpec.around((0.0, 0.0, 0.0))
    cue = TargetCue(0.0, np.array([100.0, -60.0, 40.0]), np.diag([40.0, 40.0, 15.0]) ** 2)
    b = BeliefGrid.from_cue(spec, cue)
    assert b.total() == pytest.approx(1.0)
    np.testing.assert_allclose(spec.center_of(b.max_cell()), [100, -60, 40])
    c = spec.centers()
    mean = np.einsum("ijkl,ijk->l", c, b.p)
    var_x = float(np.einsum("ijk,ijk->", (c[..., 0] - mean[0]) ** 2, b.p))
    np.testing.assert_allclose(mean, [100, -60, 40], atol=1.0)
    assert var_x == pytest.approx(40.0**2 + 20.0**2 / 12, rel=0.05)  # the cue's variance plus the cell's


def brute_force_transition(belief: np.ndarray, allowed: np.ndarray, k1d: list[np.ndarray], floored: bool):
    """The 'exclude' policy from its definition: each source's kernel renormalised over where it may go."""
    shape = belief.shape
    new = np.zeros(shape)
    outflow = 0.0
    ms = [(len(k) - 1) // 2 for k in k1d]
    for src in itertools.product(*(range(n) for n in shape)):
        if belief[src] == 0:
            continue
        weights, z, out = {}, 0.0, 0.0
        for d in itertools.product(*(range(-m, m + 1) for m in ms)):
            w = k1d[0][d[0] + ms[0]] * k1d[1][d[1] + ms[1]] * k1d[2][d[2] + ms[2]]
            dst = tuple(s + o for s, o in zip(src, d))
            if all(0 <= dst[a] < shape[a] for a in range(3)):
                if allowed[dst]:
                    weights[dst] = w
                    z += w
            elif not (floored and dst[2] < 0):
                out += w
                z += w
        for dst, w in weights.items():
            new[dst] += belief[src] * w / z
        outflow += belief[src] * out / z
    return new, outflow


@pytest.mark.parametrize("dt", [0.3, 1.0, 2.5])
@pytest.mark.parametrize("floored", [True, False])
def test_exclude_dynamics_match_the_transition_definition(dt, floored):
    rng = np.random.default_rng(1)
    spec = small_spec(floored=floored)
    nogo = rng.random(spec.shape) < 0.25
    b = BeliefGrid(spec, rng.random(spec.shape), nogo)
    before = b.p.copy()
    dyn = GaussianDynamics(v_h_mps=12.0, v_v_mps=6.0)
    dyn.step(b, dt)
    expected, outflow = brute_force_transition(before, ~nogo, dyn.kernels(dt, spec.spacing_m), floored)
    np.testing.assert_allclose(b.p, expected, atol=1e-15)
    assert b.ledger.outflow == pytest.approx(outflow, abs=1e-15)
    assert not b.p[nogo].any()


def test_absorb_policy_drops_what_lands_in_no_go_cells_into_the_ledger():
    spec = small_spec()
    nogo = np.zeros(spec.shape, bool)
    nogo[3, 2, 1] = True
    p = np.zeros(spec.shape)
    p[2, 2, 1] = 1.0
    b = BeliefGrid(spec, p, nogo)
    dyn = GaussianDynamics(v_h_mps=10.0, v_v_mps=5.0, nogo_policy="absorb")
    dyn.step(b, 1.0)
    # sigma_h = 10 m = half a cell: three-tap kernel with a = 0.125 per side along x; y, z centre weights.
    a_x, a_z = 0.5 * 0.25, 0.5 * (5.0 / 20.0) ** 2
    assert b.ledger.nogo == pytest.approx(a_x * (1 - 2 * a_x) * (1 - 2 * a_z))
    assert b.total() + b.ledger.nogo == pytest.approx(1.0, abs=1e-15)


def test_one_update_of_tau_is_the_papers_kernel_and_updates_compose():
    # Paper: sigma = v * dt. With tau = dt that is one update; ten updates of dt/10 give the same variance.
    spec = GridSpec((0.0, 0.0, 0.0), 20.0, (61, 3, 1), floored=False)
    p = np.zeros(spec.shape)
    p[30, 1, 0] = 1.0
    one, ten = BeliefGrid(spec, p), BeliefGrid(spec, p)
    dyn = GaussianDynamics(v_h_mps=10.0, v_v_mps=0.0, tau_s=4.0)
    dyn.step(one, 4.0)
    for _ in range(10):
        dyn.step(ten, 0.4)
    x = np.arange(61) * 20.0 - 600.0
    for b in (one, ten):
        px = b.p.sum(axis=(1, 2)) / b.total()
        assert float((px * x**2).sum()) == pytest.approx(40.0**2, rel=0.01)  # sigma_x = v * dt = 40 m


@pytest.mark.parametrize("variance", [0.0, 0.1, 0.5, 0.8, 3.0, 20.0])
def test_kernels_are_normalised_with_the_requested_variance(variance):
    w, first = gaussian_kernel_1d(variance)
    x = np.arange(first, first + len(w))
    assert w.sum() == pytest.approx(1.0)
    assert (w * x).sum() == pytest.approx(0.0, abs=1e-12)
    assert (w * x**2).sum() == pytest.approx(variance, rel=0.02, abs=1e-12)


def test_velocity_dynamics_drift_with_the_cue_velocity():
    spec = GridSpec((0.0, 0.0, 0.0), 20.0, (40, 5, 1), floored=False)
    p = np.zeros(spec.shape)
    p[5, 2, 0] = 1.0
    b = BeliefGrid(spec, p)
    dyn = VelocityDynamics(np.array([8.0, 0.0, 0.0]), sigma_v_h_mps=1.0, sigma_v_v_mps=0.0)
    for _ in range(50):
        dyn.step(b, 0.5)  # 200 m east in 25 s
    px = b.p.sum(axis=(1, 2)) / b.total()
    mean_x = float((px * np.arange(40) * 20.0).sum())
    assert mean_x == pytest.approx(100.0 + 200.0, abs=10.0)


def test_mass_is_accounted_to_1e_9_over_1000_updates():
    rng = np.random.default_rng(5)
    spec = GridSpec.around((0.0, 0.0, 0.0), half_width_m=200.0, z_max_m=100.0)
    nogo = box_mask(spec, (-60.0, -60.0, 0.0), (20.0, 40.0, 60.0)) | corridor_mask(spec, [(150, -200), (200, 200)], 25.0)
    b = BeliefGrid.from_cue(spec, TargetCue(0.0, np.array([-100.0, 80.0, 40.0]), np.eye(3) * 900.0), nogo)
    sensor = SensorModel(CameraModel(), spec)
    models = [GaussianDynamics(), GaussianDynamics(nogo_policy="absorb"), VelocityDynamics(np.array([3.0, -2.0, 0.5]))]
    for i in range(1000):
        models[i % 3].step(b, float(rng.uniform(0.05, 1.0)))
        pos = rng.uniform([-200, -200, 0], [200, 200, 100])
        att = Rotation.from_euler("zyx", [rng.uniform(-math.pi, math.pi), rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3)])
        sensor.observe(b, pos, att)
        if i % 100 == 0:
            assert b.total() + b.ledger.removed == pytest.approx(1.0, abs=1e-9)
    assert b.total() + b.ledger.removed == pytest.approx(1.0, abs=1e-9)
    # Every account was exercised, and none of the belief sits in a no-go cell.
    assert b.ledger.observed > 0.01 and b.ledger.outflow > 0.01 and b.ledger.nogo > 1e-6
    assert not b.p[nogo].any()


def test_observe_removes_p_detect_of_the_seen_cells_and_reports_the_gain():
    spec = small_spec((5, 5, 1))
    b = BeliefGrid(spec, np.ones(spec.shape))
    sensor = SensorModel(CameraModel(max_range_m=30.0, p_detect=0.5, tilt_rad=0.0), spec)
    # Facing east from cell (1, 2): sees (2, 2) at 20 m and, 45 deg off-axis (< 47.5) at 28.3 m, (2, 1) and
    # (2, 3); (3, 2) at 40 m is out of range.
    gain = sensor.observe(b, spec.center_of([1, 2, 0]), Rotation.identity())
    assert gain == pytest.approx(0.5 * 3 / 25)
    assert b.p[2, 2, 0] == pytest.approx(0.5 / 25) and b.p[3, 2, 0] == pytest.approx(1 / 25)
    assert b.ledger.observed == pytest.approx(0.5 * 3 / 25)


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: BeliefGrid(small_spec(), np.full((6, 5, 4), np.nan)), "non-finite"),
        (lambda: BeliefGrid(small_spec(), np.zeros((6, 5, 4))), "empty"),
        (lambda: BeliefGrid(small_spec(), np.ones((6, 5, 4)), np.ones((6, 5, 4), bool)), "empty"),
        (lambda: BeliefGrid(small_spec(), -np.ones((6, 5, 4))), "negative"),
        (lambda: BeliefGrid(small_spec(), np.ones((2, 2, 2))), "does not match"),
        (lambda: BeliefGrid.from_cue(small_spec(), TargetCue(0.0, np.array([500.0, 0.0, 0.0]))), "outside the search grid"),
        (lambda: BeliefGrid.from_cue(GridSpec.around((0, 0, 0), half_width_m=400_000.0, z_max_m=2000.0, spacing_m=1.0),
                                     TargetCue(0.0, np.zeros(3))), "exceeds"),
        (lambda: GridSpec((0.0, 0.0, 0.0), 0.0, (2, 2, 2)), "spacing_m"),
        (lambda: GaussianDynamics(nogo_policy="bounce"), "nogo_policy"),
    ],
)
def test_bad_input_gets_a_clear_error(build, message):
    with pytest.raises(BeliefError, match=message):
        build()


def test_a_huge_grid_is_refused_before_anything_is_allocated():
    spec = GridSpec.around((0, 0, 0), half_width_m=1e6, z_max_m=1e4, spacing_m=0.5)  # ~3e16 cells
    with pytest.raises(BeliefError, match="exceeds"):
        spec.check_fits()


def test_nan_dt_and_a_nan_belief_mid_search_are_errors_not_hangs():
    b = BeliefGrid(small_spec(), np.ones((6, 5, 4)))
    with pytest.raises(BeliefError, match="dt"):
        GaussianDynamics().step(b, float("nan"))
    b.p[0, 0, 0] = np.nan
    with pytest.raises(BeliefError, match="non-finite"):
        GaussianDynamics().step(b, 1.0)


def test_a_grid_centred_on_a_point_keeps_its_lattice_and_size():
    spec = GridSpec.around([0.0, 0.0, 0.0], 400.0, 0.0, 100.0, 20.0)  # origin (-400, -400, 0), 41 x 41 x 6
    moved = spec.centred_on([517.0, -93.0, 55.0])
    assert moved.shape == spec.shape and moved.spacing_m == spec.spacing_m and moved.floored == spec.floored
    # Centre (origin + 400) on the nearest lattice point to the target: 520, -100; heights untouched.
    assert moved.origin_enu == (120.0, -500.0, 0.0)
    assert moved.contains([517.0, -93.0, 55.0]) and not spec.contains([517.0, -93.0, 55.0])
