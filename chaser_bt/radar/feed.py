"""The radar as the mission sees it: datagrams in, an ENU track picture with the ownship filtered out.

:class:`RadarFeed` ties the pieces together once per mission tick: it reads what arrived from a
:class:`~chaser_bt.radar.stream.DatagramSource` (bad datagrams dropped and counted), turns every
report into the mission's ENU frame with the radar's calibrated :class:`RadarPose`, gives the
ownship's GPS and the reports to a track correlator (section 3.3) and returns a
:class:`RadarPicture`: the active tracks, which of them are our own drone, and the rest, the
candidates for the intruder cue. Radar time plus ``time_offset_s`` is mission time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from chaser_bt.cue import TargetCue
from chaser_bt.radar.correlator import Association, TrackCorrelator, TrackPoints, make_correlator
from chaser_bt.radar.geometry import RadarPose
from chaser_bt.radar.report import RadarScan
from chaser_bt.radar.stream import DatagramSource, DropCounts, RadarStreamReader

__all__ = ["RadarNoise", "RadarTrack", "RadarPicture", "RadarFeed", "scan_to_points"]


@dataclass(frozen=True)
class RadarNoise:
    """The radar's 1-sigma measurement noise (its data sheet), for gates and cue covariances."""

    sigma_range_m: float = 0.5
    sigma_az_rad: float = math.radians(0.4)
    sigma_el_rad: float = math.radians(1.0)

    def sigma_m(self, range_m: np.ndarray) -> np.ndarray:
        """Expected 1-sigma position error at ``range_m`` (all three axes together)."""
        r = np.asarray(range_m, float)
        return np.sqrt(self.sigma_range_m**2 + (r * self.sigma_az_rad) ** 2 + (r * self.sigma_el_rad) ** 2)


def scan_to_points(scan: RadarScan, pose: RadarPose, noise: RadarNoise, time_offset_s: float = 0.0) -> TrackPoints:
    """A scan's reports in ENU, as correlator input."""
    n = len(scan.tracks)
    if n == 0:
        return TrackPoints.empty()
    rae = np.array([(r.range_m, r.az_rad, r.el_rad) for r in scan.tracks])
    vel = np.array([r.velocity if r.velocity is not None else (np.nan,) * 3 for r in scan.tracks], float)
    return TrackPoints(
        np.full(n, scan.t + time_offset_s),
        np.array([r.track_id for r in scan.tracks], np.int64),
        pose.rae_to_enu(rae[:, 0], rae[:, 1], rae[:, 2]),
        pose.vector_to_enu(vel),
        noise.sigma_m(rae[:, 0]),
    )


@dataclass(frozen=True)
class RadarTrack:
    """The latest report of one track, in the mission's ENU frame."""

    track_id: int
    t: float
    position_enu: np.ndarray
    velocity_enu: np.ndarray | None
    covariance_enu: np.ndarray
    confidence: float
    first_seen_t: float

    def to_cue(self) -> TargetCue:
        return TargetCue(self.t, self.position_enu, self.covariance_enu, self.velocity_enu, "radar", self.track_id)


@dataclass(frozen=True)
class OwnshipFix:
    """The ownship's own telemetry: ENU position and velocity at mission time ``t``."""

    t: float
    position_enu: np.ndarray
    velocity_enu: np.ndarray | None = None

    def at(self, t: float) -> np.ndarray:
        """Where it is at ``t``, on its velocity (the fix and a radar report are a scan apart)."""
        if self.velocity_enu is None or not np.all(np.isfinite(self.velocity_enu)):
            return self.position_enu
        return self.position_enu + self.velocity_enu * (t - self.t)


@dataclass(frozen=True)
class RadarPicture:
    """Active tracks at mission time ``t`` and what the correlator made of them."""

    t: float
    tracks: dict[int, RadarTrack]
    association: Association | None
    last_scan_t: float | None
    counts: DropCounts = field(default_factory=DropCounts)
    ownship: OwnshipFix | None = None  # our own telemetry at the picture's update

    @property
    def ownship_ids(self) -> frozenset[int]:
        return self.association.ownship_ids if self.association is not None else frozenset()

    @property
    def intruders(self) -> list[RadarTrack]:
        """Tracks that are not the ownship, most confident first."""
        own = self.ownship_ids
        return sorted((tr for i, tr in self.tracks.items() if i not in own),
                      key=lambda tr: (-tr.confidence, tr.first_seen_t, tr.track_id))


class RadarFeed:
    """Reads a radar stream and keeps the mission's picture of it.

    Args:
        source: where datagrams arrive.
        pose: the radar's calibrated pose in the mission frame.
        noise: the radar's measurement noise.
        correlator: a :class:`TrackCorrelator` or its name (``"gated"``, ``"alg1"``).
        time_offset_s: mission time = radar time + offset.
        track_timeout_s: a track not reported for this long leaves the picture.
        reader: checks the datagrams (its envelope, its verifier); default: unsigned, default envelope.
    """

    def __init__(self, source: DatagramSource, pose: RadarPose, *, noise: RadarNoise | None = None,
                 correlator: TrackCorrelator | str = "gated", time_offset_s: float = 0.0,
                 track_timeout_s: float = 1.0, reader: RadarStreamReader | None = None) -> None:
        self.source = source
        self.pose = pose
        self.noise = noise or RadarNoise()
        self.correlator = make_correlator(correlator) if isinstance(correlator, str) else correlator
        self.time_offset_s = time_offset_s
        self.track_timeout_s = track_timeout_s
        self.reader = reader or RadarStreamReader()
        self._tracks: dict[int, RadarTrack] = {}
        self._last_scan_t: float | None = None
        self._picture: RadarPicture | None = None

    def update(self, t: float, ownship_position_enu: np.ndarray | None = None,
               ownship_velocity_enu: np.ndarray | None = None, ownship_t: float | None = None) -> RadarPicture:
        """Take in the ownship fix and every datagram that arrived; the picture at mission time ``t``.

        Calling again at the same ``t`` returns the same picture (two behaviours, one tick).
        """
        if self._picture is not None and self._picture.t == t:
            return self._picture
        fix = None
        if ownship_position_enu is not None:
            fix = OwnshipFix(t if ownship_t is None else ownship_t, np.asarray(ownship_position_enu, float),
                             None if ownship_velocity_enu is None else np.asarray(ownship_velocity_enu, float))
            self.correlator.add_ownship(fix.t, ownship_position_enu, ownship_velocity_enu)
        for scan in self.reader.accept_all(self.source.receive()):
            self._take(scan)
        self._tracks = {i: tr for i, tr in self._tracks.items() if t - tr.t <= self.track_timeout_s}
        assoc = self.correlator.associate(t) if self._last_scan_t is not None else None
        self._picture = RadarPicture(t, dict(self._tracks), assoc, self._last_scan_t, self.reader.counts, fix)
        return self._picture

    def _take(self, scan: RadarScan) -> None:
        pts = scan_to_points(scan, self.pose, self.noise, self.time_offset_s)
        self.correlator.add_tracks(pts)
        t = scan.t + self.time_offset_s
        self._last_scan_t = t
        n = self.noise
        for k, r in enumerate(scan.tracks):
            prev = self._tracks.get(r.track_id)
            cov = self.pose.covariance_enu(r.range_m, r.az_rad, r.el_rad, n.sigma_range_m, n.sigma_az_rad, n.sigma_el_rad)
            vel = None if r.velocity is None else pts.velocity[k]
            self._tracks[r.track_id] = RadarTrack(r.track_id, t, pts.position[k], vel, cov, r.confidence,
                                                  prev.first_seen_t if prev else t)

