"""Scoring a rehearsal against ground truth: the DESIGN §7 figures and the flight trace.

Only this module (and the rehearsal that calls it) reads the simulator's truth. The scores:

- ``t_airborne_s``: the first write of ``/radar/validated_track`` to the first tick at which the
  vehicle's telemetry altitude above home reaches the take-off altitude, by the take-off node's own
  rule (the first ``ArmAndTakeoff`` node's ``altitude_m - tolerance_m``); paper 15.48 s.
- ``t_acquire_s``: that moment to the first ``/target/estimate`` within 10 m of the true target, or
  within 3 deg of its true bearing from the camera; paper 4.95 s.
- ``target_in_fov_frac``: the share of ticks in autonomous flight with the true target inside the
  camera's frustum (true pose and :class:`~chaser_bt.vision.camera.CameraModel`, any range), from
  the first acquisition to the end of following, as the paper scored it (0.91);
  ``target_in_fov_frac_flight`` the same over all autonomous flight. Autonomous flight: armed,
  airborne, in a mode the mission flies (GUIDED or ALT_HOLD: not RTL/LAND/LOITER/BRAKE/failsafes),
  and the mission's phase not a safety hand-over (``safety:...``, e.g. the pilot's gate off).
- ``detection_frac``: the share of camera frames in that span whose chosen detector/tracker box
  matches the target's true box in the rendered frame (IoU >= 0.3, or the box centre inside it);
  paper 0.66.
- custody (the chase keeps the target it designated): the *designated* object is the one the radar
  track named in ``/target/custody`` was of when it was designated (the radar model's truth), else
  the first intruder; every figure above is scored on it. A tick *follows* an object when the
  camera's latest estimate (no older than 2 s) matches it (of two it matches, the one nearest its
  bearing: the box's range cannot part two drones close together). Over the follow phase after acquisition:
  ``custody_frac``, the share of ticks following something in which it is the designated object;
  ``target_switches``, how often the object followed changed; ``losses`` and ``reacquire_s_max``,
  the times the designated object went unmatched for over 2 s and the longest such gap that ended;
  ``envelope_frac``, the share of follow ticks inside the paper's follow envelope (slant range
  30-50 m, depression 30-50 deg, truth); ``followed_s_by_object``, seconds each object was followed;
  ``custody_at_end``, whether the last object followed is the designated one.
- ``radar_assoc_frac`` / ``wrong_assoc_frac``: 1 s windows of flight with the ownship in the radar's
  coverage, the radar on and the flying tree reading it; in each, the association the mission's
  correlator held for most ticks: a track that follows the ownship (right), another track (wrong) or
  none (paper 0.917); the radar model's truth says which track follows what.

Each is None where it does not apply (no radar, no camera, no target, never airborne...).
:func:`score_ticks` computes them from a list of :class:`TickRecord` (pure; tests build records by
hand); :class:`RehearsalObserver` records them while a rehearsal flies and fills the
:class:`~chaser_bt.log.trace.FlightTrace`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np
import py_trees
from scipy.spatial.transform import Rotation

from chaser_bt.geo import heading_to_enu_yaw
from chaser_bt.log.animation import FrameKeeper
from chaser_bt.log.trace import BeliefSnapshot, FlightTrace, TraceEvent
from chaser_bt.mission.outcome import PHASE_KEY
from chaser_bt.mission.resources import used_resources
from chaser_bt.radar.correlator import Association, TrackCorrelator, TrackPoints
from chaser_bt.vision.camera import CameraModel

__all__ = ["AUTONOMOUS_MODES", "FOLLOW_LEAVES", "TickRecord", "Scores", "score_ticks", "box_iou", "box_matches",
           "estimate_matches", "in_frustum", "belief_snapshot", "follow_geometry_errors", "association_windows", "AssociationRecorder", "RehearsalObserver"]

AUTONOMOUS_MODES = ("GUIDED", "ALT_HOLD")
FOLLOW_LEAVES = ("CVFollow", "FollowGlobal")
FOLLOW_PHASE = "follow"
VALIDATED_TRACK_KEY = "/radar/validated_track"
CUSTODY_KEY = "/target/custody"
ESTIMATE_KEY = "/target/estimate"
BELIEF_KEY = "/search/belief"
ACQUIRE_TOL_M = 10.0
ACQUIRE_TOL_RAD = math.radians(3.0)
LOST_AFTER_S = 2.0  # no matching estimate for this long after an acquisition: "lost" (DESIGN §3 stale data)
BELIEF_EVERY_S = 5.0
#: The paper's follow envelope (section 4): slant range 30-50 m, depression 30-50 deg.
ENVELOPE_RANGE_M = (30.0, 50.0)
ENVELOPE_DEPRESSION_RAD = (math.radians(30.0), math.radians(50.0))


# --- geometry of a match ------------------------------------------------------------------------

def box_iou(a: Sequence[float], b: Sequence[float]) -> float:
    """Intersection over union of two (x0, y0, x1, y1) boxes."""
    iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = iw * ih
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def box_matches(box: Sequence[float], truth: Sequence[float], min_iou: float = 0.3) -> bool:
    """A detection matches the truth box when IoU >= ``min_iou`` or its centre lies inside the truth box."""
    cx, cy = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
    return box_iou(box, truth) >= min_iou or (truth[0] <= cx <= truth[2] and truth[1] <= cy <= truth[3])


def estimate_matches(position_enu: np.ndarray, bearing_enu: np.ndarray | None, camera_enu: np.ndarray,
                     target_enu: np.ndarray, tol_m: float = ACQUIRE_TOL_M, tol_rad: float = ACQUIRE_TOL_RAD) -> bool:
    """Whether an estimate is of the true target: within ``tol_m`` of it, or its bearing within
    ``tol_rad`` of the true bearing from the camera (the range from a box is the loose part)."""
    if np.linalg.norm(np.asarray(position_enu, float) - target_enu) <= tol_m:
        return True
    if bearing_enu is None or not np.all(np.isfinite(bearing_enu)):
        return False
    to_target = np.asarray(target_enu, float) - camera_enu
    n = np.linalg.norm(to_target) * np.linalg.norm(bearing_enu)
    return bool(n > 0 and math.acos(min(1.0, max(-1.0, float(np.dot(to_target, bearing_enu)) / n))) <= tol_rad)


def in_frustum(camera: CameraModel, target_enu: np.ndarray, vehicle_enu: np.ndarray, attitude: Rotation) -> bool:
    """Whether the target projects inside the image (in front of the camera, any range)."""
    px, front = camera.project(np.asarray(target_enu, float)[None], vehicle_enu, attitude)
    u, v = px[0]
    return bool(front[0] and 0.0 <= u <= camera.width_px and 0.0 <= v <= camera.height_px)


def belief_snapshot(t: float, belief: Any) -> BeliefSnapshot:
    """A search belief (:class:`chaser_bt.search.belief.BeliefGrid`) for the trace: normalised and
    summed over altitude, with the east and north cell centres."""
    spec = belief.spec
    x = spec.origin_enu[0] + spec.spacing_m * np.arange(spec.shape[0])
    y = spec.origin_enu[1] + spec.spacing_m * np.arange(spec.shape[1])
    return BeliefSnapshot(t, x, y, belief.normalized().sum(axis=2))


# --- radar association windows --------------------------------------------------------------------

def association_windows(t: np.ndarray, state: np.ndarray, counted: np.ndarray, window_s: float = 1.0) -> tuple[int, float | None, float | None]:
    """1 s windows of ``t`` where most samples are ``counted``; in each, the state held by a strict
    majority of its samples (1 right, -1 wrong, else none). Returns (windows, right share, wrong share)
    (as :func:`sitl.bench.radar_trials.score_correlator` scores the paper's correlation test)."""
    t, state, counted = np.asarray(t, float), np.asarray(state, int), np.asarray(counted, bool)
    if t.size == 0:
        return 0, None, None
    win = np.floor(t / window_s).astype(np.int64)
    n = right = wrong = 0
    for w in np.unique(win):
        sel = win == w
        if counted[sel].mean() < 0.5:
            continue
        n += 1
        s = state[sel & counted]
        values, counts = np.unique(s, return_counts=True)
        held = values[np.argmax(counts)] if counts.max() * 2 > s.size else 0
        right += int(held == 1)
        wrong += int(held == -1)
    return n, (right / n if n else None), (wrong / n if n else None)


class AssociationRecorder:
    """Wraps the mission's correlator and remembers its latest decision (for scoring only)."""

    def __init__(self, inner: TrackCorrelator) -> None:
        self.inner = inner
        self.last_t: float | None = None
        self.last_id: int | None = None

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def add_ownship(self, *args: Any, **kwargs: Any) -> None:
        self.inner.add_ownship(*args, **kwargs)

    def add_tracks(self, points: TrackPoints) -> None:
        self.inner.add_tracks(points)

    def associate(self, t: float) -> Association:
        a = self.inner.associate(t)
        self.last_t, self.last_id = t, a.associated_id
        return a

    def reset(self) -> None:
        self.inner.reset()


# --- per-tick records and the scores -----------------------------------------------------------

@dataclass
class TickRecord:
    """What scoring needs from one mission tick (truth and the mission's side).

    Args:
        t: mission time (s).
        autonomous: armed, airborne, in a mission mode, not handed over (see the module docstring).
        airborne: off the ground (truth).
        validated: ``/radar/validated_track`` has been written.
        alt_reached: telemetry altitude at or above the take-off altitude.
        following: the mission is in its follow phase (or a follow leaf is running).
        in_fov: the true target inside the camera frustum (None: no target).
        acquired: a fresh estimate this tick that matches the true target (None: no fresh estimate).
        frame: a camera frame was processed this tick.
        frame_matched: that frame's chosen box matches the true target box.
        radar_state: 1 ownship's track associated, -1 another track, 0 none.
        radar_counted: airborne, radar on and the ownship in its coverage.
        followed: index of the object a fresh estimate matched this tick (None: no fresh match).
        designated: index of the designated object (None: no target).
        in_envelope: the truth geometry to the designated object inside the paper's follow envelope.
    """

    t: float
    autonomous: bool = False
    airborne: bool = False
    validated: bool = False
    alt_reached: bool = False
    following: bool = False
    in_fov: bool | None = None
    acquired: bool | None = None
    frame: bool = False
    frame_matched: bool = False
    radar_state: int = 0
    radar_counted: bool = False
    followed: int | None = None
    designated: int | None = None
    in_envelope: bool | None = None


@dataclass(frozen=True)
class Scores:
    """The DESIGN §7 figures of one run (None where they do not apply) and the times behind them."""

    t_airborne_s: float | None = None
    t_acquire_s: float | None = None
    target_in_fov_frac: float | None = None
    target_in_fov_frac_flight: float | None = None
    detection_frac: float | None = None
    radar_assoc_frac: float | None = None
    wrong_assoc_frac: float | None = None
    radar_windows: int = 0
    detection_frames: int = 0  # frames in the scored span
    t_validated: float | None = None
    t_alt_reached: float | None = None
    t_acquired: float | None = None
    t_follow_end: float | None = None
    custody_frac: float | None = None
    target_switches: int | None = None
    losses: int | None = None
    reacquire_s_max: float | None = None
    envelope_frac: float | None = None
    custody_at_end: bool | None = None
    followed_ticks: dict[int, int] = field(default_factory=dict)  # object index -> follow ticks following it

    def report_keys(self, names: Sequence[str] = (), tick_s: float = 0.0) -> dict[str, Any]:
        """The keys the rehearsal report carries (rounded)."""
        def r(v: float | None, nd: int) -> float | None:
            return None if v is None else round(float(v), nd)

        return {"t_airborne_s": r(self.t_airborne_s, 2), "t_acquire_s": r(self.t_acquire_s, 2),
                "target_in_fov_frac": r(self.target_in_fov_frac, 3),
                "target_in_fov_frac_flight": r(self.target_in_fov_frac_flight, 3),
                "detection_frac": r(self.detection_frac, 3), "radar_assoc_frac": r(self.radar_assoc_frac, 3),
                "wrong_assoc_frac": r(self.wrong_assoc_frac, 3), "radar_windows": self.radar_windows,
                "detection_frames": self.detection_frames,
                "custody_frac": r(self.custody_frac, 3), "target_switches": self.target_switches,
                "losses": self.losses, "reacquire_s_max": r(self.reacquire_s_max, 2),
                "envelope_frac": r(self.envelope_frac, 3), "custody_at_end": self.custody_at_end,
                "followed_s_by_object": {(names[k] if k < len(names) else str(k)): round(n * tick_s, 1)
                                         for k, n in sorted(self.followed_ticks.items())} or None}


def _first(records: Sequence[TickRecord], after: float, pred) -> float | None:
    return next((r.t for r in records if r.t >= after and pred(r)), None)


def _share(flags: list[bool]) -> float | None:
    return sum(flags) / len(flags) if flags else None


def score_ticks(records: Sequence[TickRecord], *, has_target: bool = True, has_camera: bool = True,
                has_radar: bool = True) -> Scores:
    """The scores of a run from its tick records (see the module docstring for each definition)."""
    t_val = _first(records, -math.inf, lambda r: r.validated)
    t_alt = None if t_val is None else _first(records, t_val, lambda r: r.alt_reached)
    t_acq = None if t_alt is None or not has_target else _first(records, t_alt, lambda r: bool(r.acquired))
    t_end = None
    if t_acq is not None:
        follow = [r.t for r in records if r.t >= t_acq and r.following]
        auto = [r.t for r in records if r.t >= t_acq and r.autonomous]
        t_end = follow[-1] if follow else (auto[-1] if auto else t_acq)
    fov = fov_flight = det = None
    frames = 0
    if has_target and has_camera:
        fov_flight = _share([bool(r.in_fov) for r in records if r.autonomous and r.in_fov is not None])
        if t_acq is not None:
            span = [r for r in records if t_acq <= r.t <= t_end and r.autonomous]
            fov = _share([bool(r.in_fov) for r in span if r.in_fov is not None])
            shots = [r.frame_matched for r in span if r.frame]
            frames, det = len(shots), _share(shots)
    custody = _custody_scores(records, t_acq, t_end) if has_target and t_acq is not None else {}
    windows, right, wrong = 0, None, None
    if has_radar:
        windows, right, wrong = association_windows(np.array([r.t for r in records]),
                                                    np.array([r.radar_state for r in records]),
                                                    np.array([r.radar_counted for r in records]))
    return Scores(
        t_airborne_s=None if t_alt is None else t_alt - t_val,
        t_acquire_s=None if t_acq is None else t_acq - t_alt,
        target_in_fov_frac=fov, target_in_fov_frac_flight=fov_flight, detection_frac=det,
        radar_assoc_frac=right, wrong_assoc_frac=wrong, radar_windows=windows, detection_frames=frames,
        t_validated=t_val, t_alt_reached=t_alt, t_acquired=t_acq, t_follow_end=t_end, **custody,
    )


def _custody_scores(records: Sequence[TickRecord], t_acq: float, t_end: float) -> dict[str, Any]:
    """The custody figures over the follow ticks from acquisition to the end of following (module docstring)."""
    followed: list[int | None] = []  # per record: the object followed (a match no older than LOST_AFTER_S)
    last: tuple[float, int] | None = None
    for r in records:
        if r.followed is not None:
            last = (r.t, r.followed)
        followed.append(last[1] if last is not None and r.t - last[0] <= LOST_AFTER_S else None)
    span = [(r, f) for r, f in zip(records, followed) if t_acq <= r.t <= t_end and r.following and r.autonomous]
    if not span:
        return {}
    held = [(r, f) for r, f in span if f is not None]
    counts: dict[int, int] = {}
    for _, f in held:
        counts[f] = counts.get(f, 0) + 1
    switches = sum(1 for (_, a), (_, b) in zip(held, held[1:]) if a != b)
    gaps, start, losses = [], None, 0
    for r, f in span:
        on_target = f is not None and f == r.designated
        if not on_target and start is None:
            start = r.t
            losses += 1
        elif on_target and start is not None:
            gaps.append(r.t - start + LOST_AFTER_S)
            start = None
    env = [bool(r.in_envelope) for r, _ in span if r.in_envelope is not None]
    return {
        "custody_frac": _share([f == r.designated for r, f in held]),
        "target_switches": switches,
        "losses": losses,
        "reacquire_s_max": max(gaps) if gaps else None,
        "envelope_frac": _share(env),
        "custody_at_end": bool(held) and held[-1][1] == held[-1][0].designated,
        "followed_ticks": counts,
    }


def follow_geometry_errors(trace: FlightTrace) -> tuple[float | None, float | None]:
    """How far the vehicle sat from the follow geometry it was asked for: medians over the trace's
    ``follow`` ticks of |slant range - desired| (m) and |depression - desired| (rad), from the truth.
    (None, None) without a follow phase or a desired geometry."""
    follow = np.array([p == FOLLOW_PHASE for p in trace.phase], dtype=bool)
    if not follow.any() or not math.isfinite(trace.desired_range_m) or not math.isfinite(trace.desired_elevation_rad):
        return None, None
    rng = np.abs(trace.slant_range_m[follow] - trace.desired_range_m)
    elev = np.abs(trace.elevation_rad[follow] - trace.desired_elevation_rad)
    return float(np.nanmedian(rng)), float(np.nanmedian(elev))


# --- watching a live rehearsal -----------------------------------------------------------------

def _blackboard(key: str) -> Any:
    return py_trees.blackboard.Blackboard.storage.get(key)


def _nodes_named(root: py_trees.behaviour.Behaviour, class_names: Sequence[str]) -> list[Any]:
    return [n for n in root.iterate() if type(n).__name__ in class_names]


def _port(node: Any, name: str) -> Any:
    try:
        return node.get_input(name)
    except Exception:  # an unset remapped key: not known (yet)
        return None


@dataclass
class _TraceColumns:
    t: list[float] = field(default_factory=list)
    own: list[np.ndarray] = field(default_factory=list)
    yaw: list[float] = field(default_factory=list)
    target: list[np.ndarray] = field(default_factory=list)
    in_fov: list[float] = field(default_factory=list)
    detected: list[float] = field(default_factory=list)
    mode: list[str] = field(default_factory=list)
    phase: list[str] = field(default_factory=list)
    tip: list[str] = field(default_factory=list)


class RehearsalObserver:
    """Records a :class:`TickRecord` (and, with ``trace``, a trace row) after every mission tick.

    Args:
        sim: the simulator (truth).
        link: the mission's vehicle link (what the mission knows: telemetry altitude).
        runner: the mission runner (tree, tip).
        sensors: the rehearsal's :class:`sitl.bench.sensors.MissionSensors`.
        trace: also fill a :class:`FlightTrace`.
    """

    def __init__(self, sim: Any, link: Any, runner: Any, sensors: Any, trace: bool = False) -> None:
        self.sim, self.link, self.runner, self.sensors = sim, link, runner, sensors
        self.records: list[TickRecord] = []
        self.events: list[TraceEvent] = []
        self.beliefs: list[BeliefSnapshot] = []
        self._cols = _TraceColumns() if trace else None
        # The objects a chase may follow, in the camera's label order (intruders, then scripted
        # targets); the one scored is the designated one (the first until a custody names another).
        self._objects: list[tuple[str, Callable[[float], np.ndarray | None]]] = [
            (intr.name, lambda t, i=intr: i.pos.copy()) for intr in sim.intruders]
        self._objects += [(tg.name, lambda t, tg=tg: (np.asarray(tg.path.position_enu(t), float) if tg.present(t) else None))
                          for tg in sim.scenario.targets]
        self.has_target = bool(self._objects)
        self._designated: int | None = 0 if self._objects else None
        self._custody_seen: tuple | None = None
        self._custody_track: int | None = None
        self.camera: CameraModel = (sensors.camera.pipeline.camera if sensors.camera is not None else CameraModel())
        self.has_camera = sensors.camera is not None
        self.has_radar = sensors.radar is not None
        self._recorder: AssociationRecorder | None = None
        self._labels: dict[int, str] = {}
        self._radar_tree: tuple[Any, bool] | None = None  # (the flying tree's root, whether it reads the radar)
        if sensors.radar is not None:
            self._recorder = AssociationRecorder(sensors.radar.correlator)
            sensors.radar.correlator = self._recorder
            sim.add_radar_consumer(self._radar_truth)
        tree_root = runner.tree.root
        self._takeoff = next(iter(_nodes_named(tree_root, ("ArmAndTakeoff",))), None)
        self._follow = next(iter(_nodes_named(tree_root, FOLLOW_LEAVES)), None)
        self._takeoff_alt: float | None = None
        self._last_frame_index: int | None = None
        self._last_est_t: float | None = None
        self._acquired = False
        self._last_match_t: float | None = None
        self._last_phase = self._last_mode = None
        self._validated_seen = self._alt_seen = False
        self._next_belief_t = -math.inf
        self._last_belief_t: float | None = None
        # With a trace: a few camera frames around the acquisition, for the animated report (chaser_bt.log.animation).
        self.frames: FrameKeeper | None = FrameKeeper() if trace and self.has_camera else None

    def _radar_truth(self, datagram: bytes) -> None:
        truth = self.sim.radar_truth
        if truth is not None:
            self._labels.update(truth.labels)

    # -- per tick --------------------------------------------------------------------------------

    @property
    def object_names(self) -> list[str]:
        return [name for name, _ in self._objects]

    def target_enu(self) -> np.ndarray | None:
        """The designated object's true position now (None: no target, or not present)."""
        if self._designated is None:
            return None
        return self._objects[self._designated][1](self.sim.time_s)

    def _designation(self, t: float) -> None:
        """Follow the mission's custody: a new designation names the object its track was of then;
        a change of the carrying track is an event."""
        custody = _blackboard(CUSTODY_KEY)
        if custody is None or not hasattr(custody, "target_id"):
            return
        key = (custody.target_id, custody.t_designated)
        if key != self._custody_seen:
            self._custody_seen = key
            name = self._labels.get(custody.target_id)
            names = self.object_names
            self._designated = names.index(name) if name in names else None
            self.events.append(TraceEvent(t, "designated", f"track {custody.target_id}: {name or 'not a target'} "
                                                           f"({custody.designated_by})"))
        if custody.track_id != self._custody_track:
            self._custody_track = custody.track_id
            state = "coasting" if custody.track_id is None else f"track {custody.track_id}"
            self.events.append(TraceEvent(t, "custody", "lost" if custody.lost else state))

    def _followed(self, est: Any, cam_pos: np.ndarray, t: float) -> int | None:
        """The object a fresh estimate is of: the nearest in bearing among those it matches (the
        camera measures the bearing well and the range from a box badly, so two drones close
        together are told apart by the bearing; an estimate without one, by position over range)."""
        best: tuple[float, int] | None = None
        bearing = getattr(est, "bearing_enu", None)
        bearing = bearing if bearing is not None and np.all(np.isfinite(bearing)) else None
        for k, (_, where) in enumerate(self._objects):
            pos = where(t)
            if pos is None or not estimate_matches(est.position_enu, bearing, cam_pos, pos):
                continue
            to = pos - cam_pos
            dist = max(float(np.linalg.norm(to)), 1e-6)
            if bearing is not None:
                d = math.acos(min(1.0, max(-1.0, float(bearing @ to) / dist)))
            else:
                d = float(np.linalg.norm(est.position_enu - pos)) / dist
            if best is None or d < best[0]:
                best = (d, k)
        return None if best is None else best[1]

    def _takeoff_altitude(self) -> float | None:
        if self._takeoff_alt is None and self._takeoff is not None:
            alt, tol = _port(self._takeoff, "altitude_m"), _port(self._takeoff, "tolerance_m")
            if alt is not None:
                self._takeoff_alt = float(alt) - float(tol or 0.0)
        return self._takeoff_alt

    def after_tick(self, t: float) -> None:
        """Record the tick that just ran at mission time ``t``."""
        sim, truth = self.sim, self.sim.truth
        ap = sim.autopilot
        mode = ap.mode
        phase = _blackboard(PHASE_KEY)
        phase = phase if isinstance(phase, str) else ""
        tip_node = self.runner.tree.root.tip()
        tip_name = type(tip_node).__name__ if tip_node is not None else ""
        airborne = not truth.on_ground
        autonomous = bool(ap.armed and airborne and mode in AUTONOMOUS_MODES and not phase.startswith("safety"))
        following = phase == FOLLOW_PHASE or tip_name in FOLLOW_LEAVES
        rec = TickRecord(t, autonomous=autonomous, airborne=airborne, following=following)
        rec.validated = _blackboard(VALIDATED_TRACK_KEY) is not None
        alt = self._takeoff_altitude()
        rec.alt_reached = alt is not None and math.isfinite(self.link.state.alt_rel_m) and self.link.state.alt_rel_m >= alt
        own = np.asarray(truth.pos_enu, float)
        self._designation(t)
        rec.designated = self._designated
        target = self.target_enu()
        if target is not None:  # the attitude (a scipy Rotation, built on demand) only serves the target's scores
            att = truth.attitude
            rec.in_fov = in_frustum(self.camera, target, own, att)
            rel = target - own
            slant = float(np.linalg.norm(rel))
            depression = math.atan2(-rel[2], float(np.hypot(rel[0], rel[1])))
            rec.in_envelope = (ENVELOPE_RANGE_M[0] <= slant <= ENVELOPE_RANGE_M[1]
                               and ENVELOPE_DEPRESSION_RAD[0] <= depression <= ENVELOPE_DEPRESSION_RAD[1])
        est = _blackboard(ESTIMATE_KEY)
        if est is not None and est.t != self._last_est_t and self.has_target:
            self._last_est_t = est.t
            cam_pos = self.camera.position_enu(own, truth.attitude)
            rec.followed = self._followed(est, cam_pos, self.sim.time_s)
            rec.acquired = rec.followed is not None and rec.followed == self._designated
        self._camera_frame(rec)
        self._radar_state(rec, own, airborne)
        self.records.append(rec)
        self._note_events(rec, mode, phase)
        self._belief(t)
        if self._cols is not None:
            self._trace_row(rec, own, truth, target, mode, phase)

    def _camera_frame(self, rec: TickRecord) -> None:
        cam = self.sensors.camera
        frame = cam.last_frame if cam is not None else None
        if frame is None or frame.index == self._last_frame_index:
            return
        self._last_frame_index = frame.index
        rec.frame = True
        track = cam.pipeline.track
        truth_boxes = [lab.box for lab in self.sensors.frame_source.last_labels if lab.index == self._designated]
        rec.frame_matched = bool(track is not None and truth_boxes and box_matches(track.box, truth_boxes[0]))
        if self.frames is not None:
            try:
                self.frames.offer(float(frame.t), frame.image, None if track is None else track.box,
                                  truth_boxes[0] if truth_boxes else None, acquired=bool(rec.acquired))
            except Exception:  # the pictures never cost the flight
                logging.getLogger(__name__).exception("could not keep a camera frame; keeping none")
                self.frames = None

    def _radar_state(self, rec: TickRecord, own: np.ndarray, airborne: bool) -> None:
        radar = self.sim.radar
        if radar is None or self._recorder is None:
            return
        rec.radar_counted = bool(airborne and radar.is_on(self.sim.time_s) and radar.in_coverage(own)
                                 and self._tree_uses_radar())
        r = self._recorder
        if r.last_t is not None and rec.t - r.last_t <= 1.0 and r.last_id is not None:
            rec.radar_state = 1 if self._labels.get(r.last_id) == "ownship" else -1

    def _tree_uses_radar(self) -> bool:
        """Whether the tree flying now reads the radar (a retask may have replaced it with one that does not:
        its windows are then no association's to score)."""
        root = self.runner.tree.root
        if self._radar_tree is None or self._radar_tree[0] is not root:
            self._radar_tree = (root, "radar" in used_resources(root))
        return self._radar_tree[1]

    def _note_events(self, rec: TickRecord, mode: str, phase: str) -> None:
        t = rec.t
        if rec.validated and not self._validated_seen:
            self._validated_seen = True
            self.events.append(TraceEvent(t, "radar_validated", str(_blackboard(VALIDATED_TRACK_KEY))))
        if self._validated_seen and rec.alt_reached and not self._alt_seen:
            self._alt_seen = True
            self.events.append(TraceEvent(t, "airborne", f"{self.link.state.alt_rel_m:.1f} m"))
        if rec.acquired:
            self._last_match_t = t
            if not self._acquired:
                self._acquired = True
                self.events.append(TraceEvent(t, "acquired"))
        elif self._acquired and self._last_match_t is not None and t - self._last_match_t > LOST_AFTER_S:
            self._acquired = False
            self.events.append(TraceEvent(t, "lost", f"no matching estimate for {LOST_AFTER_S:.0f} s"))
        if phase != self._last_phase:
            if phase:
                self.events.append(TraceEvent(t, "phase", phase))
            self._last_phase = phase
        if mode != self._last_mode:
            self.events.append(TraceEvent(t, "mode", mode))
            self._last_mode = mode

    def _belief(self, t: float) -> None:
        snap = _blackboard(BELIEF_KEY)
        belief = getattr(snap, "belief", None)
        if belief is None or t < self._next_belief_t or snap.t == self._last_belief_t:
            return
        self._next_belief_t, self._last_belief_t = t + BELIEF_EVERY_S, snap.t
        self.beliefs.append(belief_snapshot(float(snap.t), belief))

    def _trace_row(self, rec: TickRecord, own: np.ndarray, truth: Any, target: np.ndarray | None, mode: str,
                   phase: str) -> None:
        c = self._cols
        c.t.append(rec.t)
        c.own.append(own)
        c.yaw.append(heading_to_enu_yaw(truth.euler_ned[2]))
        c.target.append(target if target is not None else np.full(3, np.nan))
        c.in_fov.append(float(rec.in_fov) if rec.autonomous and rec.in_fov is not None else math.nan)
        c.detected.append(float(rec.frame_matched) if rec.autonomous and rec.frame else math.nan)
        c.mode.append(mode)
        c.phase.append(phase)
        c.tip.append(self.runner.tip_message())

    # -- at the end --------------------------------------------------------------------------------

    def scores(self) -> Scores:
        return score_ticks(self.records, has_target=self.has_target, has_camera=self.has_camera,
                           has_radar=self.has_radar)

    def report_keys(self) -> dict[str, Any]:
        """The scores as the rehearsal report carries them."""
        tick_s = float(np.median(np.diff([r.t for r in self.records]))) if len(self.records) > 1 else 0.0
        designated = self._designated
        return {**self.scores().report_keys(self.object_names, tick_s),
                "designated_object": None if designated is None else self.object_names[designated]}

    def following(self) -> bool:
        """Whether the mission was following at its last tick."""
        return bool(self.records) and self.records[-1].following

    def trace(self, meta: dict) -> FlightTrace | None:
        """The flight trace (None unless asked for); ownship pose and target are the simulator's truth."""
        c = self._cols
        if c is None:
            return None
        rng = _port(self._follow, "slant_range_m") if self._follow is not None else None
        elev = _port(self._follow, "elevation_deg") if self._follow is not None else None
        # A run interrupted (Ctrl-C) in the middle of a row leaves the columns uneven: whole rows only.
        n = min(len(col) for col in (c.t, c.own, c.yaw, c.target, c.in_fov, c.detected, c.mode, c.phase, c.tip))
        return FlightTrace(
            t=np.array(c.t[:n], float), ownship_enu=np.array(c.own[:n], float).reshape(-1, 3),
            ownship_yaw_rad=np.array(c.yaw[:n], float), target_enu=np.array(c.target[:n], float).reshape(-1, 3),
            in_fov=np.array(c.in_fov[:n], float), detected=np.array(c.detected[:n], float), mode=c.mode[:n],
            phase=c.phase[:n], tip=c.tip[:n], events=list(self.events), beliefs=list(self.beliefs), target_source="truth",
            desired_range_m=float(rng) if rng is not None else math.nan,
            desired_elevation_rad=math.radians(float(elev)) if elev is not None else math.nan,
            meta={**meta, "ownship_source": "truth"}, frames=[] if self.frames is None else self.frames.snapshots(),
        )
