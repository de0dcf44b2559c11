"""Custody of one designated intruder: the chase keeps the target it chose across radar drop-outs,
new track ids and id swaps, and never drifts to another object on its own.

A radar reports *tracks*, not objects: the target's track drops and returns under a new id, the
radar swaps two ids in a close pass, and a bird or a second drone has a track of its own. The
mission wants one *target*. :class:`Custody` is what the tree knows of it (blackboard
``/target/custody``): the target's id (the track id it was designated under), the track carrying it
now, when the radar last confirmed it and where it was going. :func:`track_custody` carries a
custody over one radar picture (pure: the custody holds all the state), by these rules:

* the carrying track keeps custody while its reports stay inside the target's gate (the position
  predicted on the target's velocity, widened by a manoeuvre allowance, a tighter one in height,
  and that velocity); two reports in a row outside it release the id (a swap, or a track that
  jumped to something else);
* an id swap with a track beside the target is seen in the scan it happens: their offset from each
  other reverses, and the other id takes the target over at once (judged on position only for
  ``vel_lag_s``, while the tracker turns its velocity over to the target's). The swap would show in the
  carrier's velocity only as the radar's tracker turns it over, so when the reversal is not seen, a
  release takes custody back to its confirmation ``swap_lookback_s`` before the first miss (and
  the tracks beside the target then), not to a report that may have been the other object's.
  Without both, a bird keeping beside the target, whose id the radar swaps with the target's every
  few seconds, leaves custody on the bird's path;
* when no track carries the target it *coasts* on its last velocity; a track takes it over only
  if its report falls inside the gate on position **and** velocity (not on confidence) and it is
  not an object seen apart from the target while the target was tracked: another drone, a bird or
  clutter seen beside the target is never the target, so a drop-out never hands custody to it
  (the one exception, an id swap in a close pass, is the next rule's). While the camera follows the
  target (a :class:`Sight`: its line of sight, fresh), a track must also lie on that line within
  ``sight_sigma`` of its own radar error: in a close crossing the gate holds both drones and the
  radar's new id may be either, but the camera has kept its eye on one. The one track in the gate
  on that line takes the target over even from a crowd the radar cannot part;
* after a release in a crowd (another object's track within ``crowd_m`` of the target's at its last
  report: a close pass, where the radar cannot part the two; a duplicate of the target's own track,
  beside it at its velocity, is not another object), a track takes the target over only if it fits
  the target's prediction better, by ``crowd_margin`` in gate units, than the prediction of each
  object that was beside it: a new id born in the pass may be either, so the chase waits for their
  paths to part instead of guessing. The same test lets the other object's own id take the target
  over within ``crowd_window_s`` (the radar swapped the two ids): it must fit the target better
  than its own past;
* a track where our own telemetry puts the chaser, moving as it moves, is the chaser (a duplicate,
  or an id the correlator has not claimed yet), never the target: it neither takes the target
  over nor confirms it (the camera's line of sight starts at the chaser, so the sight alone would
  not refuse it);
* after ``max_coast_s`` without a confirmation the target is *lost* and the mission searches; only a
  confident track within ``max_gate_m`` of where the target was last takes it back: the one on the
  camera's line of sight, else one that appeared after the loss (or the operator designates again,
  :func:`designate`).

Changing the designated target is only ever :func:`designate`, and every change of the carrying
track is a :class:`CustodyEvent` with a reason, for the log and the flight record.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from chaser_bt.cue import TargetCue, TargetEstimate, sight_offset_sigma
from chaser_bt.radar.feed import OwnshipFix, RadarPicture, RadarTrack

__all__ = ["CustodyParams", "CustodyEvent", "Custody", "Sight", "designate", "is_ownship", "track_custody"]


@dataclass(frozen=True)
class CustodyParams:
    """How custody gates and coasts.

    Args:
        gate_sigma: the position gate in multiples of the predicted error.
        floor_m: smallest position gate (calibration and GPS error, m).
        accel_mps2: the manoeuvre allowance: how hard the target may accelerate while unseen (m/s^2;
            a Phantom 4 in sport mode reaches 8).
        max_speed_mps: nor faster than this (a Phantom 4 in sport mode: 20 m/s).
        accel_v_mps2, max_vertical_mps: the same for climbs and dives, which a multirotor flies far
            slower than it flies across (a Phantom 4 climbs at 6 m/s): a track far above or below
            the prediction is not the target even when the position gate, grown over a long coast,
            would reach it (a bird or clutter 100 m up).
        vel_gate_mps: smallest velocity gate for a new track taking the target over (m/s).
        carrier_vel_gate_mps: smallest velocity gate for the carrying track's next report (m/s): the
            radar's tracker changes a track's velocity smoothly, so a jump means another object (a swap).
        vel_lag_s: the radar tracker's velocity lags a manoeuvre by about this long (s): the velocity
            gate allows ``accel_mps2`` over it too.
        swap_lookback_s: a swap shows in the carrying track's velocity up to this long after it
            happened (the tracker's lag, and the gate's allowance for a manoeuvre over it): a release
            takes custody back to its confirmation from this long before the first miss (s).
        max_gate_m: the position gate never grows past this (m).
        apart_m: a track seen this far from the target's, while both were reported, is another object.
        duplicate_m: a track this close to the target's, at its velocity (``carrier_vel_gate_mps``), is a
            duplicate of it, not another object (m).
        misses_to_release: reports in a row outside the gate that release the carrying id.
        max_coast_s: unconfirmed this long, the target is lost (s).
        reacquire_confidence: a lost target is taken back only by a new track at least this confident.
        confidence_tau_s: custody confidence falls as exp(-unconfirmed / tau).
        sight_sigma: with a fresh :class:`Sight`, a track taking the target over lies on the camera's
            line of sight within this many sigma of its report's error (plus ``sight_floor_m``).
        sight_floor_m: added to a report's error on every axis against the line of sight (the
            camera's mounting and timing, the target's size; m).
        sight_max_age_s: a sight older than this, against the report's time, is not used (s).
        crowd_m: a track this close to the target's at its last report makes a release a crowded one (m).
        crowd_window_s: how long after the last confirmation an id that was beside the target may
            take it over, fitting it better than its own past (s).
        crowd_margin: in a crowd, how much better (position miss over its gate plus velocity miss
            over its gate) a track must fit the target than any object that was beside it.
        self_sigma: a report within this many sigma of its error (plus ``self_floor_m``) of the
            chaser's own telemetry position, and ``self_vel_mps`` of its velocity, is the chaser.
        self_floor_m: added to a report's error on every axis against our own position (GPS, timing; m).
        self_vel_mps: the velocity half of that test (m/s).
    """

    gate_sigma: float = 3.5
    floor_m: float = 8.0
    accel_mps2: float = 8.0
    max_speed_mps: float = 20.0
    accel_v_mps2: float = 4.0
    max_vertical_mps: float = 6.0
    vel_gate_mps: float = 6.0
    carrier_vel_gate_mps: float = 2.0
    vel_lag_s: float = 1.0
    swap_lookback_s: float = 2.0
    max_gate_m: float = 200.0
    apart_m: float = 20.0
    duplicate_m: float = 15.0
    misses_to_release: int = 2
    max_coast_s: float = 15.0
    reacquire_confidence: float = 0.8
    confidence_tau_s: float = 4.0
    sight_sigma: float = 3.5
    sight_floor_m: float = 2.0
    sight_max_age_s: float = 0.5
    crowd_m: float = 30.0
    crowd_margin: float = 0.2
    crowd_window_s: float = 3.0
    self_sigma: float = 3.0
    self_floor_m: float = 2.0
    self_vel_mps: float = 3.0

    def __post_init__(self) -> None:
        for name in ("gate_sigma", "floor_m", "vel_gate_mps", "max_gate_m", "apart_m", "max_coast_s", "confidence_tau_s",
                     "max_speed_mps", "accel_v_mps2", "max_vertical_mps"):
            if not getattr(self, name) > 0:
                raise ValueError(f"CustodyParams.{name} must be positive")
        if self.accel_mps2 < 0 or self.vel_lag_s < 0 or self.swap_lookback_s < 0 or self.misses_to_release < 1:
            raise ValueError("CustodyParams: accel_mps2, vel_lag_s and swap_lookback_s >= 0 and misses_to_release >= 1 "
                             "are required")


@dataclass(frozen=True)
class CustodyEvent:
    """A change in custody: ``kind`` is designated, handover, released, lost, reacquired or switched."""

    t: float
    kind: str
    target_id: int
    track_id: int | None
    reason: str

    def __str__(self) -> str:
        track = "no track" if self.track_id is None else f"track {self.track_id}"
        return f"target {self.target_id} {self.kind} ({track}): {self.reason}"


@dataclass(frozen=True)
class Custody:
    """The designated target as the mission knows it.

    Args:
        target_id: the target's name: the track id it was designated under.
        track_id: the radar track carrying it now; None while it coasts or is lost.
        t_confirmed: mission time of the last radar report of it.
        position_enu, velocity_enu, covariance_enu: that report (velocity zero if never measured).
        designated_by: who chose it ("operator", "radar confidence 0.93", ...).
        t_designated: when.
        track_ids: every id that has carried it, in order.
        apart_ids: ids of tracks seen apart from it (other objects), never handed custody.
        refused_ids: ids whose first report after the target's last confirmation missed its gate: a
            new track is judged where it appears, so a wider gate later does not let it in.
        misses: reports in a row of the carrying track outside the gate.
        t_missed: the time of the last of them (the tree ticks faster than the radar reports, so a
            picture may hold a report already judged: each report is one miss, however often seen).
        lost: unconfirmed past ``max_coast_s``; only a new designation ends it.
    """

    target_id: int
    track_id: int | None
    t_confirmed: float
    position_enu: np.ndarray
    velocity_enu: np.ndarray
    covariance_enu: np.ndarray
    designated_by: str
    t_designated: float
    track_ids: tuple[int, ...] = ()
    apart_ids: frozenset[int] = frozenset()
    refused_ids: frozenset[int] = frozenset()
    misses: int = 0
    t_missed: float = -math.inf
    lost: bool = False
    beside: tuple[RadarTrack, ...] = field(default=(), repr=False)  # reports within crowd_m of it at the last one
    noted_t: float = field(default=-math.inf, repr=False)  # the report of it the other tracks were last judged against
    recent: tuple[_Confirmation, ...] = field(default=(), repr=False)  # its last confirmations, oldest first
    t_swapped: float = field(default=-math.inf, repr=False)  # when an id swap last handed it to its carrier
    t_velocity: float = field(default=-math.inf, repr=False)  # when its velocity was last measured (not kept)

    def since_confirmed(self, t: float) -> float:
        return max(0.0, t - self.t_confirmed)

    def confidence(self, t: float, tau_s: float = CustodyParams.confidence_tau_s) -> float:
        """1 at a confirmation, falling while the radar does not confirm it; 0 once lost."""
        return 0.0 if self.lost else math.exp(-self.since_confirmed(t) / tau_s)

    def predicted(self, t: float) -> np.ndarray:
        """Where the target should be at ``t``, on its last velocity."""
        return self.position_enu + self.velocity_enu * self.since_confirmed(t)

    def cue(self) -> TargetCue:
        """The last confirmation as a radar cue."""
        return TargetCue(self.t_confirmed, self.position_enu, self.covariance_enu, self.velocity_enu, "radar",
                         self.target_id)


@dataclass(frozen=True)
class _Confirmation:
    """One confirmation of the target and the tracks beside it then: what a release goes back to."""

    t: float
    position_enu: np.ndarray
    velocity_enu: np.ndarray
    covariance_enu: np.ndarray
    beside: tuple[RadarTrack, ...]

    @classmethod
    def of(cls, c: Custody) -> _Confirmation:
        return cls(c.t_confirmed, c.position_enu, c.velocity_enu, c.covariance_enu, c.beside)

    def restore(self, c: Custody) -> Custody:
        return replace(c, t_confirmed=self.t, position_enu=self.position_enu, velocity_enu=self.velocity_enu,
                       covariance_enu=self.covariance_enu, beside=self.beside, noted_t=self.t, recent=(),
                       t_velocity=min(c.t_velocity, self.t))


@dataclass(frozen=True)
class Sight:
    """The camera's line of sight to the target it follows at mission time ``t``: from ``camera_enu``
    along the unit ``bearing_enu`` (the range, which the camera measures badly, is left out)."""

    t: float
    camera_enu: np.ndarray
    bearing_enu: np.ndarray

    @classmethod
    def of(cls, estimate: TargetEstimate) -> Sight | None:
        """The sight a camera estimate gives, None without a usable range to place its camera."""
        if not math.isfinite(estimate.range_m):
            return None
        return cls(estimate.t, estimate.position_enu - estimate.range_m * estimate.bearing_enu, estimate.bearing_enu)

    def offset_sigma(self, report: RadarTrack, floor_m: float) -> float:
        """How far ``report`` lies from the line of sight, in its error widened by ``floor_m``."""
        return sight_offset_sigma(self.camera_enu, self.bearing_enu, report.position_enu,
                                  report.covariance_enu + floor_m**2 * np.eye(3))


def designate(track: RadarTrack, t: float, by: str, previous: Custody | None = None) -> tuple[Custody, CustodyEvent | None]:
    """Custody of the object ``track`` reports, chosen ``by`` someone; the event is None when ``track``
    already carries the designated target (a re-validation changes nothing)."""
    if previous is not None and not previous.lost and previous.track_id == track.track_id:
        return previous, None
    vel = track.velocity_enu if track.velocity_enu is not None else np.zeros(3)
    custody = Custody(track.track_id, track.track_id, track.t, track.position_enu, np.asarray(vel, float),
                      track.covariance_enu, by, t, (track.track_id,))
    kind = "designated" if previous is None else "switched"
    reason = by if previous is None else f"{by}, was target {previous.target_id}"
    return custody, CustodyEvent(t, kind, custody.target_id, track.track_id, reason)


def is_ownship(report: RadarTrack, own: OwnshipFix | None, p: CustodyParams) -> bool:
    """Whether ``report`` is where our own telemetry puts the chaser at the report's time, moving as it
    moves (the velocity half is skipped when either velocity is unknown)."""
    if own is None:
        return False
    d = report.position_enu - own.at(report.t)
    cov = report.covariance_enu + p.self_floor_m**2 * np.eye(3)
    if float(d @ np.linalg.solve(cov, d)) > p.self_sigma**2:
        return False
    if report.velocity_enu is None or own.velocity_enu is None:
        return True
    return float(np.linalg.norm(report.velocity_enu - own.velocity_enu)) <= p.self_vel_mps


def _reach_m(dt: float, v0: float, accel: float, v_max: float) -> float:
    """How far from its straight-line prediction an object moving at ``v0`` can be after ``dt``:
    accelerating at ``accel`` away from its velocity, never faster than ``v_max``."""
    dv_max = v_max + v0  # turning about at full speed
    t_sat = dv_max / accel if accel > 0 else math.inf
    if dt <= t_sat:
        return 0.5 * accel * dt * dt
    return 0.5 * accel * t_sat * t_sat + dv_max * (dt - t_sat)


def _position_gate(c: Custody, report: RadarTrack, p: CustodyParams) -> float:
    """The radius around the prediction a report of the target may fall in: ``gate_sigma`` of the
    two reports' radar error, plus how far the target can have manoeuvred since."""
    dt = max(0.0, report.t - c.t_confirmed)
    sigma = math.sqrt(float(np.trace(report.covariance_enu)) + float(np.trace(c.covariance_enu)))
    reach = _reach_m(dt, float(np.linalg.norm(c.velocity_enu)), p.accel_mps2, p.max_speed_mps)
    return min(p.max_gate_m, max(p.floor_m, p.gate_sigma * sigma) + reach)


