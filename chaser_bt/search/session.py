"""One search in progress: belief, dynamics, sensor model and planner, advanced by mission time.

Each :meth:`SearchSession.update` does what the paper's loop does once (section 3.4, figure
"RHC triplet"): advance the belief by the elapsed time (dynamics), lower it where the camera
looks now (sensor model S at the vehicle's real pose), and, when the vehicle has reached its
step (or ``replan_s`` passed), plan again and return the next set-point. Time is passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.search.belief import BeliefError, BeliefGrid
from chaser_bt.search.rhc import PlanResult
from chaser_bt.search.sensor import SensorModel, level_attitude

__all__ = ["Dynamics", "Planner", "SearchSession", "SearchSnapshot"]


class Dynamics(Protocol):
    def step(self, belief: BeliefGrid, dt: float) -> None: ...


class Planner(Protocol):
    def plan(self, belief: np.ndarray, start_enu: np.ndarray, yaw_enu_rad: float, blocked: np.ndarray | None = None) -> PlanResult: ...


@dataclass(frozen=True)
class SearchSnapshot:
    """What the search knows after an update (published on the blackboard for plots and logs).

    Args:
        t: mission time of the update (s).
        belief: the belief grid (unnormalised; ``belief.normalized()`` for plots).
        gain: belief gain of the camera's look at this update: P(detect now | not seen before).
        target_enu: the set-point being flown to.
        yaw_enu_rad: the heading to fly it with (None: keep the vehicle's).
        plan: the latest plan.
        replanned: whether this update planned.
    """

    t: float
    belief: BeliefGrid
    gain: float
    target_enu: np.ndarray
    yaw_enu_rad: float | None
    plan: PlanResult
    replanned: bool


class SearchSession:
    """A running search from an initial belief at time ``t0``.

    Args:
        belief: B_0, e.g. :meth:`BeliefGrid.from_cue` (mutated in place as the search goes).
        dynamics: target dynamics model.
        sensor: sensor model S.
        planner: :class:`RecedingHorizonPlanner` or :class:`MaxBeliefPlanner`.
        t0: mission time of B_0 (the cue's time).
        acceptance_m: re-plan once the vehicle is this close to its set-point (default 0.35 cell).
        replan_s: re-plan at least this often (s).
        blocked: cells the vehicle may not enter (default: the belief's no-go cells).
    """

    def __init__(self, belief: BeliefGrid, dynamics: Dynamics, sensor: SensorModel, planner: Planner, t0: float,
                 acceptance_m: float | None = None, replan_s: float = 2.0, blocked: np.ndarray | None = None) -> None:
        if not math.isfinite(t0):
            raise BeliefError(f"search start time must be finite, got {t0}")
        self.belief, self.dynamics, self.sensor, self.planner = belief, dynamics, sensor, planner
        self.t = float(t0)
        self.acceptance_m = 0.35 * belief.spec.spacing_m if acceptance_m is None else float(acceptance_m)
        self.replan_s = float(replan_s)
        self.blocked = belief.nogo if blocked is None else np.asarray(blocked, dtype=bool)
        self.plan: PlanResult | None = None
        self._planned_at = -math.inf

    def update(self, t: float, vehicle_pos_enu: np.ndarray, body_attitude: Rotation | None, yaw_enu_rad: float) -> SearchSnapshot:
        """Advance to mission time ``t``, look from the vehicle's pose, re-plan when due."""
        pos = np.asarray(vehicle_pos_enu, dtype=float)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise BeliefError(f"vehicle position must be 3 finite numbers, got {vehicle_pos_enu!r}")
        yaw = float(yaw_enu_rad) if math.isfinite(yaw_enu_rad) else 0.0
        attitude = body_attitude if body_attitude is not None else level_attitude(yaw)
        dt = t - self.t
        if dt > 0:  # a clock that steps back is ignored rather than un-spreading the belief
            self.dynamics.step(self.belief, dt)
            self.t = float(t)
        gain = self.sensor.observe(self.belief, pos, attitude)
        due = (
            self.plan is None
            or t - self._planned_at >= self.replan_s
            or float(np.linalg.norm(pos - self.plan.target_enu)) <= self.acceptance_m
        )
        if due:
            self.plan = self.planner.plan(self.belief.p, pos, yaw, self.blocked)
            self._planned_at = float(t)
        assert self.plan is not None
        return SearchSnapshot(float(t), self.belief, gain, self.plan.target_enu, self.plan.yaw_enu_rad, self.plan, due)
