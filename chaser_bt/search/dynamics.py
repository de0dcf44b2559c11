"""Target dynamics: how the belief spreads between updates (paper section 3.4, and section 5's suggestion).

The paper convolves the belief with a 3-D Gaussian of sigma_x = sigma_y = v_h * dt and
sigma_z = v_v * dt. Taken literally that depends on the update rate: n updates of dt spread the
belief by sqrt(n) * v * dt, not v * n * dt, so a 5 Hz loop would barely spread at all. Here the
per-update variance is ``v^2 * tau_s * dt`` (a random walk with correlation time ``tau_s``): it
equals the paper's kernel when ``dt == tau_s`` and is the same whether a second is applied in one
update or in ten. Kernels are separable, one 1-D kernel per axis; a spread below 0.7 cell uses
the three-tap kernel with exactly that variance (a sampled Gaussian would lose it entirely).

No-go cells (buildings, terrain, restricted airspace, or everything off a road for a
road-bound target) are handled by one of two policies:

- ``"exclude"`` (default): the target cannot enter them. Each source cell's kernel is
  renormalised over the cells it may move to (allowed cells, plus the open air beyond the grid's
  sides and top), so mass is conserved: p' = A * (K conv (p / Z)), Z = K corr A_ext. What goes
  beyond the grid is ``ledger.outflow``.
- ``"absorb"``: the paper-plain convolution; mass landing on no-go cells is dropped into
  ``ledger.nogo`` (conditioning on "not there"), mass beyond the grid into ``ledger.outflow``.

:class:`VelocityDynamics` is the velocity-aware model: the belief also drifts with the cue's
velocity (whole-cell shifts with the fraction carried over, so drift adds no numerical
diffusion) and spreads with the velocity's uncertainty instead of the maximum speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from chaser_bt.search.belief import BeliefError, BeliefGrid

__all__ = ["GaussianDynamics", "VelocityDynamics", "gaussian_kernel_1d"]

_POLICIES = ("exclude", "absorb")


def gaussian_kernel_1d(variance_cells: float, shift: int = 0) -> tuple[np.ndarray, int]:
    """A normalised 1-D transition kernel with the given variance (cells^2), moved by ``shift`` cells.

    Returns (weights, first_offset): ``weights[m]`` is the probability of moving by
    ``first_offset + m`` cells.
    """
    if not (variance_cells >= 0 and math.isfinite(variance_cells)):
        raise BeliefError(f"dynamics variance must be finite and >= 0, got {variance_cells}")
    if variance_cells <= 0.5:
        a = 0.5 * variance_cells
        w = np.array([a, 1.0 - 2.0 * a, a])
    else:
        sigma = math.sqrt(variance_cells)
        r = int(math.ceil(4.0 * sigma))
        x = np.arange(-r, r + 1, dtype=float)
        w = np.exp(-0.5 * (x / sigma) ** 2)
        w /= w.sum()
    return w, shift - (len(w) - 1) // 2


def _centered(weights: np.ndarray, first: int) -> np.ndarray:
    """Weights on a symmetric offset range [-M, M] (zero-padded) so ndimage's origin is 0."""
    last = first + len(weights) - 1
    m = max(abs(first), abs(last))
    out = np.zeros(2 * m + 1)
    out[first + m : last + m + 1] = weights
    return out


def _spread(x: np.ndarray, kernels: list[np.ndarray]) -> np.ndarray:
    """y[i] = sum_d K(d) x[i - d] on every axis (mass moves by d), zero outside the grid."""
    for axis, k in enumerate(kernels):
        x = ndimage.correlate1d(x, k[::-1], axis=axis, mode="constant", cval=0.0)
    return x


def _gather(x: np.ndarray, kernels: list[np.ndarray]) -> np.ndarray:
    """y[s] = sum_d K(d) x[s + d] on every axis: what a source cell's kernel sees, zero outside."""
    for axis, k in enumerate(kernels):
        x = ndimage.correlate1d(x, k, axis=axis, mode="constant", cval=0.0)
    return x


def _below_floor(k: np.ndarray, nz: int) -> np.ndarray:
    """For each layer k, the kernel mass that would move below layer 0."""
    m = (len(k) - 1) // 2
    offsets = np.arange(-m, m + 1)
    return np.array([k[(layer + offsets) < 0].sum() for layer in range(nz)])