def _vertical_gate(c: Custody, report: RadarTrack, p: CustodyParams) -> float:
    """How far above or below the prediction a report of the target may be: ``gate_sigma`` of the two
    reports' vertical error, plus how far the target can have climbed or dived since."""
    dt = max(0.0, report.t - c.t_confirmed)
    sigma = math.sqrt(float(report.covariance_enu[2, 2]) + float(c.covariance_enu[2, 2]))
    reach = _reach_m(dt, abs(float(c.velocity_enu[2])), p.accel_v_mps2, p.max_vertical_mps)
    return min(p.max_gate_m, max(p.floor_m, p.gate_sigma * sigma) + reach)


@dataclass(frozen=True)
class _Fit:
    """How a report sits against the target's gate: position miss and gate, height miss and gate,
    velocity miss and gate."""

    miss_m: float
    gate_m: float
    dv_mps: float
    vgate_mps: float
    dz_m: float = 0.0
    zgate_m: float = math.inf

    @property
    def inside(self) -> bool:
        return self.miss_m <= self.gate_m and self.dz_m <= self.zgate_m and self.dv_mps <= self.vgate_mps

    @property
    def cost(self) -> float:
        return self.miss_m / self.gate_m + (self.dv_mps / self.vgate_mps if self.vgate_mps > 0 else 0.0)

    def __str__(self) -> str:
        height = f" ({self.dz_m:.0f} m of {self.zgate_m:.0f} in height)" if self.dz_m > self.zgate_m else ""
        return f"{self.miss_m:.0f} m of a {self.gate_m:.0f} m gate{height}, {self.dv_mps:.1f} of {self.vgate_mps:.1f} m/s"


