"""The target belief: a probability over a uniform 3-D grid of cells (paper section 3.4).

Each cell centre is a grid point ``q``; ``BeliefGrid.p[i, j, k]`` is the probability that the
target is in that cell *and has not been detected yet*. Keeping the belief unnormalised makes
the bookkeeping exact: probability mass only ever leaves ``p`` through one of three ledger
accounts, so ``p.sum() + observed + outflow + nogo == 1`` at all times (to rounding):

- ``observed``: removed by the sensor model where the camera looked and saw nothing;
- ``outflow``: carried by the target dynamics across the grid's boundary;
- ``nogo``: dynamics that put mass into no-go cells under the paper-plain "absorb" policy.

Planners work on :meth:`BeliefGrid.normalized`, the belief given that the target was not seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from chaser_bt.cue import TargetCue

__all__ = ["GridSpec", "BeliefGrid", "MassLedger", "BeliefError", "DEFAULT_MAX_BYTES", "box_mask", "corridor_mask"]

#: The largest belief array a grid may allocate (bytes, float64); the planner keeps a few copies.
DEFAULT_MAX_BYTES = 256 * 1024 * 1024


class BeliefError(ValueError):
    """A belief that cannot be built or used: too big, empty, not finite, or a cue off the grid."""


@dataclass(frozen=True)
class GridSpec:
    """A uniform grid of cell centres ``origin_enu + spacing_m * (i, j, k)``.

    Args:
        origin_enu: ENU centre of cell (0, 0, 0), the grid's lowest south-west cell (m).
        spacing_m: distance between neighbouring centres (m).
        shape: cells along east, north, up.
        floored: the bottom layer is the ground: nothing (mass or target) goes below it.
    """

    origin_enu: tuple[float, float, float]
    spacing_m: float
    shape: tuple[int, int, int]
    floored: bool = True

    def __post_init__(self) -> None:
        if len(self.origin_enu) != 3 or not all(math.isfinite(float(v)) for v in self.origin_enu):
            raise BeliefError(f"grid origin_enu must be 3 finite numbers, got {self.origin_enu!r}")
        if not (math.isfinite(self.spacing_m) and self.spacing_m > 0):
            raise BeliefError(f"grid spacing_m must be positive, got {self.spacing_m}")
        if len(self.shape) != 3 or any(int(n) < 1 for n in self.shape):
            raise BeliefError(f"grid shape must be 3 positive counts, got {self.shape!r}")
        object.__setattr__(self, "origin_enu", tuple(float(v) for v in self.origin_enu))
        object.__setattr__(self, "shape", tuple(int(n) for n in self.shape))

    @classmethod
    def around(cls, center_enu, half_width_m: float = 400.0, z_min_m: float = 0.0, z_max_m: float = 200.0,
               spacing_m: float = 20.0, floored: bool = True) -> GridSpec:
        """The paper's grid: +-``half_width_m`` east and north of ``center_enu`` (the radar), from
        ``z_min_m`` to ``z_max_m`` up (absolute ENU heights), ``spacing_m`` apart: 41 x 41 x 11 by default."""
        if not (half_width_m >= 0 and z_max_m >= z_min_m):
            raise BeliefError(f"grid extent must be non-negative, got half_width_m={half_width_m}, z {z_min_m}..{z_max_m}")
        if not (math.isfinite(spacing_m) and spacing_m > 0):
            raise BeliefError(f"grid spacing_m must be positive, got {spacing_m}")
        n_xy = int(round(2 * half_width_m / spacing_m)) + 1
        n_z = int(round((z_max_m - z_min_m) / spacing_m)) + 1
        c = np.asarray(center_enu, dtype=float)
        return cls((c[0] - half_width_m, c[1] - half_width_m, z_min_m), spacing_m, (n_xy, n_xy, n_z), floored)

    @property
    def size(self) -> int:
        return self.shape[0] * self.shape[1] * self.shape[2]

    @property
    def nbytes(self) -> int:
        """Bytes of one float64 belief array on this grid."""
        return 8 * self.size

    def check_fits(self, max_bytes: int = DEFAULT_MAX_BYTES) -> None:
        """Raise :class:`BeliefError` before allocating a grid larger than ``max_bytes``."""
        if self.nbytes > max_bytes:
            raise BeliefError(
                f"belief grid {self.shape[0]} x {self.shape[1]} x {self.shape[2]} ({self.size:,} cells, "
                f"{self.nbytes / 2**20:,.0f} MiB) exceeds the {max_bytes / 2**20:,.0f} MiB limit: "
                "use a coarser spacing_m or a smaller extent"
            )

    def centers(self) -> np.ndarray:
        """Every cell centre, (nx, ny, nz, 3) ENU metres."""
        axes = [self.origin_enu[a] + self.spacing_m * np.arange(self.shape[a]) for a in range(3)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)

    def center_of(self, index) -> np.ndarray:
        """ENU centre of cell ``index`` (3 ints, or (N, 3))."""
        return np.asarray(self.origin_enu) + self.spacing_m * np.asarray(index, dtype=float)

    def index_of(self, points_enu) -> tuple[np.ndarray, np.ndarray]:
        """Nearest cell of each point: (indices (N, 3) clipped into the grid, inside (N,) mask)."""
        pts = np.asarray(points_enu, dtype=float).reshape(-1, 3)
        raw = np.rint((pts - np.asarray(self.origin_enu)) / self.spacing_m).astype(np.int64)
        hi = np.asarray(self.shape) - 1
        inside = np.all((raw >= 0) & (raw <= hi), axis=1) & np.all(np.isfinite(pts), axis=1)
        return np.clip(raw, 0, hi), inside

    def centred_on(self, point_enu) -> GridSpec:
        """The same grid moved horizontally by whole cells (its lattice kept) to centre on ``point_enu``."""
        p = np.asarray(point_enu, dtype=float)
        moved = list(self.origin_enu)
        for a in (0, 1):
            half = 0.5 * (self.shape[a] - 1) * self.spacing_m
            moved[a] += round((p[a] - half - self.origin_enu[a]) / self.spacing_m) * self.spacing_m
        return replace(self, origin_enu=tuple(moved))

    def contains(self, point_enu) -> bool:
        """Whether ``point_enu`` lies within half a cell of the grid's outer centres."""
        return bool(self.index_of(point_enu)[1][0])


