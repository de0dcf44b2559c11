"""Our correlator: gate every report on position *and* velocity, confirm fast, hold with hysteresis.

Algorithm 1 needs a new track to win two of three 2-second windows before it is taken, so after
every drop the ownship goes unassociated for 2-4 s, and after a swap the old id keeps the
association for as long. This method looks at each track's last few reports instead:

* a report is *consistent* with the ownship when its distance to the interpolated GPS is inside
  ``max(floor_m, gate_sigma * sigma)`` (sigma: that report's expected radar error, which grows
  with range) and, when the radar gives a velocity, the velocity differs from the ownship's by
  less than ``vel_gate_mps``;
* a track is a *candidate* when its last ``confirm_n`` reports are all consistent; it is
  *rejected* when ``reject_n`` of its last ``reject_window`` reports are not;
* hysteresis: the associated track is kept while it is active, not rejected and reported within
  ``hold_s`` (or no fresher candidate exists), so duplicates and
  close passes do not make it flicker; otherwise the candidate with the smallest mean normalised
  residual is taken at once (a one-target assignment on a gated cost);
* but a held track gives way to a candidate at least ``switch_margin`` cheaper that is not a
  duplicate of it (further than ``ambiguity_m``): at long range the gate is tens of metres wide,
  and a drone we follow a few tens of metres away, at our velocity, passes it too;
* a new association is not made while another, non-candidate track is within ``ambiguity_m`` of
  the candidate: in a close pass the method waits rather than guesses;
* every candidate within ``ambiguity_m`` of the associated track is attributed to the ownship, so
  the radar's duplicate tracks of our own drone are filtered out of the mission's picture as well
  (a candidate further away is another drone inside the gate, not us).

* a track reported at the same time as the associated one and at least ``ambiguity_m`` from it is
  another object (the drone we follow, a bird), unless it fits the GPS better than the associated
  one by ``switch_margin`` (then the association may be the mistake): it is never taken for the ownship on the gate alone,
  which at long range is tens of metres wide. Only the ownship's own telemetry reclaims it: every
  report of the last ``reclaim_s`` seconds (at least ``reject_window`` of them) consistent and their
  mean offset from the GPS under ``floor_m`` (an id swap with our own track). A few reports are not
  enough: in a close pass the radar cannot part two drones ten metres apart, and four noisy reports
  of the other one average onto our GPS by chance; over two seconds the two have drifted apart. So
  when our track drops, a co-moving intruder a dozen metres away is not taken for us, and it stays
  in the mission's picture. A track stays "apart" while the radar keeps reporting it within the
  history window, so a report gap does not launder it.

The velocity gate is what catches a swap within a scan or two: the ids exchange where the two
drones are close in position, but they rarely fly the same velocity there.
"""

from __future__ import annotations

import numpy as np

from chaser_bt.radar.correlator.base import CorrelationWindow, TrackCorrelator

__all__ = ["GatedCorrelator"]