def _fit(c: Custody, report: RadarTrack, p: CustodyParams, carrier: bool = False, position_only: bool = False) -> _Fit:
    """The report against the target's prediction (``carrier``: the next report of the track that
    carries the target, whose velocity the radar's tracker only changes smoothly; ``position_only``:
    its velocity is not the target's yet, so it is not judged)."""
    dt = max(0.0, report.t - c.t_confirmed)
    off = report.position_enu - c.predicted(report.t)
    miss = float(np.linalg.norm(off))
    dv, vgate = 0.0, math.inf
    if report.velocity_enu is not None and not position_only:
        dv = float(np.linalg.norm(report.velocity_enu - c.velocity_enu))
        reach = p.max_speed_mps + float(np.linalg.norm(c.velocity_enu))
        since_measured = dt if not math.isfinite(c.t_velocity) else max(dt, report.t - c.t_velocity)
        vgate = (p.carrier_vel_gate_mps + p.accel_mps2 * since_measured if carrier
                 else p.vel_gate_mps + min(reach, p.accel_mps2 * (dt + p.vel_lag_s)))
    return _Fit(miss, _position_gate(c, report, p), dv, vgate, abs(float(off[2])), _vertical_gate(c, report, p))


def _settling(c: Custody, report: RadarTrack, p: CustodyParams) -> bool:
    """Whether ``report`` comes within ``vel_lag_s`` of an id swap that handed the target to its track:
    the radar's tracker is still turning that track's velocity over from the other object's."""
    return report.t - c.t_swapped <= p.vel_lag_s


