"""Max-belief search: go straight to the most probable cell (the paper's baseline, section 4.4).

The same belief, dynamics and sensor model as RHC; only the planner differs: the set-point is the
centre of the belief maximum, however far, instead of one adjacent step of the best path.
"""

from __future__ import annotations

import math

import numpy as np

from chaser_bt.search.belief import BeliefError, GridSpec
from chaser_bt.search.rhc import PlanResult

__all__ = ["MaxBeliefPlanner"]


class MaxBeliefPlanner:
    """Plan straight to the maximum of the belief (ties: the first cell in C order)."""

    def __init__(self, spec: GridSpec) -> None:
        self.spec = spec

    def plan(self, belief: np.ndarray, start_enu: np.ndarray, yaw_enu_rad: float, blocked: np.ndarray | None = None) -> PlanResult:
        """``blocked`` cells are never chosen (the belief is zero there anyway when they are no-go)."""
        b = np.asarray(belief, dtype=float)
        if b.shape != self.spec.shape:
            raise BeliefError(f"belief shape {b.shape} does not match the grid {self.spec.shape}")
        if not np.all(np.isfinite(b)) or not b.sum() > 0:
            raise BeliefError("belief must be finite and not empty to plan on")
        if blocked is not None:
            b = np.where(blocked, -np.inf, b)
        cell = np.array(np.unravel_index(int(np.argmax(b)), self.spec.shape))
        start = self.spec.index_of(start_enu)[0][0]
        target = self.spec.center_of(cell)
        delta = target - np.asarray(start_enu, dtype=float)
        yaw = float(math.atan2(delta[1], delta[0])) if np.hypot(delta[0], delta[1]) > 1e-6 else float(yaw_enu_rad)
        return PlanResult(np.array([start, cell]), 0.0, target, yaw, False, 1)
