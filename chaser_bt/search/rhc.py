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
optimum. Children are expanded best bound first so a near-optimal path is found at once; the
path's looks lower the belief in place on the way down and are undone exactly (saved values) on
the way back, so every prefix is scored once and shared by its subtree. The window sums, the bound's
dynamic programme and the search are compiled (:mod:`chaser_bt.search.rhc_kernel`, numba); this
module prepares their inputs. ``node_budget`` turns this into a labelled approximate, anytime planner.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from chaser_bt.search.belief import BeliefError, GridSpec
from chaser_bt.search.rhc_kernel import branch_and_bound, remaining_bounds, window_sums
from chaser_bt.search.sensor import SensorModel
from chaser_bt.vision.camera import CameraModel

__all__ = ["MOVES", "PlanResult", "RecedingHorizonPlanner", "move_headings", "warm_up_planner"]

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
        # For each (previous heading, move): which offsets of the new look the previous look saw
        # too (the overlap sets of the bound), grouped by the new look's heading.
        self._members = np.stack([_membership(st, self._reach) for st in self._stencils])
        width = max(len(st) for st in self._stencils)
        fixed = [_overlap_indices(self._stencils, self._members, y, self._reach, width) for y in range(len(HEADINGS))]
        self._ov_idx = np.stack([i for i, _ in fixed])
        self._ov_len = np.stack([n for _, n in fixed])

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
        m = max(len(st) for st in stencils)
        offs = np.zeros((len(stencils), max(m, 1)), dtype=np.int64)
        lens = np.array([len(st) for st in stencils], dtype=np.int64)
        for i, st in enumerate(stencils):
            offs[i, : len(st)] = st @ strides
        flat = local.reshape(-1)

        # Window cells u in [0, win)^3 <-> grid cell c0 + u - h.
        uu = np.stack(np.meshgrid(*(np.arange(win),) * 3, indexing="ij"), axis=-1)
        cells = c0 + uu - h
        valid = np.all((cells >= 0) & (cells < np.array(spec.shape)), axis=-1)
        if blocked is not None:
            blk = np.asarray(blocked, dtype=bool)
            valid[valid] = ~blk[tuple(cells[valid].T)]
        base = ((uu + reach) @ strides).reshape(-1)  # flat index in `local` of each window cell
        valid = valid.reshape(-1)
        if h > 1:
            members = np.concatenate([self._members, _membership(stencils[_START], self._reach)[None]])
            start_idx, start_len = _overlap_indices(stencils, members, _START, self._reach, offs.shape[1])
            ov_idx = np.zeros((len(stencils), len(MOVES), offs.shape[1]), dtype=np.int64)
            ov_idx[: len(HEADINGS), :, : self._ov_idx.shape[2]] = self._ov_idx
            ov_idx[_START] = start_idx
            ov_len = np.concatenate([self._ov_len, start_len[None]])
            g0, overlap = window_sums(flat, base, offs, lens, ov_idx, ov_len, MOVE_HEADING, pd)
            bounds = remaining_bounds(g0, overlap, valid, MOVES, MOVE_HEADING, win, h, self.gamma, pd)
        else:
            bounds = np.zeros((1, len(stencils), base.size))
        gain, best, n_best, nodes, cut = branch_and_bound(
            flat, offs, lens, base, valid, bounds, MOVES, MOVE_HEADING, win, h, _START, self.gamma, pd,
            self.threshold, 0 if self.node_budget is None else self.node_budget)
        if n_best == 0:
            target = spec.center_of(np.unravel_index(int(np.argmax(b)), spec.shape))
            return PlanResult(np.array([c0]), 0.0, target, None, True, int(nodes), not cut)
        path = best[:n_best] - h + c0
        step = path[1] - path[0]
        yaw = float(math.atan2(step[1], step[0])) if np.any(step[:2]) else float(yaw_enu_rad)
        return PlanResult(path, float(gain), spec.center_of(path[1]), yaw, False, int(nodes), not cut)


def warm_up_planner() -> None:
    """Compile (or load from numba's on-disk cache) the planner's kernels now, on a tiny problem.

    The first plan in a process otherwise pays it: seconds when compiling, about a second when
    loading. Behaviours call this from ``setup()``, before the mission flies.
    """
    spec = GridSpec((0.0, 0.0, 0.0), 20.0, (3, 3, 2))
    planner = RecedingHorizonPlanner(SensorModel(CameraModel(), spec), horizon=2)
    planner.plan(np.ones(spec.shape), spec.center_of([1, 1, 0]), 0.0)


def _membership(stencil: np.ndarray, reach: int) -> np.ndarray:
    """Boolean cube over offsets within reach + 1 cells: True where the look sees that offset."""
    cube = np.zeros((2 * reach + 3,) * 3, dtype=bool)
    if len(stencil):
        cube[tuple((stencil + reach + 1).T)] = True
    return cube


def _overlap_indices(stencils: list[np.ndarray], members: np.ndarray, prev: int, reach: int,
                     width: int) -> tuple[np.ndarray, np.ndarray]:
    """For each move from heading ``prev``: the positions (in the new look's stencil) of the offsets
    s with s + move inside the previous look -- the cells both looks see. Padded to ``width``."""
    idx = np.zeros((len(MOVES), width), dtype=np.int64)
    n = np.zeros(len(MOVES), dtype=np.int64)
    for mi, (d, head) in enumerate(zip(MOVES, MOVE_HEADING)):
        st = stencils[prev if head < 0 else head]
        if len(st):
            pos = np.flatnonzero(members[prev][tuple((st + d + reach + 1).T)])
            idx[mi, : len(pos)], n[mi] = pos, len(pos)
    return idx, n