def _confirm(c: Custody, report: RadarTrack, keep_velocity: bool = False) -> Custody:
    """The target confirmed by ``report``; its velocity is the report's (the radar's tracker filters it)
    unless ``keep_velocity``."""
    kept = report.velocity_enu is None or keep_velocity
    vel = c.velocity_enu if kept else report.velocity_enu
    ids = c.track_ids if report.track_id in c.track_ids[-1:] else c.track_ids + (report.track_id,)
    return replace(c, track_id=report.track_id, t_confirmed=report.t, position_enu=report.position_enu,
                   velocity_enu=np.asarray(vel, float), covariance_enu=report.covariance_enu, track_ids=ids, misses=0,
                   lost=False, t_velocity=c.t_velocity if kept else report.t)


def track_custody(c: Custody, picture: RadarPicture, params: CustodyParams | None = None,
                  sight: Sight | None = None) -> tuple[Custody, list[CustodyEvent]]:
    """Carry custody over one radar picture; the new custody and what changed. ``sight``: where the
    camera sees the target, when it does (a track taking the target over must lie on it)."""
    p = params or CustodyParams()
    t = picture.t
    events: list[CustodyEvent] = []
    candidates = {tr.track_id: tr for tr in picture.intruders if not is_ownship(tr, picture.ownship, p)}
    if c.lost:
        return _reacquire(c, candidates, p, events, sight), events
    carrier = candidates.get(c.track_id) if c.track_id is not None else None
    if carrier is None and c.track_id is not None and c.track_id in picture.tracks and c.track_id not in picture.ownship_ids:
        carrier = picture.tracks[c.track_id]  # on the chaser itself now: a miss, as a report outside the gate
    partner = _swap_partner(c, carrier, candidates, p) if carrier is not None and carrier.t > c.t_confirmed else None
    if partner is not None:
        events.append(CustodyEvent(partner.t, "handover", c.target_id, partner.track_id,
                                   f"id swap with track {c.track_id}: their offset from each other reversed"))
        c = _confirm(replace(c, apart_ids=(c.apart_ids | {c.track_id}) - {partner.track_id}, refused_ids=frozenset(),
                             t_swapped=partner.t), partner, keep_velocity=True)
    elif carrier is not None and carrier.t > max(c.t_confirmed, c.t_missed):
        settling = _settling(c, carrier, p)
        fit = _fit(c, carrier, p, carrier=True, position_only=settling)
        on_self = carrier.track_id not in candidates
        if fit.inside and not on_self:
            c = _confirm(c, carrier, keep_velocity=settling)
        elif c.misses + 1 >= p.misses_to_release:
            where = "on the chaser's own position" if on_self else "outside the target's gate"
            back = _before_swap(c, c.t_missed if c.misses else carrier.t, p)
            since = f"; back to its report at {back.t:.1f} s" if back is not None and back.t < c.t_confirmed else ""
            events.append(CustodyEvent(t, "released", c.target_id, c.track_id,
                                       f"{c.misses + 1} reports {where} (id swap or wrong track; last {fit}){since}"))
            c = replace(c, track_id=None, misses=0, apart_ids=c.apart_ids | {carrier.track_id})
            c = back.restore(c) if back is not None else c
            carrier = None
        else:
            c = replace(c, misses=c.misses + 1, t_missed=carrier.t)
    elif c.track_id is not None and carrier is None:
        why = "track ended" if c.track_id not in picture.tracks else "track taken for the ownship"
        crowd = f", {len(c.beside)} track(s) within {p.crowd_m:g} m" if c.beside else ""
        events.append(CustodyEvent(t, "released", c.target_id, c.track_id, f"{why}; coasting{crowd}"))
        c = replace(c, track_id=None, misses=0)
    if c.track_id is None:
        c = _hand_over(c, candidates, p, events, sight)
    c = _remember(_note_others(c, candidates, p), p)
    if c.track_id is None and c.since_confirmed(t) > p.max_coast_s:
        c = replace(c, lost=True)
        events.append(CustodyEvent(t, "lost", c.target_id, None, f"unconfirmed for {c.since_confirmed(t):.1f} s"))
    return c, events


