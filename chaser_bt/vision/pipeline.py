"""Frames -> detections -> tracks -> target estimate (paper section 3.1).

The detector runs on every ``detect_every``-th frame; the trackers carry the boxes on the frames in
between (paper: detector 8-10 frames/s, estimates above 30). The chosen track's box centre becomes an
ENU bearing through the smoothed attitude (:mod:`chaser_bt.vision.projection`), its width a range
(:mod:`chaser_bt.vision.range`) unless the mission gives the target's telemetry or the target is on
flat ground (a person in search and rescue: range to where the bearing meets z = 0), and the two a
:class:`~chaser_bt.cue.TargetEstimate` with a covariance that is tight across the bearing and loose
along it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.cue import TargetEstimate
from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detection import Detection
from chaser_bt.vision.frame_source import Frame, FrameSource
from chaser_bt.vision.projection import AttitudeSmoother, Projector
from chaser_bt.vision.range import TARGET_SPAN_M, RangeFilter, range_from_box
from chaser_bt.vision.trackers import Track, TrackerBank

__all__ = ["OwnshipPose", "PipelineConfig", "VisionPipeline", "CameraSensor", "ground_range"]


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
        confirm_hits: detector hits before a track is reported (1: the first detection).
        max_misses: detector frames in a row a confirmed track coasts on its trackers without a detection.
        reacquire_s: for this long after the last estimate, a new track is picked by its bearing's
            closeness to that estimate's (else by hits, then score).
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
    reacquire_s: float = 2.0


@dataclass
class VisionPipeline:
    """Stateful per-camera pipeline; :meth:`process` takes one frame and the ownship pose."""

    camera: CameraModel
    detector: Callable[[np.ndarray], Sequence[Detection]]
    config: PipelineConfig = field(default_factory=PipelineConfig)

    def __post_init__(self) -> None:
        if self.config.detect_every < 1:
            raise ValueError(f"detect_every must be >= 1, got {self.config.detect_every}")
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

    def _bank(self) -> TrackerBank:
        return TrackerBank(self.config.tracker_kinds, max_misses=self.config.max_misses)

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
        self.last_estimate = None
        self.range_filter.reset()
        self.frames = 0

    def process(self, frame: Frame, ownship: OwnshipPose, target_range_m: float | None = None) -> TargetEstimate | None:
        """One frame; ``target_range_m`` is the range from target telemetry when the mission uses it."""
        image = frame.image
        if self.frames % self.config.detect_every == 0:
            dets = [d for d in self.detector(image) if not self.config.classes or d.class_name in self.config.classes]
            tracks = self.trackers.correct(image, dets, frame.t)
            self.detector_frames += 1
        else:
            tracks = self.trackers.advance(image, frame.t)
        self.frames += 1
        att = self.smoother.update(frame.t, ownship.attitude)
        tracks = [tr for tr in tracks if frame.t - tr.t_detected <= self.config.max_track_age_s and tr.hits >= self.config.confirm_hits]
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
        cam = self.camera.position_enu(ownship.position_enu, att)
        if target_range_m is None and self.config.target_on_ground:
            target_range_m = ground_range(cam, bearing)
        if target_range_m is not None:
            self.range_filter.update_known(frame.t, target_range_m)
        elif span is not None and track.t_detected == frame.t:  # box sizes come from detections only
            self.last_box_range_m = range_from_box(track.box, span, 0.5 * self.camera.width_px, fx)
            self.range_filter.update_box(frame.t, track.box, span, 0.5 * self.camera.width_px, fx)
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

    def _select(self, tracks: list[Track], attitude: Rotation, t: float) -> Track:
        """The current track while it lives; else, shortly after an estimate, the track nearest its
        bearing (the target does not jump across the image); else the most confirmed, then confident."""
        if self.track is not None:
            same = next((tr for tr in tracks if tr.track_id == self.track.track_id), None)
            if same is not None:
                return same
        last = self.last_estimate
        if last is not None and last.bearing_enu is not None and t - last.t <= self.config.reacquire_s and len(tracks) > 1:
            bearings = self.projector.bearing_enu(np.array([tr.centre for tr in tracks]), attitude)
            return tracks[int(np.argmax(bearings @ last.bearing_enu))]
        return max(tracks, key=lambda tr: (min(tr.hits, 3), tr.score))


def ground_range(camera_enu: np.ndarray, bearing_enu: np.ndarray, min_down: float = 0.02) -> float | None:
    """Range from the camera along the unit ``bearing_enu`` to flat ground at z = 0, or None when the
    bearing does not point down by more than ``min_down`` (at or above the horizon)."""
    down = -float(bearing_enu[2])
    if down <= min_down or camera_enu[2] <= 0.0:
        return None
    return float(camera_enu[2]) / down


@dataclass
class CameraSensor:
    """A frame source and the pipeline that reads it: what the VisionPipeline behaviour ticks."""

    source: FrameSource
    pipeline: VisionPipeline
    last_frame: Frame | None = field(default=None, init=False)  # the frame last processed (for streaming and logs)

    def step(self, t: float, ownship: OwnshipPose, target_range_m: float | None = None) -> TargetEstimate | None:
        """Read the frame for ``t`` and process it; None when there is no frame or no target."""
        frame = self.source.read(t)
        if frame is None:
            return None
        self.last_frame = frame
        return self.pipeline.process(frame, ownship, target_range_m)
