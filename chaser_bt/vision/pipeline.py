"""Frames -> detections -> tracks -> target estimate (paper section 3.1).

The detector runs on every ``detect_every``-th frame; the trackers carry the boxes on the frames in
between (paper: detector 8-10 frames/s, estimates above 30). With ``focus`` on, a detector frame
looks at a zoomed window (:mod:`chaser_bt.vision.focus`) around the followed track or, before
there is one, around a cue (radar or the target's telemetry) projected into the image; without a
cue, every ``full_frame_every``-th detector frame still sees the whole frame. Given a cue, a track whose
bearing disagrees with the cue's by more than the gate is not taken for the target (a bush or a
bird the detector mistook for it). The chosen track's box centre becomes an
ENU bearing through the smoothed attitude (:mod:`chaser_bt.vision.projection`), its width a range
(:mod:`chaser_bt.vision.range`) unless the mission gives the target's telemetry or the target is on
flat ground (a person in search and rescue: range to where the bearing meets z = 0), and the two a
:class:`~chaser_bt.cue.TargetEstimate` with a covariance that is tight across the bearing and loose
along it.

Each frame is planned before it is read (:meth:`VisionPipeline.plan`: detector frame or not, the focus
window, the trackers' neighbourhoods), so a camera that reads out regions of interest (the
simulator's) is asked for only those parts (:class:`CameraSensor`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from typing import Callable, ClassVar, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.cue_fit import CueFit
from chaser_bt.vision.detection import Detection
from chaser_bt.vision.focus import FocusWindow, focus_window
from chaser_bt.vision.frame_source import Frame, FrameSource, Region, reads_regions
from chaser_bt.vision.projection import AttitudeSmoother, Projector
from chaser_bt.vision.range import TARGET_SPAN_M, RangeFilter, range_from_box
from chaser_bt.vision.trackers import Track, TrackerBank

log = logging.getLogger(__name__)

__all__ = ["OwnshipPose", "PipelineConfig", "FramePlan", "VisionPipeline", "CameraSensor", "ground_range"]


@dataclass(frozen=True)
class OwnshipPose:
    """The chaser at a frame's time, from its own telemetry: ENU position, velocity and FLU->ENU attitude."""

    t: float
    position_enu: np.ndarray
    velocity_enu: np.ndarray
    attitude: Rotation


