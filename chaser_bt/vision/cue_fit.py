"""How well each camera track fits the designated target's cue, over time: radar-camera association.

The cue's gate (:class:`~chaser_bt.vision.pipeline.VisionPipeline`) keeps out what cannot be the
target on one frame, but at follow range its radar error spans tens of degrees, so a second drone
crossing close by passes it too, and the trackers may slide onto it. One frame cannot tell the two
apart; a second or two can. :func:`~chaser_bt.cue.sight_offset_sigma` measures, in the cue's own error, how far the
cue lies from a track's line of sight (the camera knows the bearing well and the range poorly, so
the range is left free); :class:`CueFit` keeps a running mean of it per track, and names a track
that fits clearly better than the one followed once the followed one has drifted off the cue.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from chaser_bt.cue import sight_offset_sigma

__all__ = ["CueFit"]


@dataclass
class CueFit:
    """Running fit of camera tracks to the cue.

    Args:
        tau_s: time constant of each track's running mean offset (s).
        switch_sigma: the followed track is given up once its running offset exceeds this.
        margin_sigma: for a track whose running offset is lower by at least this.
        floor_m: added to the cue's error on every axis (the target's size, the cue's lag).
    """

    tau_s: float = 1.0
    switch_sigma: float = 2.5
    margin_sigma: float = 1.0
    floor_m: float = 1.0
    _fit: dict[int, tuple[float, float]] = field(default_factory=dict)  # track id -> (t, running offset)

    def reset(self) -> None:
        self._fit.clear()

    def offset(self, track_id: int) -> float | None:
        """The track's running offset from the cue (sigma), None before its first fit."""
        fit = self._fit.get(track_id)
        return None if fit is None else fit[1]

    def update(self, t: float, camera_enu: np.ndarray, tracks: dict[int, np.ndarray], cue_enu: np.ndarray,
               cue_cov: np.ndarray) -> None:
        """Fold in one frame: ``tracks`` maps each live track's id to its bearing (ENU unit vector).
        Tracks no longer live are forgotten."""
        cov = np.asarray(cue_cov, float) + self.floor_m**2 * np.eye(3)
        self._fit = {k: v for k, v in self._fit.items() if k in tracks}
        for tid, bearing in tracks.items():
            r = sight_offset_sigma(camera_enu, bearing, cue_enu, cov)
            last = self._fit.get(tid)
            if last is None:
                self._fit[tid] = (t, r)
            elif t > last[0]:
                a = 1.0 - math.exp(-(t - last[0]) / self.tau_s)
                self._fit[tid] = (t, last[1] + a * (r - last[1]))

    def better_than(self, followed: int, candidates: list[int]) -> int | None:
        """A candidate to follow instead of ``followed``: only once ``followed`` has drifted off the cue
        (running offset above ``switch_sigma``), the best-fitting candidate at least ``margin_sigma``
        closer to it; else None (keep following)."""
        current = self.offset(followed)
        if current is None or current <= self.switch_sigma:
            return None
        fits = [(self.offset(k), k) for k in candidates if k != followed and self.offset(k) is not None]
        if not fits:
            return None
        best, k = min(fits)
        return k if best <= current - self.margin_sigma else None
