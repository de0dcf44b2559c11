"""Is the aircraft getting anywhere? A bound on how long a movement may go without progress.

An autopilot that will not fly a target says so only sometimes: ArduCopter's fence refuses a GUIDED
target outside it and holds where it is, a wind it cannot beat holds it in place, a target it never
received leaves it hovering. A leaf that waits for arrival would wait for the battery. The watch
keeps the best distance to go so far and when it last improved by ``min_progress_m``; after
``window_s`` without such an improvement the movement has stalled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["ClosingWatch", "ProgressWatch"]


@dataclass
class ProgressWatch:
    """Feed it ``(t, distance_to_go)``; :meth:`stalled` once ``window_s`` pass without the distance
    falling ``min_progress_m`` below its best. ``window_s`` ≤ 0 never stalls."""

    window_s: float = 20.0
    min_progress_m: float = 2.0
    best_m: float = field(default=math.inf, init=False)
    improved_at_s: float | None = field(default=None, init=False)

    def observe(self, t: float, distance_m: float) -> None:
        if not math.isfinite(distance_m):
            return  # no position this tick: neither progress nor its absence
        if self.improved_at_s is None or distance_m < self.best_m - self.min_progress_m:
            self.best_m, self.improved_at_s = distance_m, t  # the anchor: creeping counts once it adds up

    def stalled(self, t: float) -> bool:
        return self.window_s > 0 and self.improved_at_s is not None and t - self.improved_at_s > self.window_s

    def since_s(self, t: float) -> float:
        """Seconds since the last progress (0 before the first observation)."""
        return 0.0 if self.improved_at_s is None else t - self.improved_at_s


@dataclass
class ClosingWatch:
    """A :class:`ProgressWatch` for a goal that moves (a cue, a search set-point): progress is the
    distance flown *towards* wherever the goal is now, so a chase that keeps its range to a fleeing
    target still counts as progress while a vehicle the autopilot holds in place does not. Within
    ``near_m`` of the goal the vehicle is where it was sent: that is progress too.
    """

    window_s: float = 30.0
    min_progress_m: float = 2.0
    near_m: float = 5.0
    closed_m: float = field(default=0.0, init=False)
    _watch: ProgressWatch = field(init=False)
    _last: np.ndarray | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        self._watch = ProgressWatch(self.window_s, self.min_progress_m)

    def observe(self, t: float, position: np.ndarray, goal: np.ndarray) -> None:
        position, goal = np.asarray(position, dtype=float), np.asarray(goal, dtype=float)
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(goal))):
            return
        if self._last is not None:
            to_goal = goal - self._last
            norm = float(np.linalg.norm(to_goal))
            if norm > 1e-6:
                self.closed_m += float(np.dot(position - self._last, to_goal) / norm)
        self._last = position
        if float(np.linalg.norm(goal - position)) <= self.near_m:
            self._watch = ProgressWatch(self.window_s, self.min_progress_m)  # arrived: the clock starts again
        self._watch.observe(t, -self.closed_m)

    def stalled(self, t: float) -> bool:
        return self._watch.stalled(t)

    def since_s(self, t: float) -> float:
        return self._watch.since_s(t)