@dataclass(frozen=True)
class PipelineConfig:
    """Pipeline settings.

    Args:
        detect_every: run the detector on every k-th frame (1 = every frame).
        classes: class names accepted as targets (empty = all).
        bearing_std_rad: 1-sigma bearing error used in the covariance.
        confidence_half_life_s: how fast a track's confidence decays without a detection.
        max_track_age_s: a track not confirmed by a detection for this long is not reported.
        target_on_ground: the target stands on flat ground at ENU z = 0 (home's height): range is
            where the bearing meets it, not the box size (used when no telemetry range is given).
        confirm_hits: detector hits before a track is reported (1: the first detection); with a cue,
            one hit inside the cue's gate is enough.
        max_misses: detector frames in a row a confirmed track coasts on its trackers without a detection.
        reacquire_s: for this long after the last estimate, a new track is picked by its bearing's
            closeness to that estimate's (else by hits, then score).
        focus: detect in a zoomed window around the followed track or the cue (see the module docstring).
        focus_box_px: the zoom puts the expected box this wide in the detector's input.
        focus_max_zoom: most zoom (detector pixels per frame pixel) of the focus window.
        focus_min_zoom: a window zooming less than this is not used: a target that large is detected
            on the whole frame, at the scale the detector was trained on.
        full_frame_every: without a cue, every k-th detector frame sees the whole frame even with a focus.
        cue_min_score: with a fresh cue, the detector keeps boxes in its focus window down to this score
            (None: its own threshold; a detector without a ``detect(image, conf_threshold)`` keeps its
            own): the cue's gate is the independent check a low score lacks, and a target 60-120 m out,
            a few pixels across, scores low.
        cue_gate_deg: a track's bearing may differ from the cue's by this much, plus three sigma of the
            cue's position error seen from the camera. A cue just off the image is looked for at its
            edge; one further outside the image than the gate reaches gets no detector frame (nothing
            in view could pass the gate), only the trackers.
        cue_range_ratio: a track whose box-size range is shorter than the cue's distance less three
            sigma divided by this, or longer than its distance plus three sigma times this, is not the
            target: something near the camera on the cue's bearing (clutter, a cloud's edge). Boxes of
            a target a few pixels wide read it up to 4x short (the detector's smallest box), hence 5.
        detector_input_px: the focus window's size in detector pixels; the detector takes it as it is
            (no letterbox). 320, not the whole frame's 416: the window is centred on the track or the
            cue, so the context a larger one adds is far from the target, and a 320 window costs the
            int8 network 3.1 ms against 4.5 and the simulated camera a smaller region to draw.
        track_margin_px: the part of a frame the trackers read around a track's box: this much on each
            side, or the box's own size if larger (:attr:`FramePlan.regions`).
        reseed_min_score: with a detector whose scores predict the box's IoU (``scores_are_iou``), a
            detection scoring less confirms a followed track without moving it
            (:class:`chaser_bt.vision.trackers.TrackerBank`); ignored for other detectors.
        refine_tracks: between detector frames, re-place the tracked boxes with the detector's box
            refiner when it has one (:mod:`chaser_bt.vision.detector.refine`): trackers keep the detection's
            size and drift by a pixel or two a frame.
        cue_fit_tau_s, cue_switch_sigma: radar-camera association (:mod:`chaser_bt.vision.cue_fit`):
            each gated track's offset from the cue's line of sight, in the cue's error, is averaged
            with this time constant; once the followed track's exceeds ``cue_switch_sigma`` and
            another's is a sigma lower, the pipeline follows the other (the trackers slid onto a
            drone crossing close by). ``inf`` never switches.
        cue_fusion_max_age_s, cue_speed_std_mps, cue_range_floor_m: a cue at most this old (the radar's
            report of the target) gives the range filter its position seen along the camera's bearing,
            with the cue's own error along it widened by ``cue_range_floor_m`` (our own position,
            timing, the target's size: :meth:`~chaser_bt.vision.range.RangeFilter.fuse_range`), and,
            with a velocity, the target's speed along the bearing, told with ``cue_speed_std_mps``
            (:meth:`~chaser_bt.vision.range.RangeFilter.update_radial_speed`): a distant target is not read
            too close from its few-pixel box, nor a target dashing at the camera too far until its box
            has grown. 0 s: box sizes alone.
    """

    detect_every: int = 3
    classes: tuple[str, ...] = ()
    bearing_std_rad: float = math.radians(0.3)
    confidence_half_life_s: float = 1.0
    max_track_age_s: float = 1.5
    tracker_kinds: tuple[str, ...] = ("mosse", "medianflow")  # KCF/CSRT/MIL cost 60-95 ms a frame here (docs/vision.md)
    attitude_alpha: float = 0.6
    attitude_beta: float = 0.1
    target_on_ground: bool = False
    confirm_hits: int = 2
    max_misses: int = 2
    reseed_min_score: float = 0.5
    refine_tracks: bool = True
    reacquire_s: float = 2.0
    focus: bool = True
    focus_box_px: float = 32.0
    focus_max_zoom: float = 2.0
    focus_min_zoom: float = 1.25
    full_frame_every: int = 3
    cue_min_score: float | None = 0.15
    cue_gate_deg: float = 4.0
    cue_range_ratio: float = 5.0
    detector_input_px: int = 320
    track_margin_px: float = 64.0
    cue_fit_tau_s: float = 1.0
    cue_switch_sigma: float = 2.5
    cue_fusion_max_age_s: float = 1.0
    cue_speed_std_mps: float = 1.0
    cue_range_floor_m: float = 3.0


@dataclass(frozen=True)
class FramePlan:
    """What the pipeline does with the next frame, decided before the frame is read: the smoothed
    attitude and camera position, the attitude as ``measured`` (the camera's turn between frames is
    reckoned from it: the smoothing lags a gust's swing), the cue's position, whether the detector
    runs and where it looks (``window``; None: the whole frame), whether a track the detector did not
    see there counts against it (``judge``), and ``regions``, the only parts of the frame the pipeline
    will read (the focus window, the trackers' neighbourhoods; None: all of it), for a camera that
    reads out regions."""

    attitude: Rotation
    measured: Rotation
    camera_enu: np.ndarray
    cue_enu: np.ndarray | None
    detect: bool
    window: FocusWindow | None
    judge: bool
    regions: tuple[Region, ...] | None