def _swap_partner(c: Custody, carrier: RadarTrack, candidates: dict[int, RadarTrack], p: CustodyParams) -> RadarTrack | None:
    """The track beside the target that the radar exchanged ids with: in this scan its offset from the
    carrying track is the reverse of their offset at the target's last confirmation (both carried on
    their velocities), within ``gate_sigma`` of the four reports' error, and not the same offset. A
    bird keeping a few metres from the target is inside every position gate, and the swap shows in
    the carrier's velocity only as the radar's tracker turns it over; the offset reverses at once."""
    if carrier.track_id not in candidates:
        return None
    dt = carrier.t - c.t_confirmed
    for o in c.beside:
        now = candidates.get(o.track_id)
        if now is None or abs(now.t - carrier.t) > 0.1 or abs(o.t - c.t_confirmed) > 0.1:
            continue
        v_other = np.zeros(3) if o.velocity_enu is None else np.asarray(o.velocity_enu, float)
        before = c.position_enu - o.position_enu + (c.velocity_enu - v_other) * dt
        after = carrier.position_enu - now.position_enu
        slack = (p.accel_mps2 * dt * dt) ** 2  # both may have accelerated, each at up to accel_mps2
        cov = c.covariance_enu + o.covariance_enu + carrier.covariance_enu + now.covariance_enu + slack * np.eye(3)
        inv = np.linalg.inv(cov)
        reversed_, kept = float((after + before) @ inv @ (after + before)), float((after - before) @ inv @ (after - before))
        if reversed_ <= p.gate_sigma**2 < kept and _fit(c, now, p).inside:
            return now
    return None


