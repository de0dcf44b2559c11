"""Search-and-rescue scores: did the mission's find land on the person? (Ground truth: scoring only.)

The mission reports its find on ``/sar/find`` (:class:`chaser_bt.find.Find`, written by the
``ReportFind`` behaviour); the simulator knows where the people are (the scenario's ``kind:
person`` targets, placed for the run's seed: ``sim.scenario``). Report keys:

- ``sar_found``: the last find is within ``found_radius_m`` (10 m: a rescuer sent to the point sees
  the person) of a person, horizontally. False when the mission reported nothing or the wrong place.
- ``sar_find_error_m``: horizontal distance from the last find to the nearest person (None: no find).
- ``sar_t_find_s``: simulated seconds from launch (first time airborne) to the first find.

All three are None in a scenario without a person. :class:`SarObserver` collects them during a
rehearsal: ``rehearse(..., on_start=observer.attach)`` hooks it to the runner's ticks, or the
rehearsal calls :meth:`SarObserver.after_tick` itself after each tick.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import py_trees

from chaser_bt.find import Find

__all__ = ["FIND_KEY", "FOUND_RADIUS_M", "SarObserver", "people_enu", "score_find"]

FIND_KEY = "/sar/find"
FOUND_RADIUS_M = 10.0


def people_enu(scenario: Any, t: float = 0.0) -> list[np.ndarray]:
    """Truth ENU positions of the scenario's people at sim time ``t`` (use the simulator's placed scenario)."""
    return [np.asarray(tg.path.position_enu(t), float) for tg in scenario.targets if tg.kind == "person"]


def score_find(find_enu: np.ndarray | None, people: Sequence[np.ndarray],
               found_radius_m: float = FOUND_RADIUS_M) -> dict[str, Any]:
    """``sar_found`` and ``sar_find_error_m`` for a find (None: nothing reported) against the people's truth."""
    if not people:
        return {"sar_found": None, "sar_find_error_m": None}
    if find_enu is None:
        return {"sar_found": False, "sar_find_error_m": None}
    err = min(float(np.hypot(*(np.asarray(find_enu, float)[:2] - p[:2]))) for p in people)
    return {"sar_found": err <= found_radius_m, "sar_find_error_m": round(err, 2)}


class SarObserver:
    """Watches ``/sar/find`` after every tick of a rehearsal; :meth:`report_keys` scores it."""

    def __init__(self, sim: Any, found_radius_m: float = FOUND_RADIUS_M) -> None:
        self.sim = sim
        self.found_radius_m = found_radius_m
        self.has_person = bool(people_enu(sim.scenario))
        self.launch_s: float | None = None
        self.first_find_s: float | None = None
        self.find: Find | None = None

    def after_tick(self) -> None:
        """Called by the rehearsal after every tick: note the launch and the latest find."""
        t = self.sim.time_s
        if self.launch_s is None and not self.sim.truth.on_ground:
            self.launch_s = t
        find = py_trees.blackboard.Blackboard.storage.get(FIND_KEY)
        if isinstance(find, Find):
            self.find = find
            if self.first_find_s is None:
                self.first_find_s = t

    def report_keys(self) -> dict[str, Any]:
        """``sar_found``, ``sar_find_error_m``, ``sar_t_find_s`` (all None without a person in the scenario)."""
        if not self.has_person:
            return {"sar_found": None, "sar_find_error_m": None, "sar_t_find_s": None}
        keys = score_find(None if self.find is None else self.find.position_enu, people_enu(self.sim.scenario, self.sim.time_s),
                          self.found_radius_m)
        found_at = None if self.first_find_s is None or self.launch_s is None else round(self.first_find_s - self.launch_s, 2)
        return {**keys, "sar_t_find_s": found_at}