@dataclass
class VisionPipeline:
    """Stateful per-camera pipeline; :meth:`process` takes one frame and the ownship pose."""

    camera: CameraModel
    detector: Callable[[np.ndarray], Sequence[Detection]]
    config: PipelineConfig = field(default_factory=PipelineConfig)

    def __post_init__(self) -> None:
        if self.config.detect_every < 1 or self.config.full_frame_every < 1:
            raise ValueError(f"detect_every and full_frame_every must be >= 1, got {self.config.detect_every}, "
                             f"{self.config.full_frame_every}")
        self.projector = Projector(self.camera)
        self.smoother = AttitudeSmoother(self.config.attitude_alpha, self.config.attitude_beta)
        self.trackers = self._bank()
        self.range_filter = RangeFilter()
        self.frames = 0
        self.detector_frames = 0
        self.track: Track | None = None
        self.last_box_range_m = float("nan")
        self.detector_name = ""
        self.last_estimate: TargetEstimate | None = None
        self.focused_frames = 0
        self.cue_fit = CueFit(self.config.cue_fit_tau_s, self.config.cue_switch_sigma)
        self._seen_attitude: Rotation | None = None  # the measured attitude at the last frame processed
        # (time, where the detector looks; None: the whole frame) of detector frames planned, not processed yet.
        self._unseen_detections: list[tuple[float, Region | None]] = []

    def _bank(self) -> TrackerBank:
        self._bank_tuned = False
        return TrackerBank(self.config.tracker_kinds, max_misses=self.config.max_misses)

    def _tune_bank(self) -> None:
        """Give the trackers what the detector offers: its box refiner and, when its scores predict
        the box's IoU, the reseed threshold. Done after the detector's first call, so a detector
        that loads lazily (the simulator's shared one) has loaded."""
        refiner = getattr(self.detector, "refiner", None) if self.config.refine_tracks else None
        self.trackers.refine = None if refiner is None else refiner.boxes
        self.trackers.reseed_min_score = self.config.reseed_min_score if getattr(self.detector, "scores_are_iou", False) else 0.0
        self._bank_tuned = True

    def use_detector(self, detector: Callable[[np.ndarray], Sequence[Detection]], name: str = "",
                     classes: Sequence[str] | None = None, target_on_ground: bool | None = None) -> None:
        """Swap the detector (a mission picks its model: drones for the chase, people for search and
        rescue) and, when given, the accepted classes and the ground-target ranging; tracks restart."""
        changes: dict = {}
        if classes is not None:
            changes["classes"] = tuple(classes)
        if target_on_ground is not None:
            changes["target_on_ground"] = bool(target_on_ground)
        if changes:
            self.config = replace(self.config, **changes)
        self.detector = detector
        self.detector_name = name
        self.trackers = self._bank()
        self.track = None
        self.cue_fit.reset()
        self.last_estimate = None
        self.range_filter.reset()
        self.frames = 0
        self._unseen_detections.clear()

    def plan(self, t: float, ownship: OwnshipPose, cue: TargetCue | None = None) -> FramePlan:
        """Decide what the frame at ``t`` is for (:class:`FramePlan`); :meth:`process` then takes that frame.
        Call once per frame: it advances the attitude smoother."""
        cfg = self.config
        att = self.smoother.update(t, ownship.attitude)
        cam = self.camera.position_enu(ownship.position_enu, att)
        cue_enu = None if cue is None else cue.position_at(t)
        detect = self.frames % cfg.detect_every == 0
        if detect and cue is not None and self._followed() is None and self._cue_out_of_sight(ownship, att, cam, cue_enu, cue.covariance_enu):
            detect = False  # the gate would refuse whatever the detector found: the trackers carry on alone
        window, judge = self._focus(ownship, att, cam, cue_enu) if detect else (None, True)
        regions: tuple[Region, ...] | None = None
        if not detect or window is not None:
            regions = tuple(self._track_regions(ownship.attitude)) + (() if window is None else (window.region,))
        if regions is not None and self._unseen_detections:
            # A frame planned before an earlier detector frame is processed (a camera behind the tick)
            # reads where that detector looked too: a track it starts will be looked for here.
            unseen = [r for _, r in self._unseen_detections]
            regions = None if None in unseen else regions + tuple(r for r in unseen if r is not None)
        if detect:
            self._unseen_detections.append((t, None if window is None else window.region))
        return FramePlan(att, ownship.attitude, cam, cue_enu, detect, window, judge, regions)

    def process(self, frame: Frame, ownship: OwnshipPose, target_range_m: float | None = None,
                cue: TargetCue | None = None, plan: FramePlan | None = None) -> TargetEstimate | None:
        """One frame; ``target_range_m`` is the range from target telemetry when the mission uses it,
        ``cue`` a fresh cue of the target (radar or telemetry) to look at and gate tracks by, ``plan``
        the frame's :meth:`plan` when it was made before the frame was read (else it is made here)."""
        if plan is None:
            plan = self.plan(frame.t, ownship, cue)
        image = frame.image
        att, cam, cue_enu = plan.attitude, plan.camera_enu, plan.cue_enu
        # This frame, and any planned before it that never came, are no longer ahead.
        self._unseen_detections = [u for u in self._unseen_detections if u[0] > frame.t]
        region = None
        self._follow_the_turn(plan.measured)
        if plan.detect:
            if plan.window is None:
                dets = list(self.detector(image))
            else:
                self.focused_frames += 1
                window = plan.window
                region = window.region
                dets = [replace(d, box=window.to_frame(d.box)) for d in self._detect(window.crop(image), cue_enu is not None)]
            dets = [d for d in dets if not self.config.classes or d.class_name in self.config.classes]
            if not self._bank_tuned:
                self._tune_bank()
            tracks = self.trackers.correct(image, dets, frame.t, region, plan.judge)
            self.detector_frames += 1
        else:
            tracks = self.trackers.advance(image, frame.t)
        self.frames += 1
        self._seen_attitude = plan.measured
        # A track the cue agrees with needs no second hit: the cue is the independent confirmation.
        need = 1 if cue_enu is not None else self.config.confirm_hits
        tracks = [tr for tr in tracks if frame.t - tr.t_detected <= self.config.max_track_age_s and tr.hits >= need]
        if cue_enu is not None and tracks:
            tracks = self._gate(tracks, att, cam, cue_enu, cue.covariance_enu)
        if cue_enu is None:
            self.cue_fit.reset()
        elif tracks:
            bearings = self.projector.bearing_enu(np.array([tr.centre for tr in tracks]), att)
            self.cue_fit.update(frame.t, cam, {tr.track_id: b for tr, b in zip(tracks, bearings)}, cue_enu,
                                cue.covariance_enu)
        if not tracks:
            self.track = None
            self.range_filter.reset()
            return None
        track = self._select(tracks, att, frame.t)
        if self.track is None or track.track_id != self.track.track_id:
            self.range_filter.reset()
        self.track = track
        bearing = self.projector.bearing_enu(np.array([track.centre]), att)[0]
        self.range_filter.predict(frame.t, ownship.velocity_enu, bearing)
        fx = self.camera.focal_px[0]
        span = TARGET_SPAN_M.get(track.class_name)
        if target_range_m is None and self.config.target_on_ground:
            target_range_m = ground_range(cam, bearing)
        if target_range_m is not None:
            self.range_filter.update_known(frame.t, target_range_m)
        elif span is not None and track.t_detected == frame.t and (region is None or cue_enu is not None):
            # Box sizes come from whole-frame detections where there are any (no cue): seen zoomed,
            # the detector draws the box wider (1.16-1.35x the target at 2x against 1.15-1.22x on the
            # whole frame: benchmarks/bench_focus.py), which biases the range short. With a cue
            # every detection is zoomed, and those are all there is.
            self.last_box_range_m = range_from_box(track.box, span, 0.5 * self.camera.width_px, fx)
            self.range_filter.update_box(frame.t, track.box, span, 0.5 * self.camera.width_px, fx)
        fuse_age = self.config.cue_fusion_max_age_s
        if target_range_m is None and cue is not None and fuse_age > 0.0 and 0.0 <= frame.t - cue.t <= fuse_age:
            self._fuse_cue(frame.t, cue, cam, bearing)
        r, r_std = self.range_filter.range_m, self.range_filter.range_std_m
        if not math.isfinite(r):
            return None
        cross = (r * self.config.bearing_std_rad) ** 2
        cov = cross * (np.eye(3) - np.outer(bearing, bearing)) + r_std**2 * np.outer(bearing, bearing) + 1e-6 * np.eye(3)
        conf = track.score * 0.5 ** ((frame.t - track.t_detected) / self.config.confidence_half_life_s)
        self.last_estimate = TargetEstimate(t=frame.t, position_enu=cam + r * bearing, covariance_enu=cov, source="vision",
                                            track_id=track.track_id, bearing_enu=bearing, range_m=r, range_std_m=r_std,
                                            confidence=float(min(max(conf, 0.0), 1.0)))
        return self.last_estimate

    def _fuse_cue(self, t: float, cue: TargetCue, camera_enu: np.ndarray, bearing: np.ndarray) -> None:
        """The range filter takes a fresh cue's position along the bearing, and its velocity along it."""
        c = self.config
        along = float(np.dot(cue.position_at(t) - camera_enu, bearing))
        std = math.sqrt(float(bearing @ cue.covariance_enu @ bearing) + c.cue_range_floor_m**2)
        self.range_filter.fuse_range(along, std)
        if cue.velocity_enu is not None:
            self.range_filter.update_radial_speed(float(np.dot(cue.velocity_enu, bearing)), c.cue_speed_std_mps)

    def _focus(self, ownship: OwnshipPose, attitude: Rotation, camera_enu: np.ndarray,
               cue_enu: np.ndarray | None) -> tuple[FocusWindow | None, bool]:
        """Where the detector looks on a detector frame (None: the whole frame) and whether a track it
        did not see there counts against it: the focus window when there is one this frame, else the
        whole frame (judged only when there was nothing to focus on: the whole frame's coarser scale
        misses small targets the window sees). With a cue the window is always used: the gate
        would refuse whatever the whole frame found outside it."""
        cfg = self.config
        w, h = self.camera.width_px, self.camera.height_px
        centre = expected = None
        track = self._followed()
        if track is not None:
            x0, y0, x1, y1 = self._turned(np.array([track.box], float), ownship.attitude)[0]
            centre, expected = ((x0 + x1) / 2, (y0 + y1) / 2), max(track.size)
        elif cue_enu is not None:
            px, front = self.projector.pixel_of(cue_enu[None], ownship.position_enu, attitude)
            rng = float(np.linalg.norm(cue_enu - camera_enu))
            if front[0] and rng > 0.0:  # a cue just off the image is looked for at its edge
                centre = (min(max(float(px[0, 0]), 0.0), w - 1.0), min(max(float(px[0, 1]), 0.0), h - 1.0))
                expected = self._span_m() * self.camera.focal_px[0] / rng
        window = None
        if cfg.focus and centre is not None:
            window = focus_window(centre, expected, (w, h), cfg.detector_input_px, cfg.focus_box_px, 1.0, cfg.focus_max_zoom)
        if window is None or window.zoom < cfg.focus_min_zoom:
            return None, True
        if cue_enu is None and self.detector_frames % cfg.full_frame_every == 0:
            return None, False
        return window, True

    def _detect(self, image: np.ndarray, cued: bool) -> list:
        """The detector on ``image``, keeping boxes down to ``cue_min_score`` when ``cued``."""
        detect = getattr(self.detector, "detect", None)
        if cued and self.config.cue_min_score is not None and callable(detect):
            return list(detect(image, conf_threshold=self.config.cue_min_score))
        return list(self.detector(image))

    def _followed(self) -> Track | None:
        """The track followed, while the trackers still hold it."""
        return self.track if self.track is not None and any(tr is self.track for tr in self.trackers.tracks) else None

    def _gate_rad(self, cue_dist_m: float, cue_sigma_m: float) -> float:
        """The gate on a track's bearing from the cue's: ``cue_gate_deg`` plus three sigma of the cue's
        position error seen from ``cue_dist_m``."""
        return math.radians(self.config.cue_gate_deg) + math.atan2(3.0 * cue_sigma_m, cue_dist_m)

    def _cue_out_of_sight(self, ownship: OwnshipPose, attitude: Rotation, camera_enu: np.ndarray, cue_enu: np.ndarray,
                          cue_cov: np.ndarray) -> bool:
        """The cue lies further outside the image than the gate reaches: nothing in view can be the target."""
        dist = float(np.linalg.norm(cue_enu - camera_enu))
        gate = self._gate_rad(dist, _largest_sigma(cue_cov))
        return dist > 1e-6 and self.projector.angle_outside_rad(cue_enu, ownship.position_enu, attitude) > gate

    def _track_regions(self, attitude: Rotation) -> list[Region]:
        """The neighbourhoods the trackers (and the box refiner) read around each track's box, in a frame
        taken at ``attitude``: around the box as last seen and where the camera's turn since moves it."""
        w, h = self.camera.width_px, self.camera.height_px
        boxes = np.array([tr.box for tr in self.trackers.tracks], float).reshape(-1, 4)
        out = []
        for (x0, y0, x1, y1), (u0, v0, u1, v1) in zip(boxes, self._turned(boxes, attitude)):
            m = max(self.config.track_margin_px, x1 - x0, y1 - y0)
            out.append((max(int(min(x0, u0) - m), 0), max(int(min(y0, v0) - m), 0),
                        min(int(math.ceil(max(x1, u1) + m)), w), min(int(math.ceil(max(y1, v1) + m)), h)))
        return [r for r in out if r[2] > r[0] and r[3] > r[1]]

    def _turned(self, boxes: np.ndarray, attitude: Rotation) -> np.ndarray:
        """(N, 4) boxes of the last frame processed, moved to where they are seen at ``attitude``: each
        box's centre keeps its bearing, so the camera's rotation since that frame moves it on the image
        (a target's own motion and the camera's travel are left to the margins). Unchanged before any
        frame, and for a centre the turn puts behind the camera."""
        if self._seen_attitude is None or not len(boxes):
            return boxes
        centres = np.stack([(boxes[:, 0] + boxes[:, 2]) / 2, (boxes[:, 1] + boxes[:, 3]) / 2], axis=1)
        bearings = self.projector.bearing_enu(centres, self._seen_attitude)
        px, front = self.projector.pixel_of(1e4 * bearings, np.zeros(3), attitude)  # 10 km out: rotation only
        shift = np.where(front[:, None] & np.isfinite(px), px - centres, 0.0)
        return boxes + np.hstack([shift, shift])

    def _follow_the_turn(self, attitude: Rotation) -> None:
        """Move every track's box to where the camera's turn since the last frame puts it
        (:meth:`_turned`), before detections are matched to the boxes: in gusts the image swings by
        more than a small target's size from one frame to the next, and an unmoved box would miss its
        own target's detection (the track is pruned, a new one starts and the range restarts)."""
        tracks = self.trackers.tracks
        if not tracks:
            return
        for track, box in zip(tracks, self._turned(np.array([tr.box for tr in tracks], float), attitude)):
            track.box = tuple(float(v) for v in box)

    def _span_m(self) -> float:
        """The width expected of the target: the largest known width of the accepted classes (1 m if none is known)."""
        spans = [TARGET_SPAN_M[c] for c in (self.config.classes or tuple(TARGET_SPAN_M)) if c in TARGET_SPAN_M]
        return max(spans) if spans else 1.0

    def _gate(self, tracks: list[Track], attitude: Rotation, camera_enu: np.ndarray, cue_enu: np.ndarray,
              cue_cov: np.ndarray) -> list[Track]:
        """The tracks whose bearing is within the gate of the cue's bearing from the camera and whose
        box-size range (for a class of known size) agrees with the cue's distance within
        ``cue_range_ratio``."""
        to_cue = cue_enu - camera_enu
        dist = float(np.linalg.norm(to_cue))
        if dist <= 1e-6:
            return tracks
        sigma = _largest_sigma(cue_cov)
        gate = self._gate_rad(dist, sigma)
        bearings = self.projector.bearing_enu(np.array([tr.centre for tr in tracks]), attitude)
        cos = np.clip(bearings @ (to_cue / dist), -1.0, 1.0)
        k = self.config.cue_range_ratio
        near, far = max(dist - 3.0 * sigma, 0.0) / k, (dist + 3.0 * sigma) * k
        cx, fx = 0.5 * self.camera.width_px, self.camera.focal_px[0]
        kept = []
        for tr, c in zip(tracks, cos):
            if math.acos(float(c)) > gate:
                continue
            span = TARGET_SPAN_M.get(tr.class_name)
            if span is not None and not near <= range_from_box(tr.box, span, cx, fx) <= far:
                continue
            kept.append(tr)
        return kept

    def _select(self, tracks: list[Track], attitude: Rotation, t: float) -> Track:
        """The current track while it lives, unless it drifted off the cue and another track fits the cue
        clearly better (:class:`~chaser_bt.vision.cue_fit.CueFit`); else, shortly after an estimate, the
        track nearest its bearing (the target does not jump across the image); else the most confirmed,
        then confident."""
        if self.track is not None:
            same = next((tr for tr in tracks if tr.track_id == self.track.track_id), None)
            if same is not None:
                other = self.cue_fit.better_than(same.track_id, [tr.track_id for tr in tracks])
                if other is None:
                    return same
                log.info("vision: track %d drifted off the cue (%.1f sigma); following track %d (%.1f sigma) at %.1f s",
                         same.track_id, self.cue_fit.offset(same.track_id), other, self.cue_fit.offset(other), t)
                return next(tr for tr in tracks if tr.track_id == other)
        last = self.last_estimate
        if last is not None and last.bearing_enu is not None and t - last.t <= self.config.reacquire_s and len(tracks) > 1:
            bearings = self.projector.bearing_enu(np.array([tr.centre for tr in tracks]), attitude)
            return tracks[int(np.argmax(bearings @ last.bearing_enu))]
        return max(tracks, key=lambda tr: (min(tr.hits, 3), tr.score))