def _hand_over(c: Custody, candidates: dict[int, RadarTrack], p: CustodyParams,
               events: list[CustodyEvent], sight: Sight | None = None) -> Custody:
    """The track that takes over a coasting target: the best fit in the gate that can be the target,
    and, while the camera sees the target, lies on its line of sight (one that does not waits: the
    camera may be the one that is wrong, so it is not refused for good). The one track in the gate the
    camera's line of sight passes through takes it over even from a crowd the radar cannot part (a
    bird keeping beside the target): there the camera, which tells a drone from a bird, decides."""
    best: tuple[_Fit, RadarTrack, str] | None = None
    refused = set(c.refused_ids)
    since = c.since_confirmed(max((tr.t for tr in candidates.values()), default=c.t_confirmed))
    beside_ids = {o.track_id for o in c.beside}
    fits = {}
    for tr in candidates.values():
        if tr.t <= c.t_confirmed or tr.track_id in refused:
            continue
        fit = _fit(c, tr, p)
        if not fit.inside:
            refused.add(tr.track_id)
            continue
        fits[tr.track_id] = fit
    picked = _on_sight(c, [candidates[i] for i in fits], p, sight)
    for tid, fit in fits.items():
        tr = candidates[tid]
        if tid == picked:
            why = ("id swap" if tid in c.apart_ids | beside_ids else "new id in the target's gate") + \
                ", the only one on the camera's line of sight"
            best = (fit, tr, why)
            break
        swap = since <= p.crowd_window_s and tid in beside_ids  # its own past is weighed below
        if tid in c.apart_ids and not swap:
            continue  # another object seen beside the target, or one that appeared away from it
        if c.beside and not _fits_target_better(c, tr, fit, p):
            continue  # in a close pass it may be the object beside the target: wait for their paths to part
        seen = sight is not None and abs(tr.t - sight.t) <= p.sight_max_age_s
        if seen and sight.offset_sigma(tr, p.sight_floor_m) > p.sight_sigma:
            continue  # in the gate, but not where the camera sees the target
        why = "id swap" if tid in c.apart_ids | beside_ids else "new id in the target's gate"
        why += ", on the camera's line of sight" if seen else ""
        if best is None or fit.cost < best[0].cost:
            best = (fit, tr, why)
    if best is None:
        return replace(c, refused_ids=frozenset(refused))
    fit, tr, why = best
    events.append(CustodyEvent(tr.t, "handover", c.target_id, tr.track_id,
                               f"{why} after {tr.t - c.t_confirmed:.1f} s ({fit})"))
    return _confirm(replace(c, apart_ids=c.apart_ids - {tr.track_id}, refused_ids=frozenset()), tr)


