"""The track-correlator interface (paper section 3.3): which radar track is our own drone?

A correlator is fed the radar's tracks, already in the mission's ENU frame, and the ownship's GPS
positions; :meth:`TrackCorrelator.associate` then says which track id is the ownship (the
associated id), which ids are also the ownship (duplicates it recognises) and which tracks are
left for the mission: the unassociated ones. Implementations differ only in
:meth:`TrackCorrelator._decide`; the history keeping, the interpolation of GPS to each track
report's time and the notion of an active track are shared here (Stone Soup style: interface
here, one module per method).
"""

from __future__ import annotations

import abc
import collections
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

__all__ = ["TrackPoints", "Association", "CorrelationWindow", "TrackCorrelator"]


@dataclass(frozen=True)
class TrackPoints:
    """A batch of track reports in ENU (one scan or many), as parallel arrays.

    Args:
        t: (n,) report times, mission seconds.
        track_id: (n,) the radar's track ids.
        position: (n, 3) ENU metres.
        velocity: (n, 3) ENU m/s; NaN rows where the radar gave no velocity.
        sigma_m: (n,) expected 1-sigma position error of each report (radar noise carried to ENU).
    """

    t: np.ndarray
    track_id: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    sigma_m: np.ndarray

    @classmethod
    def empty(cls) -> TrackPoints:
        return cls(np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))

    @classmethod
    def build(cls, t, track_id, position, velocity=None, sigma_m=None) -> TrackPoints:
        """Arrays from sequences; missing velocity is NaN, missing sigma is 1 m."""
        tid = np.asarray(track_id, dtype=np.int64).reshape(-1)
        n = tid.size
        tt = np.broadcast_to(np.asarray(t, float), (n,)).copy()
        pos = np.asarray(position, float).reshape(n, 3)
        vel = np.full((n, 3), np.nan) if velocity is None else np.asarray(velocity, float).reshape(n, 3)
        sig = np.ones(n) if sigma_m is None else np.broadcast_to(np.asarray(sigma_m, float), (n,)).copy()
        return cls(tt, tid, pos, vel, sig)

    def __len__(self) -> int:
        return int(self.t.size)

    @staticmethod
    def concat(parts: list[TrackPoints]) -> TrackPoints:
        if not parts:
            return TrackPoints.empty()
        return TrackPoints(*(np.concatenate([getattr(p, f) for p in parts])
                             for f in ("t", "track_id", "position", "velocity", "sigma_m")))


@dataclass(frozen=True)
class Association:
    """What a correlator decided at time ``t``.

    Args:
        associated_id: the track id taken for the ownship, or None.
        ownship_ids: every active id the correlator attributes to the ownship (the associated one
            and duplicates it recognises); the mission never cues on these.
        unassociated_ids: active tracks left for the mission (intruders, birds, clutter).
    """

    t: float
    associated_id: int | None
    ownship_ids: frozenset[int]
    unassociated_ids: tuple[int, ...]


@dataclass(frozen=True)
class CorrelationWindow:
    """The recent history a decision looks at, with GPS interpolated to every report.

    Args:
        points: reports newer than ``t - history_s``, in arrival order.
        gps_position: (n, 3) ownship GPS interpolated to each report's time.
        gps_velocity: (n, 3) ownship velocity at each report's time (NaN when unknown).
        gps_ok: (n,) whether GPS brackets the report closely enough to compare at all.
        active_ids: ids reported within ``active_s`` of ``t``, ascending.
    """

    t: float
    points: TrackPoints
    gps_position: np.ndarray
    gps_velocity: np.ndarray
    gps_ok: np.ndarray
    active_ids: np.ndarray

    def distance(self) -> np.ndarray:
        """|R_i(t) - G~_i(t)| of every report (inf where GPS is unusable)."""
        d = np.linalg.norm(self.points.position - self.gps_position, axis=1)
        return np.where(self.gps_ok, d, np.inf)