def _largest_sigma(cov: np.ndarray) -> float:
    """The standard deviation along a covariance's worst axis."""
    return math.sqrt(max(float(np.max(np.linalg.eigvalsh(cov))), 0.0))


def ground_range(camera_enu: np.ndarray, bearing_enu: np.ndarray, min_down: float = 0.02) -> float | None:
    """Range from the camera along the unit ``bearing_enu`` to flat ground at z = 0, or None when the
    bearing does not point down by more than ``min_down`` (at or above the horizon)."""
    down = -float(bearing_enu[2])
    if down <= min_down or camera_enu[2] <= 0.0:
        return None
    return float(camera_enu[2]) / down


@dataclass
class CameraSensor:
    """A frame source and the pipeline that reads it: what the VisionPipeline behaviour ticks.

    A source that reads out regions of interest (the simulator's camera) is asked for only the parts
    the pipeline will look at (:attr:`FramePlan.regions`), unless ``whole_frames`` is set: a consumer
    that shows or stores the frames (the ground video stream, the flight recorder) sets it in its setup.
    """

    source: FrameSource
    pipeline: VisionPipeline
    whole_frames: bool = False
    last_frame: Frame | None = field(default=None, init=False)  # the frame last processed (for streaming and logs)
    #: Ticks between a frame's shot and the tick that processes it (a log's replay does the same).
    lag_frames: ClassVar[int] = 0

    def step(self, t: float, ownship: OwnshipPose, target_range_m: float | None = None,
             cue: TargetCue | None = None) -> TargetEstimate | None:
        """Read the frame for ``t`` and process it; None when there is no frame or no target."""
        plan = None
        if not self.whole_frames and reads_regions(self.source):
            plan = self.pipeline.plan(t, ownship, cue)
            frame = self.source.read(t, regions=plan.regions)
        else:
            frame = self.source.read(t)
        if frame is None:
            return None
        self.last_frame = frame
        return self.pipeline.process(frame, ownship, target_range_m, cue, plan)
