"""Algorithm 1 of the paper (section 3.3, "Radar Track Correlation"), as written.

For every active track R_i the GPS track G is interpolated to R_i's report times and a report
is a *detection* when |R_i(t) - G~_i(t)| < epsilon. N_i^(0) counts detections with t > T-2.
With no associated id A yet, A = argmax_i N_i^(0). When A is not that argmax, the older windows
N^(1) over (T-4, T-2] and N^(2) over (T-6, T-4] are counted too, m^(j) = argmax_i N_i^(j), and if
any two of m^(0), m^(1), m^(2) are equal, A becomes the most frequent of them.

Where the pseudo-code is silent this implementation decides, and docs/radar.md says so:

* ``argmax`` over counts that are all zero is *no track* (a window with no detection has no
  winner, and two such windows do not "agree");
* ties go to the current A when it is among the maxima, otherwise to the lowest id;
* A is never cleared (the algorithm has no such step); it is *reported* only while that track is
  active, so a dropped track stops being the ownship's until a new one wins;
* only the associated id is the ownship's: every other active track is unassociated, duplicates
  of the ownship included (the paper filters on the associated id alone).
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from chaser_bt.radar.correlator.base import CorrelationWindow, TrackCorrelator

__all__ = ["Algorithm1Correlator"]


class Algorithm1Correlator(TrackCorrelator):
    """The paper's correlator.

    Args:
        epsilon_m: detection threshold distance epsilon (m).
        window_s: length of each counting window (the paper's 2 s).
        active_s: a track reported within this many seconds is active.
    """

    name = "alg1"

    def __init__(self, *, epsilon_m: float = 10.0, window_s: float = 2.0, active_s: float = 1.0,
                 max_gps_gap_s: float = 1.0) -> None:
        super().__init__(history_s=3.0 * window_s, active_s=active_s, max_gps_gap_s=max_gps_gap_s)
        if epsilon_m <= 0 or window_s <= 0:
            raise ValueError("epsilon_m and window_s must be positive")
        self.epsilon_m = epsilon_m
        self.window_s = window_s

    def _decide(self, w: CorrelationWindow) -> int | None:
        act = w.active_ids
        if act.size == 0:
            return self.associated_id
        T, W = w.t, self.window_s
        t = w.points.t
        detection = w.distance() < self.epsilon_m
        windows = (t > T - W, (t <= T - W) & (t > T - 2 * W), (t <= T - 2 * W) & (t > T - 3 * W))
        pos = np.clip(np.searchsorted(act, w.points.track_id), 0, act.size - 1)
        is_active = act[pos] == w.points.track_id

        def winner(in_window: np.ndarray) -> int | None:
            sel = detection & in_window & is_active
            counts = np.bincount(pos[sel], minlength=act.size)
            top = counts.max()
            if top == 0:
                return None
            best = act[counts == top]
            a = self.associated_id
            return a if a is not None and a in best else int(best[0])

        a = self.associated_id
        m0 = winner(windows[0])
        if a is None:
            return m0
        if m0 == a:
            return a
        m = [m0, winner(windows[1]), winner(windows[2])]
        votes = Counter(x for x in m if x is not None)
        if votes and max(votes.values()) >= 2:
            return votes.most_common(1)[0][0]
        return a