def _on_sight(c: Custody, tracks: list[RadarTrack], p: CustodyParams, sight: Sight | None) -> int | None:
    """The id of the one track among ``tracks`` the camera's fresh line of sight passes through (within
    ``sight_sigma``), if it is one: none of the others is on it, and it is no object seen apart from the
    target except one that was beside it (the crowd the radar could not part). None otherwise."""
    if sight is None:
        return None
    beside_ids = {o.track_id for o in c.beside}
    on = [tr for tr in tracks if abs(tr.t - sight.t) <= p.sight_max_age_s
          and sight.offset_sigma(tr, p.sight_floor_m) <= p.sight_sigma]
    if len(on) != 1 or (on[0].track_id in c.apart_ids and on[0].track_id not in beside_ids):
        return None
    return on[0].track_id


def _fits_target_better(c: Custody, tr: RadarTrack, fit: _Fit, p: CustodyParams) -> bool:
    """Whether ``tr`` (whose fit to the target is ``fit``) fits the target better by ``crowd_margin``
    than it fits each object that was beside the target at its last report, carried on its own velocity."""
    for o in c.beside:
        other = Custody(o.track_id, o.track_id, o.t, o.position_enu,
                        np.zeros(3) if o.velocity_enu is None else np.asarray(o.velocity_enu, float),
                        o.covariance_enu, "", o.t)
        if _fit(other, tr, p).cost - fit.cost < p.crowd_margin:
            return False
    return True