class GatedCorrelator(TrackCorrelator):
    """Position and velocity gating with confirmation and hysteresis.

    Args:
        gate_sigma: position gate in multiples of each report's expected error.
        floor_m: smallest position gate (GPS and calibration error, m).
        vel_gate_mps: velocity gate (m/s); reports without velocity skip it.
        confirm_n: consecutive consistent reports that make a track a candidate.
        reject_window, reject_n: ``reject_n`` inconsistent among the last ``reject_window``
            reports reject the associated track.
        ambiguity_m: a candidate with a non-candidate track closer than this is not taken (two
            drones passing close: wait until they part rather than guess).
        hold_s: the associated track, unreported for longer than this, gives way to a fresher
            candidate (the radar dropped it and already tracks the ownship under a new id).
        switch_margin: a candidate whose mean normalised residual is lower than the associated
            track's by this much, and not within ``ambiguity_m`` of it, takes the association.
        reclaim_s: how long a track seen apart must stay on the GPS before it is taken for ours.
    """

    name = "gated"

    def __init__(self, *, gate_sigma: float = 4.0, floor_m: float = 5.0, vel_gate_mps: float = 3.0,
                 confirm_n: int = 2, reject_window: int = 4, reject_n: int = 2, active_s: float = 1.0,
                 ambiguity_m: float = 10.0, hold_s: float = 0.5, switch_margin: float = 0.3, history_s: float = 3.0,
                 max_gps_gap_s: float = 1.0, reclaim_s: float = 2.0) -> None:
        super().__init__(history_s=history_s, active_s=active_s, max_gps_gap_s=max_gps_gap_s)
        if not (1 <= confirm_n and 1 <= reject_n <= reject_window):
            raise ValueError("need 1 <= confirm_n and 1 <= reject_n <= reject_window")
        if not 0.0 <= reclaim_s < history_s:
            raise ValueError(f"reclaim_s must be in [0, history_s = {history_s}), got {reclaim_s}")
        self.reclaim_s = reclaim_s
        self.gate_sigma = gate_sigma
        self.floor_m = floor_m
        self.vel_gate_mps = vel_gate_mps
        self.confirm_n = confirm_n
        self.reject_window = reject_window
        self.reject_n = reject_n
        self.ambiguity_m = ambiguity_m
        self.hold_s = hold_s
        self.switch_margin = switch_margin
        self._candidates: frozenset[int] = frozenset()
        self._latest: dict[int, np.ndarray] = {}
        self._apart: set[int] = set()  # ids seen beside the ownship's track: other objects

    def reset(self) -> None:
        super().reset()
        self._candidates, self._latest, self._apart = frozenset(), {}, set()

    def _consistency(self, w: CorrelationWindow) -> tuple[np.ndarray, np.ndarray]:
        """Per report: consistent with the ownship?, and its normalised residual."""
        p = w.points
        d = w.distance()
        gate = np.maximum(self.floor_m, self.gate_sigma * p.sigma_m)
        dv = np.linalg.norm(p.velocity - w.gps_velocity, axis=1)
        vel_ok = np.isnan(dv) | (dv < self.vel_gate_mps)
        cost = d / gate + np.where(np.isnan(dv), 0.0, dv / self.vel_gate_mps)
        return (d < gate) & vel_ok, cost

    def _decide(self, w: CorrelationWindow) -> int | None:
        p = w.points
        if not w.active_ids.size:
            self._candidates = frozenset()
            return None
        ok, cost = self._consistency(w)
        order = np.lexsort((p.t, p.track_id))
        ids_sorted = p.track_id[order]
        starts = np.searchsorted(ids_sorted, w.active_ids, side="left")
        ends = np.searchsorted(ids_sorted, w.active_ids, side="right")
        candidates: dict[int, float] = {}
        recent_cost: dict[int, float] = {}
        rejected: set[int] = set()
        latest: dict[int, np.ndarray] = {}
        last_t: dict[int, float] = {}
        n_keep = max(self.confirm_n, self.reject_window)
        for tid, s, e in zip(w.active_ids.tolist(), starts, ends):
            idx = order[max(s, e - n_keep):e]
            latest[tid] = p.position[idx[-1]]
            last_t[tid] = float(p.t[idx[-1]])
            last_ok = ok[idx]
            tail = last_ok[-self.confirm_n:]
            recent_cost[tid] = float(cost[idx[-self.confirm_n:]].mean())
            if tail.size == self.confirm_n and tail.all() and (tid not in self._apart or self._reclaimed(w, ok, s, e, order)):
                candidates[tid] = recent_cost[tid]
            if (~last_ok[-self.reject_window:]).sum() >= self.reject_n:
                rejected.add(tid)
        self._candidates = frozenset(candidates)
        self._latest = latest
        self._note_apart(set(np.unique(p.track_id).tolist()), latest, last_t, recent_cost)
        a = self.associated_id
        if a is not None and a in set(w.active_ids.tolist()) and a not in rejected:
            fresher = [k for k in candidates if k != a and last_t[k] > last_t[a]]
            better = [k for k, c in candidates.items() if k != a and c < recent_cost[a] - self.switch_margin
                      and float(np.linalg.norm(latest[k] - latest[a])) >= self.ambiguity_m and not self._ambiguous(k, latest)]
            if better:
                return min(better, key=lambda k: (candidates[k], k))
            if w.t - last_t[a] <= self.hold_s or not fresher:
                return a
        clear = {k: c for k, c in candidates.items() if not self._ambiguous(k, latest)}
        if not clear:
            return None
        return min(clear, key=lambda k: (w.t - last_t[k] > self.hold_s, clear[k], k))

    def _note_apart(self, seen: set[int], latest: dict[int, np.ndarray], last_t: dict[int, float],
                    cost: dict[int, float]) -> None:
        """Remember the tracks reported beside the associated one, at least ``ambiguity_m`` from it and
        no closer to the GPS than it (a track that fits better may be ours: the association may be wrong).
        Forgotten once out of the history window (``seen``): radar ids are not reused."""
        self._apart &= seen
        a = self.associated_id
        if a is None or a not in latest:
            return
        for k, pos in latest.items():
            if (k != a and abs(last_t[k] - last_t[a]) <= 0.5 and cost[k] >= cost[a] - self.switch_margin
                    and float(np.linalg.norm(pos - latest[a])) >= self.ambiguity_m):
                self._apart.add(k)

    def _reclaimed(self, w: CorrelationWindow, ok: np.ndarray, start: int, end: int, order: np.ndarray) -> bool:
        """Whether the ownship's telemetry says a track seen apart is now ours: reported for at least
        ``reclaim_s``, every report of the last ``reclaim_s`` (at least ``reject_window``) consistent
        with the GPS, and their mean offset from it under ``floor_m``."""
        idx = order[start:end]
        t = w.points.t[idx]
        if t.size == 0 or t[0] > w.t - self.reclaim_s:
            return False
        idx = idx[t >= w.t - self.reclaim_s]
        if idx.size < self.reject_window or not ok[idx].all():
            return False
        offset = (w.points.position[idx] - w.gps_position[idx]).mean(axis=0)
        return float(np.linalg.norm(offset)) < self.floor_m

    def _ambiguous(self, tid: int, latest: dict[int, np.ndarray]) -> bool:
        """Another track that is not a candidate sits close to candidate ``tid`` (a close pass)."""
        here = latest[tid]
        return any(float(np.linalg.norm(p - here)) < self.ambiguity_m
                   for k, p in latest.items() if k != tid and k not in self._candidates)

    def _ownship_ids(self, w: CorrelationWindow) -> frozenset[int]:
        own = set(super()._ownship_ids(w))
        a = self.associated_id
        if a is None or a not in self._latest:
            return frozenset(own | set(self._candidates))
        here = self._latest[a]
        return frozenset(own | {k for k in self._candidates
                                if float(np.linalg.norm(self._latest[k] - here)) < self.ambiguity_m})