class TrackCorrelator(abc.ABC):
    """Keeps the recent radar and GPS history and decides, on request, which track is the ownship.

    Args:
        history_s: how far back reports are kept (>= the longest window a method looks at).
        active_s: a track reported within this many seconds is active.
        max_gps_gap_s: a report further than this from every GPS fix is not compared.
    """

    name: ClassVar[str]

    def __init__(self, *, history_s: float = 6.0, active_s: float = 1.0, max_gps_gap_s: float = 1.0) -> None:
        if history_s <= 0 or active_s <= 0 or max_gps_gap_s <= 0:
            raise ValueError("history_s, active_s and max_gps_gap_s must be positive")
        self.history_s = history_s
        self.active_s = active_s
        self.max_gps_gap_s = max_gps_gap_s
        self._chunks: collections.deque[TrackPoints] = collections.deque()
        self._gps: collections.deque[tuple[float, np.ndarray, np.ndarray]] = collections.deque()
        self.associated_id: int | None = None

    def reset(self) -> None:
        """Forget everything (a new flight)."""
        self._chunks.clear()
        self._gps.clear()
        self.associated_id = None

    def add_ownship(self, t: float, position_enu: np.ndarray, velocity_enu: np.ndarray | None = None) -> None:
        """One ownship GPS fix (mission time, ENU); non-finite fixes are ignored."""
        p = np.asarray(position_enu, float)
        if p.shape != (3,) or not np.all(np.isfinite(p)) or not np.isfinite(t):
            return
        v = np.full(3, np.nan) if velocity_enu is None else np.asarray(velocity_enu, float).reshape(3)
        if self._gps and t <= self._gps[-1][0]:
            return  # out of order or repeated: interpolation needs increasing times
        self._gps.append((float(t), p.copy(), v.copy()))

    def add_tracks(self, points: TrackPoints) -> None:
        """Reports of one or more scans, in ENU."""
        if len(points):
            self._chunks.append(points)

    def associate(self, t: float) -> Association:
        """Decide which active track is the ownship at time ``t``."""
        self._prune(t)
        window = self._window(t)
        self.associated_id = self._decide(window)
        return self._association(window)

    # -- for implementations ----------------------------------------------------------------

    @abc.abstractmethod
    def _decide(self, w: CorrelationWindow) -> int | None:
        """The new associated id (the stored one is :attr:`associated_id`)."""

    def _ownship_ids(self, w: CorrelationWindow) -> frozenset[int]:
        """Ids attributed to the ownship: by default the associated one if it is active."""
        a = self.associated_id
        return frozenset() if a is None or a not in set(w.active_ids.tolist()) else frozenset({a})

    # -- internals --------------------------------------------------------------------------

    def _association(self, w: CorrelationWindow) -> Association:
        own = self._ownship_ids(w)
        active = [int(i) for i in w.active_ids]
        a = self.associated_id if self.associated_id in own else None
        return Association(w.t, a, own, tuple(i for i in active if i not in own))

    def _prune(self, t: float) -> None:
        horizon = t - self.history_s
        while self._chunks and self._chunks[0].t.max() <= horizon:
            self._chunks.popleft()
        while len(self._gps) > 2 and self._gps[1][0] <= horizon - self.max_gps_gap_s:
            self._gps.popleft()

    def _window(self, t: float) -> CorrelationWindow:
        pts = TrackPoints.concat(list(self._chunks))
        keep = (pts.t > t - self.history_s) & (pts.t <= t)
        if not keep.all():
            pts = TrackPoints(pts.t[keep], pts.track_id[keep], pts.position[keep], pts.velocity[keep], pts.sigma_m[keep])
        n = len(pts)
        gpos = np.full((n, 3), np.nan)
        gvel = np.full((n, 3), np.nan)
        ok = np.zeros(n, bool)
        if self._gps and n:
            gt = np.array([g[0] for g in self._gps])
            gp = np.array([g[1] for g in self._gps])
            gv = np.array([g[2] for g in self._gps])
            for k in range(3):
                gpos[:, k] = np.interp(pts.t, gt, gp[:, k])
                gvel[:, k] = np.interp(pts.t, gt, gv[:, k])
            idx = np.clip(np.searchsorted(gt, pts.t), 1, max(gt.size - 1, 1))
            nearest = np.minimum(np.abs(pts.t - gt[idx - 1]), np.abs(pts.t - gt[np.minimum(idx, gt.size - 1)]))
            ok = nearest <= self.max_gps_gap_s
        recent = pts.t > t - self.active_s
        active = np.unique(pts.track_id[recent])
        return CorrelationWindow(t, pts, gpos, gvel, ok, active)
