"""An EchoGuard-like ground radar: tracks with ids that drop, swap and duplicate, plus clutter.

:meth:`GroundRadar.scan` is one radar frame: every object in coverage is detected with
probability ``pd`` and measured in range/azimuth/elevation with Gaussian noise; detections keep
their track id while the radar holds the track. The paper's failure modes (section 3.3) act on the
ids: a track can *drop* (the object comes back under a new id), two tracks can *swap* when their
objects pass close, and a *duplicate* track can run in parallel on one object for a while. Clutter
adds short near-stationary false tracks and slow birds. The tracker's velocity is a first-order lag
of the velocity of whatever the track follows now (so after a swap it turns over, as a real
tracker's does). Everything random comes from the Generator passed in.

The scan's truth (which object each track id follows) is returned beside the datagram for
scoring only; it never goes on the wire.

Objects may have a signature of their own (:class:`~sitl.world.radar.config.RadarSignature`: a
radar cross-section, a detection probability, a drop rate). With a cross-section, detection follows
the radar equation (:func:`detection_probability`); without one an object is detected at ``pd``
wherever it is in coverage, as before signatures existed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from chaser_bt.geo import LocalFrame
from chaser_bt.radar.geometry import RadarPose, xyz_to_rae
from chaser_bt.radar.report import RadarScan, TrackReport
from sitl.world.radar.config import RadarConfig, RadarSignature

__all__ = ["GroundRadar", "ScanTruth", "CLUTTER_LABEL", "BIRD_LABEL", "detection_probability"]

CLUTTER_LABEL = "clutter"
BIRD_LABEL = "bird"
_CONFIDENCE_CAP = {CLUTTER_LABEL: 0.3, BIRD_LABEL: 0.6}


def detection_probability(config: RadarConfig, signature: RadarSignature | None, range_m: float) -> float:
    """The chance one scan detects an object with ``signature`` at ``range_m``.

    Without a cross-section it is ``signature.pd`` (or the radar's ``pd``) wherever the object is in
    coverage. With one, the radar equation: the signal-to-noise ratio goes as ``rcs / r^4``, so
    relative to an object of ``config.reference_rcs_m2`` at ``config.max_range_m`` it is

        ratio = (rcs / reference_rcs) * (max_range / r)^4

    and a Swerling I (fluctuating) target crosses a threshold set for false-alarm probability
    ``pfa`` with ``Pd = pfa^(1 / (1 + SNR))``. The reference SNR is the one at which that gives
    ``pd`` (``1 + SNR0 = ln pfa / ln pd``), so

        Pd(r, rcs) = min(pd, pfa^(1 / (1 + SNR0 * ratio)))

    ``pd`` caps it (the tracker's own limit): an object at least as strong as the reference is seen
    at exactly ``pd``, a weaker or farther one less often, falling to ``pfa`` as the ratio goes to 0.
    """
    pd = config.pd if signature is None or signature.pd is None else signature.pd
    if signature is None or signature.rcs_m2 is None:
        return pd
    ratio = signature.rcs_m2 / config.reference_rcs_m2 * (config.max_range_m / max(range_m, 1e-3)) ** 4
    if ratio >= 1.0 or pd <= config.pfa or pd >= 1.0:
        return pd  # as strong as the reference; or no signal to scale (pd at the false-alarm floor, or certain)
    snr0 = math.log(config.pfa) / math.log(pd) - 1.0
    return config.pfa ** (1.0 / (1.0 + snr0 * ratio))


@dataclass
class _Track:
    track_id: int
    obj: str
    born_s: float
    last_detect_s: float
    velocity: np.ndarray  # radar frame, the tracker's estimate
    duplicate: bool = False
    expires_s: float = math.inf
    offset: np.ndarray | None = None  # a duplicate's constant offset (radar frame)


@dataclass
class _Wanderer:
    """A clutter object: position and velocity in ENU, and when it goes away."""

    kind: str
    pos: np.ndarray
    vel: np.ndarray
    expires_s: float


@dataclass(frozen=True)
class ScanTruth:
    """For scoring: which object each reported track id followed at this scan."""

    t: float
    labels: Mapping[int, str]


class GroundRadar:
    """Scans the objects it is shown and reports tracks in its own frame.

    Args:
        config: the radar.
        frame: the scenario's ENU frame (objects are given in it).
        rng: all randomness.
        signatures: object name -> its signature (RCS, pd, drop rate); objects not named here have
            the radar's ``pd`` and ``failures.drop_per_s``.
    """

    def __init__(self, config: RadarConfig, frame: LocalFrame, rng: np.random.Generator,
                 signatures: Mapping[str, RadarSignature] | None = None) -> None:
        self.config = config
        self.signatures = dict(signatures or {})
        self.pose = RadarPose.from_geodetic(frame, config.position, config.yaw_rad, config.pitch_rad, config.roll_rad)
        self.rng = rng
        self.dt = 1.0 / config.rate_hz
        self.seq = 0
        self._tracks: dict[int, _Track] = {}
        self._primary: dict[str, int] = {}  # object -> its (non-duplicate) track id
        self._reacquire_s: dict[str, float] = {}
        self._close: set[frozenset[str]] = set()
        self._clutter: dict[str, _Wanderer] = {}
        self._clutter_count = 0
        self._next_id = int(rng.integers(100, 1000))

    def is_on(self, t: float) -> bool:
        off = self.config.off_at_s
        return off is None or t < off

    def in_coverage(self, pos_enu: np.ndarray) -> bool:
        """Whether an ENU point is inside the field of view and range."""
        r, az, el = xyz_to_rae(self.pose.from_enu(pos_enu))
        c = self.config
        return bool(c.min_range_m <= r <= c.max_range_m and abs(az) <= c.fov_az_rad / 2
                    and abs(el) <= c.fov_el_rad / 2)

    def scan(self, t: float, objects: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> tuple[RadarScan, ScanTruth] | None:
        """One radar frame at time ``t`` over ``objects`` (name -> (ENU position, ENU velocity)).

        Returns the scan and its truth, or None once the radar is off.
        """
        if not self.is_on(t):
            return None
        c, f, rng = self.config, self.config.failures, self.rng
        self._update_clutter(t)
        everything: dict[str, tuple[np.ndarray, np.ndarray]] = dict(objects)
        everything.update({k: (w.pos, w.vel) for k, w in self._clutter.items()})
        local = {k: (self.pose.from_enu(p), self.pose.rotation.inv().apply(v)) for k, (p, v) in everything.items()}
        seen = {k for k, (p, v) in everything.items() if self.in_coverage(p)}

        # Drops: the track ends, the object is untracked for a moment, then gets a new id.
        for obj, tid in list(self._primary.items()):
            if obj in objects and rng.random() < self._drop_per_s(obj) * self.dt:
                self._end(tid)
                self._reacquire_s[obj] = t + f.drop_gap_s
        self._swaps(objects)

        reports: list[TrackReport] = []
        labels: dict[int, str] = {}
        for obj in sorted(seen):
            detected = rng.random() < self._pd(obj, local)
            tid = self._primary.get(obj)
            if tid is None:
                if not detected or t < self._reacquire_s.get(obj, -math.inf):
                    continue
                tid = self._new_track(obj, t, local[obj][1]).track_id
            if detected:
                reports.append(self._report(self._tracks[tid], t, local))
                labels[tid] = obj
            if obj in objects and rng.random() < f.duplicate_per_s * self.dt:
                dup = self._new_track(obj, t, local[obj][1], duplicate=True)
                dup.expires_s = t + f.duplicate_duration_s
                dup.offset = rng.normal(0.0, f.duplicate_offset_m, 3)
        for tr in list(self._tracks.values()):
            if not tr.duplicate:
                continue
            if t >= tr.expires_s or tr.obj not in seen:
                self._end(tr.track_id)
            elif rng.random() < self._pd(tr.obj, local):
                reports.append(self._report(tr, t, local))
                labels[tr.track_id] = tr.obj
        for tr in list(self._tracks.values()):  # coast limit
            if t - tr.last_detect_s > c.coast_s:
                self._end(tr.track_id)
        for tr in self._tracks.values():  # the tracker's velocity follows whatever it follows now
            if tr.obj in local:
                a = min(1.0, self.dt / c.vel_tau_s)
                tr.velocity = tr.velocity + a * (local[tr.obj][1] - tr.velocity)
        self.seq += 1
        return RadarScan(t, self.seq, tuple(reports), c.radar_id), ScanTruth(t, labels)

    # -- internals --------------------------------------------------------------------------

    def _pd(self, obj: str, local: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> float:
        """The detection probability of ``obj`` now (:func:`detection_probability`)."""
        sig = self.signatures.get(obj)
        if sig is None:
            return self.config.pd
        return detection_probability(self.config, sig, float(np.linalg.norm(local[obj][0])))

    def _drop_per_s(self, obj: str) -> float:
        sig = self.signatures.get(obj)
        if sig is None or sig.drop_per_s is None:
            return self.config.failures.drop_per_s
        return sig.drop_per_s

    def _new_track(self, obj: str, t: float, vel_local: np.ndarray, duplicate: bool = False) -> _Track:
        tid = self._next_id
        self._next_id += int(self.rng.integers(1, 40))
        v0 = np.asarray(vel_local, float) + self.rng.normal(0.0, self.config.sigma_vel_mps, 3)
        tr = _Track(tid, obj, t, t, v0, duplicate=duplicate)
        self._tracks[tid] = tr
        if not duplicate:
            self._primary[obj] = tid
        return tr

    def _end(self, tid: int) -> None:
        tr = self._tracks.pop(tid, None)
        if tr is not None and not tr.duplicate and self._primary.get(tr.obj) == tid:
            del self._primary[tr.obj]

    def _report(self, tr: _Track, t: float, local: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> TrackReport:
        c, rng = self.config, self.rng
        xyz = local[tr.obj][0] + (tr.offset if tr.offset is not None else 0.0)
        r, az, el = xyz_to_rae(xyz)
        r = max(0.0, float(r) + rng.normal(0.0, c.sigma_range_m))
        az = float(np.clip(az + rng.normal(0.0, c.sigma_az_rad), -math.pi, math.pi))
        el = float(np.clip(el + rng.normal(0.0, c.sigma_el_rad), -math.pi / 2, math.pi / 2))
        tr.last_detect_s = t
        vel = tr.velocity + rng.normal(0.0, c.sigma_vel_mps, 3)
        kind = tr.obj.split("-")[0]
        cap = _CONFIDENCE_CAP.get(kind, 0.99)
        conf = cap * (1.0 - math.exp(-(t - tr.born_s + self.dt) / c.confidence_tau_s))
        return TrackReport(tr.track_id, r, az, el, vel, conf)

    def _swaps(self, objects: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> None:
        f = self.config.failures
        tracked = sorted(o for o in self._primary if o in objects)
        for i, a in enumerate(tracked):
            for b in tracked[i + 1:]:
                pair = frozenset((a, b))
                close = float(np.linalg.norm(objects[a][0] - objects[b][0])) < f.swap_distance_m
                if close and pair not in self._close:
                    self._close.add(pair)
                    if self.rng.random() < f.swap_prob:
                        ta, tb = self._primary[a], self._primary[b]
                        self._tracks[ta].obj, self._tracks[tb].obj = b, a
                        self._primary[a], self._primary[b] = tb, ta
                elif not close:
                    self._close.discard(pair)

    def _update_clutter(self, t: float) -> None:
        cl, c, rng = self.config.clutter, self.config, self.rng
        for k in [k for k, w in self._clutter.items() if t >= w.expires_s]:
            del self._clutter[k]
        for w in self._clutter.values():
            w.pos = w.pos + w.vel * self.dt
        for kind, rate, life in ((CLUTTER_LABEL, cl.false_tracks_per_s, cl.false_track_life_s),
                                 (BIRD_LABEL, cl.birds_per_s, cl.bird_life_s)):
            for _ in range(int(rng.poisson(rate * self.dt))):
                r = rng.uniform(max(c.min_range_m, 30.0), min(c.max_range_m, 600.0))
                az = rng.uniform(-c.fov_az_rad / 2, c.fov_az_rad / 2) * 0.9
                el = rng.uniform(-c.fov_el_rad / 2, c.fov_el_rad / 2) * 0.5
                pos = self.pose.rae_to_enu(r, az, el)
                if kind == BIRD_LABEL:
                    heading = rng.uniform(0, 2 * math.pi)
                    vel = cl.bird_speed_mps * np.array([math.cos(heading), math.sin(heading), rng.normal(0, 0.1)])
                else:
                    vel = rng.normal(0.0, 0.3, 3)
                self._clutter_count += 1
                self._clutter[f"{kind}-{self._clutter_count}"] = _Wanderer(kind, pos, vel, t + rng.exponential(life))
