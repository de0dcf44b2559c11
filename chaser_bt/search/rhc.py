"""Receding-horizon search planner: Algorithm 2 of the paper, exact, by branch and bound.

Algorithm 2 scores every path of ``h`` moves over adjacent cells (26-connected) from the
vehicle's cell: the belief gain of move t is ``gamma^t * sum_{q in S(x_t, x_t-1)} b_q`` on the
belief already lowered by the path's earlier looks (``F(B_0, p_i)``), paths whose discounted
gain does not exceed ``threshold`` (0.001) are dropped, the best path wins, one step is flown and
the planner runs again; when no path passes, the vehicle goes to the belief maximum.

Conventions made explicit here (the paper's pseudo-code leaves them open):

- ``horizon`` is the number of moves (the pseudo-code's ``while t < h`` would stop at h - 1);
- the gain of a look is the probability the camera detects the target there,
  ``p_detect * sum b``, on the normalised belief; with ``p_detect = 1`` it is the paper's sum;
- a move's heading is its horizontal direction (one of 8); a purely vertical move keeps the
  previous heading, the first one the vehicle's own yaw; the camera is level over the horizon;
- target dynamics are frozen over the horizon (F applies the sensor model only).

Exactness (docs/search.md has the argument): a subtree is skipped only when an upper bound on
every path through it is no better than a path already found. The bound of a node at depth t
with gain g is ``g + gamma^t * V_{h-t}(cell, heading)``; V is a dynamic programme over every cell
of the local window and heading in which a move gains its look on the unlowered belief minus
``p_detect^2`` times the belief that the previous look also saw. A cell seen by the previous
look was lowered by at least (1 - p_detect), and looks further back only lower it more, so every
true continuation gains at most V: the bound is admissible and the search returns a brute-force
optimum. Children are expanded best bound first so a near-optimal path is found at once; a node's
26 children are scored in one vectorised gather that shares the parent's lowered belief (shared
prefixes). ``node_budget`` turns this into a labelled approximate, anytime planner.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.fft import irfftn, next_fast_len, rfftn

from chaser_bt.search.belief import BeliefError, GridSpec
from chaser_bt.search.sensor import SensorModel

__all__ = ["MOVES", "PlanResult", "RecedingHorizonPlanner", "move_headings"]

#: The 26 moves to adjacent cells, in a fixed (lexicographic) order.
MOVES = np.array([(dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1) if (dx, dy, dz) != (0, 0, 0)])
_HORIZONTAL = [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if (dx, dy) != (0, 0)]
#: Heading of each horizontal direction (ENU yaw, counter-clockwise from east).
HEADINGS = np.array([math.atan2(dy, dx) for dx, dy in _HORIZONTAL])
#: For each move, the index of its heading in HEADINGS, or -1 for a vertical move (keeps the heading).
MOVE_HEADING = np.array([_HORIZONTAL.index((dx, dy)) if (dx, dy) != (0, 0) else -1 for dx, dy, _ in MOVES])
_START = len(HEADINGS)  # heading index of "the vehicle's own yaw"


def move_headings(prev_heading_index: int) -> np.ndarray:
    """Heading index after each of the 26 moves, from a state with ``prev_heading_index``."""
    return np.where(MOVE_HEADING >= 0, MOVE_HEADING, prev_heading_index)


@dataclass(frozen=True)
class PlanResult:
    """A plan: the best path (cells, start first), its discounted gain, and the set-point to fly.

    ``fell_back`` means no path passed the gain threshold and ``target_enu`` is the belief maximum.
    """

    path: np.ndarray
    gain: float
    target_enu: np.ndarray
    yaw_enu_rad: float | None
    fell_back: bool
    nodes: int
    exact: bool = True  # False only when a node budget cut the search short (best path found so far)

    @property
    def next_cell(self) -> np.ndarray:
        return self.path[1] if len(self.path) > 1 else self.path[0]


class RecedingHorizonPlanner:
    """Exact Algorithm 2 (see the module docstring).

    Args:
        sensor: the sensor model (camera and grid).
        horizon: moves per path, h >= 1.
        gamma: discount factor in (0, 1].
        threshold: paths whose discounted gain does not exceed it are dropped (paper: 0.001).
        node_budget: None (default) searches to the proven optimum. A number caps the nodes
            expanded: past it the best path found so far is returned with ``exact=False`` -- an
            APPROXIMATE, anytime answer for a flight loop that must not stall.
    """

    def __init__(self, sensor: SensorModel, horizon: int = 5, gamma: float = 0.9, threshold: float = 1e-3,
                 node_budget: int | None = None) -> None:
        if int(horizon) < 1:
            raise ValueError(f"horizon must be >= 1, got {horizon}")
        if not 0.0 < gamma <= 1.0:
            raise ValueError(f"gamma must be in (0, 1], got {gamma}")
        if not (threshold >= 0 and math.isfinite(threshold)):
            raise ValueError(f"threshold must be finite and >= 0, got {threshold}")
        self.sensor, self.horizon, self.gamma, self.threshold = sensor, int(horizon), float(gamma), float(threshold)
        if node_budget is not None and int(node_budget) < 1:
            raise ValueError(f"node_budget must be >= 1 or None, got {node_budget}")
        self.node_budget = None if node_budget is None else int(node_budget)
        self._stencils = [sensor.stencil(y) for y in HEADINGS]
        self._reach = sensor.reach_cells
        self._local_shape = (2 * self.horizon + 1 + 2 * self._reach,) * 3
        self._fft_shape = tuple(next_fast_len(n, real=True) for n in self._local_shape)
        fixed = [_overlap_spectra(self._stencils, y, self._fft_shape) for y in range(len(HEADINGS))]
        self._fixed_spectra = np.stack(fixed)  # (8, 26, *rfft shape)

    @property
    def spec(self) -> GridSpec:
        return self.sensor.spec

    def plan(self, belief: np.ndarray, start_enu: np.ndarray, yaw_enu_rad: float, blocked: np.ndarray | None = None) -> PlanResult:
        """Best path from the cell nearest ``start_enu`` on ``belief`` (normalised here).

        Args:
            belief: (nx, ny, nz) non-negative belief, e.g. ``BeliefGrid.p``.
            start_enu: the vehicle's position; it starts at the nearest cell.
            yaw_enu_rad: the vehicle's yaw (heading of vertical moves until a horizontal one).
            blocked: cells the vehicle may not enter (no-go airspace, buildings).
        """
        spec, h, pd = self.spec, self.horizon, self.sensor.p_detect
        b = np.asarray(belief, dtype=float)
        if b.shape != spec.shape:
            raise BeliefError(f"belief shape {b.shape} does not match the grid {spec.shape}")
        total = b.sum()
        if not (np.isfinite(total) and total > 0) or np.any(b < 0):
            raise BeliefError("belief must be finite, non-negative and not empty to plan on")
        b = b / total
        c0 = spec.index_of(start_enu)[0][0]
        stencils = self._stencils + [self.sensor.stencil(yaw_enu_rad)]

        # Local window: cells within h moves of the start, padded by the footprint's reach.
        reach = np.full(3, self._reach)
        win = 2 * h + 1
        shape = self._local_shape
        local = np.zeros(shape)
        lo = c0 - h - reach  # grid index of local (0, 0, 0)
        src_lo, src_hi = np.maximum(lo, 0), np.minimum(lo + np.array(shape), spec.shape)
        if np.all(src_hi > src_lo):
            local[tuple(slice(s - l, e - l) for s, e, l in zip(src_lo, src_hi, lo))] = b[tuple(slice(s, e) for s, e in zip(src_lo, src_hi))]
        strides = np.array([shape[1] * shape[2], shape[2], 1])
        sentinel = local.size  # an always-zero cell that pads short footprints
        m = max(len(s) for s in stencils)
        offsets = np.full((len(stencils), max(m, 1)), sentinel, dtype=np.int64)
        for i, s in enumerate(stencils):
            offsets[i, : len(s)] = s @ strides
        flat = np.append(local.reshape(-1), 0.0)

        # Window cells u in [0, win)^3 <-> grid cell c0 + u - h.
        uu = np.stack(np.meshgrid(*(np.arange(win),) * 3, indexing="ij"), axis=-1)
        cells = c0 + uu - h
        valid = np.all((cells >= 0) & (cells < np.array(spec.shape)), axis=-1)
        if blocked is not None:
            blk = np.asarray(blocked, dtype=bool)
            valid[valid] = ~blk[tuple(cells[valid].T)]
        base = (uu + reach) @ strides  # flat index in `local` of each window cell
        pos_base = np.where(offsets == sentinel, 0, 1)  # sentinel entries must not move with the cell
        g0 = np.empty((win, win, win, len(stencils)))
        for y in range(len(stencils)):
            idx = base[..., None] * pos_base[y] + offsets[y]
            g0[..., y] = pd * flat[idx].sum(axis=-1)
        if h > 1:
            spectra = np.concatenate([self._fixed_spectra, _overlap_spectra(stencils, _START, self._fft_shape)[None]])
            overlap = _window_overlaps(local, spectra, reach, win, self._fft_shape)
            bounds = self._remaining_bounds(g0, overlap, valid, pd)
        else:
            bounds = [np.zeros_like(g0)]

        search = _Search(self, flat, offsets, pos_base, base, valid, bounds, pd)
        search.expand(0, np.array([h, h, h]), _START, 0.0, flat, [np.array([h, h, h])])
        if search.best_path is None:
            target = spec.center_of(np.unravel_index(int(np.argmax(b)), spec.shape))
            return PlanResult(np.array([c0]), 0.0, target, None, True, search.nodes, not search.cut)
        path = np.array(search.best_path) - h + c0
        step = path[1] - path[0]
        yaw = float(math.atan2(step[1], step[0])) if np.any(step[:2]) else float(yaw_enu_rad)
        return PlanResult(path, search.best_gain, spec.center_of(path[1]), yaw, False, search.nodes, not search.cut)

    def _remaining_bounds(self, g0: np.ndarray, overlap: np.ndarray, valid: np.ndarray, pd: float) -> list[np.ndarray]:
        """V_k(u, heading) for k = 0..h-1: an upper bound on the discounted gain of k more moves.

        A move from heading y to cell v (heading y') gains at most G0(v, y') = pd * (belief it sees) minus
        pd^2 * (belief in the cells that the previous look, from u with heading y, also saw):
        those cells were already lowered by at least (1 - pd). Looks further back only lower the
        belief more, so the bound holds for every path (module docstring).
        """
        win, n_head = g0.shape[0], g0.shape[-1]
        out = [np.zeros_like(g0)]
        pad = np.full((n_head, win + 2, win + 2, win + 2), -np.inf)
        for _ in range(1, self.horizon):
            prev = out[-1]
            best = np.zeros_like(g0)  # no valid move: nothing more to gain
            for m, (d, head) in enumerate(zip(MOVES, MOVE_HEADING)):
                heads = np.arange(n_head) if head < 0 else np.full(n_head, head)
                # value[y, v] of arriving at v with this move from a state of heading y
                step = np.moveaxis(g0[..., heads], -1, 0) - pd * pd * overlap[:, m]
                value = self.gamma * (step + np.moveaxis(prev[..., heads], -1, 0))
                pad[:, 1:-1, 1:-1, 1:-1] = np.where(valid[None], value, -np.inf)
                sl = pad[:, 1 + d[0] : 1 + d[0] + win, 1 + d[1] : 1 + d[1] + win, 1 + d[2] : 1 + d[2] + win]
                best = np.maximum(best, np.moveaxis(sl, 0, -1))
            out.append(best)
        return out


def _overlap_spectra(stencils: list[np.ndarray], prev: int, shape: tuple[int, int, int]) -> np.ndarray:
    """For each move from heading ``prev``: the spectrum of the offsets (from the new cell) that both looks see."""
    seen_before = {tuple(o) for o in stencils[prev]}
    masks = np.zeros((len(MOVES),) + shape)
    for m, (d, head) in enumerate(zip(MOVES, MOVE_HEADING)):
        for s in stencils[prev if head < 0 else head]:
            if tuple(s + d) in seen_before:
                masks[(m,) + tuple(np.mod(s, shape))] = 1.0
    return np.conj(rfftn(masks, axes=(1, 2, 3)))


def _window_overlaps(local: np.ndarray, spectra: np.ndarray, reach: np.ndarray, win: int, fft_shape: tuple[int, int, int]) -> np.ndarray:
    """Belief in each move's overlap set, for every window cell: (heading, move, win, win, win).

    Computed as circular cross-correlations by FFT (on a zero-padded fast length); the offsets
    never wrap because the window is padded by the footprint's reach. FFT rounding (~1e-16 of the mass) is taken off with a
    1e-12 margin so the result never exceeds the exact sum (the bound stays admissible).
    """
    corr = irfftn(rfftn(local, s=fft_shape)[None, None] * spectra, s=fft_shape, axes=(2, 3, 4), workers=-1)
    r = reach
    corr = corr[:, :, r[0] : r[0] + win, r[1] : r[1] + win, r[2] : r[2] + win]
    return np.maximum(corr - 1e-12, 0.0)


class _Search:
    """Depth-first branch and bound over move sequences (one instance per plan)."""

    def __init__(self, planner: RecedingHorizonPlanner, flat, offsets, pos_base, base, valid, bounds, pd) -> None:
        self.h, self.gamma, self.threshold = planner.horizon, planner.gamma, planner.threshold
        self.offsets, self.pos_base, self.base, self.valid, self.bounds, self.pd = offsets, pos_base, base, valid, bounds, pd
        self.win = base.shape[0]
        self.best_gain = -math.inf
        self.best_path: list[np.ndarray] | None = None
        self.nodes = 0
        self.budget = planner.node_budget
        self.cut = False

    def expand(self, depth: int, u: np.ndarray, heading: int, g: float, flat: np.ndarray, path: list[np.ndarray]) -> None:
        self.nodes += 1
        nbrs = u + MOVES
        ok = np.all((nbrs >= 0) & (nbrs < self.win), axis=1)
        ok[ok] = self.valid[tuple(nbrs[ok].T)]
        if not ok.any():
            return
        nbrs = nbrs[ok]
        heads = move_headings(heading)[ok]
        idx = self.base[tuple(nbrs.T)][:, None] * self.pos_base[heads] + self.offsets[heads]
        disc = self.gamma ** (depth + 1)
        gains = g + disc * (self.pd * flat[idx].sum(axis=1))
        keep = gains > self.threshold  # Algorithm 2's gain threshold
        if not keep.any():
            return
        nbrs, heads, idx, gains = nbrs[keep], heads[keep], idx[keep], gains[keep]
        top = int(np.argmax(gains))
        if gains[top] > self.best_gain:
            self.best_gain, self.best_path = float(gains[top]), path + [nbrs[top]]
        if depth + 1 == self.h:
            return
        bound = gains + disc * self.bounds[self.h - depth - 1][tuple(nbrs.T) + (heads,)]
        for i in np.argsort(-bound, kind="stable"):
            # Admissible bound no better than the incumbent: nothing below can win (slack for rounding).
            if bound[i] * (1.0 + 1e-12) + 1e-15 <= self.best_gain:
                break
            if self.budget is not None and self.nodes >= self.budget:
                self.cut = True  # approximate from here on: the caller asked for an anytime answer
                return
            child = flat.copy()
            child[idx[i]] *= 1.0 - self.pd
            self.expand(depth + 1, nbrs[i], int(heads[i]), float(gains[i]), child, path + [nbrs[i]])