def _reacquire(c: Custody, candidates: dict[int, RadarTrack], p: CustodyParams,
               events: list[CustodyEvent], sight: Sight | None = None) -> Custody:
    """A lost target back, near where it was last and confident: the one such track on the camera's line
    of sight while the camera sees the target (re-identification), else the nearest first seen after
    the loss."""
    near = [tr for tr in candidates.values() if tr.confidence >= p.reacquire_confidence
            and float(np.linalg.norm(tr.position_enu - c.position_enu)) <= p.max_gate_m]
    seen = _on_sight(c, near, p, sight)
    if seen is not None:
        tr, how = candidates[seen], "track on the camera's line of sight"
    else:
        fresh = [tr for tr in near if tr.first_seen_t > c.t_confirmed and tr.track_id not in c.apart_ids]
        if not fresh:
            return c
        tr, how = min(fresh, key=lambda tr: float(np.linalg.norm(tr.position_enu - c.position_enu))), "new track"
    d = float(np.linalg.norm(tr.position_enu - c.position_enu))
    events.append(CustodyEvent(tr.t, "reacquired", c.target_id, tr.track_id,
                               f"{how} {d:.0f} m from where the target was lost, confidence {tr.confidence:.2f}"))
    return _confirm(replace(c, velocity_enu=np.zeros(3), refused_ids=frozenset()), tr)


def _duplicate(tr: RadarTrack, carrier: RadarTrack, p: CustodyParams) -> bool:
    """Whether ``tr`` is a second track of the carrier's object (the radar duplicates a track now and
    then): within ``duplicate_m`` of it and at its velocity (``carrier_vel_gate_mps``). Such a track is
    neither another object nor a crowd; it may carry the target when the carrier drops."""
    if tr.velocity_enu is None or carrier.velocity_enu is None:
        return False
    return (float(np.linalg.norm(tr.position_enu - carrier.position_enu)) <= p.duplicate_m
            and float(np.linalg.norm(tr.velocity_enu - carrier.velocity_enu)) <= p.carrier_vel_gate_mps)


def _note_others(c: Custody, candidates: dict[int, RadarTrack], p: CustodyParams) -> Custody:
    """Remember the tracks seen apart from the carrying one (other objects) and those close to it, as of
    the carrying track's confirmation of the target in this picture."""
    carrier = candidates.get(c.track_id) if c.track_id is not None else None
    if carrier is None or carrier.t != c.t_confirmed or carrier.t <= c.noted_t:
        return c  # judged against each report of the target once, never against a stale one
    apart, beside = set(c.apart_ids), []
    for tr in candidates.values():
        if tr.track_id == carrier.track_id or abs(tr.t - carrier.t) > 0.5 or _duplicate(tr, carrier, p):
            continue
        d = float(np.linalg.norm(tr.position_enu - carrier.position_enu))
        if d >= p.apart_m:
            apart.add(tr.track_id)
        if d <= p.crowd_m:
            beside.append(tr)
    return replace(c, apart_ids=frozenset(apart), beside=tuple(beside), noted_t=carrier.t)


def _remember(c: Custody, p: CustodyParams) -> Custody:
    """Keep this picture's confirmation (once judged against the tracks beside it) among the recent ones,
    back as far as a release may need (``swap_lookback_s`` and a report interval or two)."""
    if c.track_id is None or c.noted_t != c.t_confirmed or (c.recent and c.recent[-1].t >= c.t_confirmed):
        return c
    keep = tuple(r for r in c.recent if r.t >= c.t_confirmed - 1.5 * p.swap_lookback_s)
    return replace(c, recent=keep + (_Confirmation.of(c),))


def _before_swap(c: Custody, t_first_miss: float, p: CustodyParams) -> _Confirmation | None:
    """The newest recent confirmation at least ``swap_lookback_s`` before the first report that missed
    the gate: the last one that cannot have been the other object's (None: none that old kept)."""
    older = [r for r in c.recent if r.t <= t_first_miss - p.swap_lookback_s]
    return older[-1] if older else None