def _apply(belief: BeliefGrid, kernels: list[np.ndarray], policy: str) -> None:
    """Advance ``belief`` by one transition with separable kernels (each centred, odd length)."""
    if policy not in _POLICIES:
        raise BeliefError(f"no-go policy must be one of {_POLICIES}, got {policy!r}")
    spec, p = belief.spec, belief.p
    inside = _gather(np.ones(spec.shape), kernels)  # kernel mass that stays on the grid
    if spec.floored:
        below = _below_floor(kernels[2], spec.shape[2])[None, None, :]
    else:
        below = np.zeros((1, 1, spec.shape[2]))
    open_outside = np.maximum(1.0 - inside - below, 0.0)  # the open air beyond the sides and top
    if policy == "exclude":
        allowed = (~belief.nogo).astype(float)
        z = _gather(allowed, kernels) + open_outside
        q = np.divide(p, z, out=np.zeros_like(p), where=z > 0)
        new = _spread(q, kernels) * allowed
        belief.ledger.outflow += float((q * open_outside).sum())
    else:
        # Paper-plain: nothing renormalised; below the floor counts as leaving the grid.
        new = _spread(p, kernels)
        belief.ledger.outflow += float((p * (1.0 - inside)).sum())
        belief.ledger.nogo += float(new[belief.nogo].sum())
        new[belief.nogo] = 0.0
    belief.p = new
    belief.check()


@dataclass
class GaussianDynamics:
    """The paper's target dynamics: a 3-D Gaussian random walk (sigma_h from v_h, sigma_v from v_v).

    Args:
        v_h_mps, v_v_mps: the target's expected horizontal and vertical speeds (paper: 10, 5).
        tau_s: correlation time; one update of ``dt == tau_s`` is exactly the paper's kernel.
        nogo_policy: "exclude" (the target avoids no-go cells) or "absorb" (paper-plain).
    """

    v_h_mps: float = 10.0
    v_v_mps: float = 5.0
    tau_s: float = 1.0
    nogo_policy: str = "exclude"

    def __post_init__(self) -> None:
        if not (self.v_h_mps >= 0 and self.v_v_mps >= 0 and self.tau_s > 0):
            raise BeliefError(f"dynamics need v_h, v_v >= 0 and tau_s > 0, got {self.v_h_mps}, {self.v_v_mps}, {self.tau_s}")
        if self.nogo_policy not in _POLICIES:
            raise BeliefError(f"nogo_policy must be one of {_POLICIES}, got {self.nogo_policy!r}")

    def kernels(self, dt: float, spacing_m: float) -> list[np.ndarray]:
        """The three centred 1-D kernels (east, north, up) for an update of ``dt`` seconds."""
        var_h = self.v_h_mps**2 * self.tau_s * dt / spacing_m**2
        var_v = self.v_v_mps**2 * self.tau_s * dt / spacing_m**2
        return [_centered(*gaussian_kernel_1d(v)) for v in (var_h, var_h, var_v)]

    def step(self, belief: BeliefGrid, dt: float) -> None:
        """Advance the belief by ``dt`` seconds in place (B_t -> B_t+dt)."""
        if not (math.isfinite(dt) and dt >= 0):
            raise BeliefError(f"dynamics dt must be finite and >= 0, got {dt}")
        if dt == 0:
            return
        _apply(belief, self.kernels(dt, belief.spec.spacing_m), self.nogo_policy)


@dataclass
class VelocityDynamics:
    """Velocity-aware target dynamics (paper section 5): drift with ``velocity_enu``, spread by its uncertainty.

    Args:
        velocity_enu: the target's estimated velocity (m/s), e.g. the last radar cue's.
        sigma_v_h_mps, sigma_v_v_mps: uncertainty of that velocity (random-walk speeds, m/s).
        tau_s: correlation time of the spread, as in :class:`GaussianDynamics`.
        nogo_policy: as in :class:`GaussianDynamics`.
    """

    velocity_enu: np.ndarray
    sigma_v_h_mps: float = 3.0
    sigma_v_v_mps: float = 1.5
    tau_s: float = 1.0
    nogo_policy: str = "exclude"
    _drift_m: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)
    _shifted: np.ndarray = field(default_factory=lambda: np.zeros(3, dtype=np.int64), repr=False)

    def __post_init__(self) -> None:
        self.velocity_enu = np.asarray(self.velocity_enu, dtype=float)
        if self.velocity_enu.shape != (3,) or not np.all(np.isfinite(self.velocity_enu)):
            raise BeliefError(f"velocity_enu must be 3 finite numbers, got {self.velocity_enu!r}")
        self._spread = GaussianDynamics(self.sigma_v_h_mps, self.sigma_v_v_mps, self.tau_s, self.nogo_policy)

    def step(self, belief: BeliefGrid, dt: float) -> None:
        """Advance the belief by ``dt`` seconds in place: drift whole cells as they accrue, then spread."""
        if not (math.isfinite(dt) and dt >= 0):
            raise BeliefError(f"dynamics dt must be finite and >= 0, got {dt}")
        if dt == 0:
            return
        self._drift_m = self._drift_m + self.velocity_enu * dt
        target = np.rint(self._drift_m / belief.spec.spacing_m).astype(np.int64)
        shift, self._shifted = target - self._shifted, target
        spread = self._spread.kernels(dt, belief.spec.spacing_m)
        kernels = []
        for axis in range(3):
            k = spread[axis]
            m = (len(k) - 1) // 2
            kernels.append(_centered(k, int(shift[axis]) - m))
        _apply(belief, kernels, self.nogo_policy)