@dataclass
class MassLedger:
    """Where probability mass went: ``p.sum() + observed + outflow + nogo`` stays at the initial 1."""

    observed: float = 0.0
    outflow: float = 0.0
    nogo: float = 0.0

    @property
    def removed(self) -> float:
        return self.observed + self.outflow + self.nogo


@dataclass
class BeliefGrid:
    """The belief ``p`` over ``spec`` with ``nogo`` cells (the target cannot be there) and its ledger.

    Build one with :meth:`from_cue` (paper: "initialized to the last known position of the
    target"), or directly from an array (it is validated and normalised to mass 1).
    """

    spec: GridSpec
    p: np.ndarray
    nogo: np.ndarray | None = None
    ledger: MassLedger = field(default_factory=MassLedger)

    def __post_init__(self) -> None:
        self.spec.check_fits()
        p = np.array(self.p, dtype=float)
        if p.shape != self.spec.shape:
            raise BeliefError(f"belief shape {p.shape} does not match the grid {self.spec.shape}")
        if self.nogo is None:
            self.nogo = np.zeros(self.spec.shape, dtype=bool)
        self.nogo = np.asarray(self.nogo, dtype=bool)
        if self.nogo.shape != self.spec.shape:
            raise BeliefError(f"no-go mask shape {self.nogo.shape} does not match the grid {self.spec.shape}")
        if not np.all(np.isfinite(p)):
            raise BeliefError(f"belief has {int(np.count_nonzero(~np.isfinite(p)))} non-finite cells (NaN or inf)")
        if np.any(p < 0):
            raise BeliefError(f"belief has {int(np.count_nonzero(p < 0))} negative cells")
        p[self.nogo] = 0.0
        total = p.sum()
        if not total > 0:
            raise BeliefError("belief is empty: no probability outside the no-go cells")
        self.p = p / total

    @classmethod
    def from_cue(cls, spec: GridSpec, cue: TargetCue, nogo: np.ndarray | None = None,
                 max_bytes: int = DEFAULT_MAX_BYTES) -> BeliefGrid:
        """B_0: the cue's Gaussian (position, covariance) over the cells, no-go cells excluded.

        The covariance is widened by the cell's own spread (spacing^2 / 12 per axis) so a cue far
        more precise than a cell still puts its mass in the nearest cells rather than underflowing.
        """
        spec.check_fits(max_bytes)
        if not spec.contains(cue.position_enu):
            raise BeliefError(f"cue at {np.round(cue.position_enu, 1).tolist()} m is outside the search grid "
                              f"(origin {spec.origin_enu}, {spec.shape} cells of {spec.spacing_m} m)")
        cov = 0.5 * (cue.covariance_enu + cue.covariance_enu.T) + np.eye(3) * spec.spacing_m**2 / 12.0
        try:
            inv = np.linalg.inv(cov)
            np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            raise BeliefError(f"cue covariance is not positive definite: {cue.covariance_enu.tolist()}") from None
        d = spec.centers() - cue.position_enu
        maha = np.einsum("...i,ij,...j->...", d, inv, d)
        p = np.exp(-0.5 * (maha - maha.min()))  # shift so the nearest cell is exp(0): never all zero
        return cls(spec, p, nogo)

    def total(self) -> float:
        """Probability the target is on the grid and undetected."""
        return float(self.p.sum())

    def normalized(self) -> np.ndarray:
        """The belief given the target has not been seen: ``p / p.sum()``."""
        total = self.p.sum()
        if not (total > 0 and math.isfinite(total)):
            raise BeliefError(f"belief has no usable mass left (total {total!r})")
        return self.p / total

    def check(self) -> None:
        """Raise :class:`BeliefError` if the belief went non-finite or empty."""
        if not np.all(np.isfinite(self.p)):
            raise BeliefError("belief became non-finite (NaN or inf)")
        if not self.p.sum() > 0:
            raise BeliefError("belief is empty")

    def observe(self, flat_cells: np.ndarray, p_detect: float) -> float:
        """Sensor update where the camera looked and saw nothing: p *= (1 - p_detect) on those cells.

        Returns the mass removed (added to ``ledger.observed``): the probability the camera would
        have detected the target there, i.e. the unnormalised belief gain.
        """
        flat = self.p.reshape(-1)
        cells = np.unique(np.asarray(flat_cells, dtype=np.int64))
        removed = float(p_detect * flat[cells].sum())
        flat[cells] *= 1.0 - p_detect
        self.ledger.observed += removed
        return removed

    def max_cell(self) -> np.ndarray:
        """Index (3,) of the most probable cell (the first in C order on ties)."""
        return np.array(np.unravel_index(int(np.argmax(self.p)), self.spec.shape))

    def copy(self) -> BeliefGrid:
        out = BeliefGrid.__new__(BeliefGrid)
        out.spec, out.p, out.nogo = self.spec, self.p.copy(), self.nogo.copy()
        out.ledger = MassLedger(self.ledger.observed, self.ledger.outflow, self.ledger.nogo)
        return out


def box_mask(spec: GridSpec, lo_enu, hi_enu) -> np.ndarray:
    """Cells whose centres lie in the axis-aligned box [lo, hi] (e.g. a building as no-go)."""
    c = spec.centers()
    return np.all((c >= np.asarray(lo_enu, dtype=float)) & (c <= np.asarray(hi_enu, dtype=float)), axis=-1)


def corridor_mask(spec: GridSpec, polyline_xy, half_width_m: float, z_max_m: float = math.inf) -> np.ndarray:
    """Cells within ``half_width_m`` (horizontally) of a polyline and at most ``z_max_m`` up: a road."""
    pts = np.asarray(polyline_xy, dtype=float).reshape(-1, 2)
    c = spec.centers()
    xy = c[..., :2]
    best = np.full(spec.shape, np.inf)
    for a, b in zip(pts[:-1], pts[1:]):
        ab = b - a
        t = np.clip(((xy - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(xy - (a + t[..., None] * ab), axis=-1))
    return (best <= half_width_m) & (c[..., 2] <= z_max_m)
