"""Frames -> detections -> tracks -> TargetEstimate, on a rendered follow sequence and with fakes."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detector.inference import Detection, Detector
from chaser_bt.vision.frame_source import Frame, VideoCaptureSource
from chaser_bt.vision.pipeline import (
    CameraSensor,
    OwnshipPose,
    PipelineConfig,
    VisionPipeline,
)
from chaser_bt.vision.projection import Projector
from sitl.bench.camera_sequences import follow_sequence

CAM = CameraModel(width_px=640, height_px=480)


def test_pipeline_on_a_rendered_follow_sequence_keeps_the_target_with_small_bearing_error():
    views = list(follow_sequence(CAM, 45, seed=11))
    pipe = VisionPipeline(CAM, Detector(), PipelineConfig(detect_every=3))
    proj = Projector(CAM)
    errs, ranges = [], []
    for k, v in enumerate(views):
        est = pipe.process(Frame(v.t, v.image, k), OwnshipPose(v.t, v.position_enu, v.velocity_enu, v.attitude_measured))
        if est is None or v.label is None:
            continue
        lb = v.label.box
        truth = proj.bearing_enu(np.array([[(lb[0] + lb[2]) / 2, (lb[1] + lb[3]) / 2]]), v.attitude_true)[0]
        errs.append(math.degrees(math.acos(min(1.0, float(est.bearing_enu @ truth)))))
        true_range = np.linalg.norm(v.target_enu - CAM.position_enu(v.position_enu, v.attitude_true))
        ranges.append(abs(est.range_m - true_range) / true_range)
        assert est.source == "vision" and 0 <= est.confidence <= 1
    assert len(errs) >= 40
    assert np.percentile(errs, 95) < 1.5
    assert np.median(ranges) < 0.3
    assert pipe.detector_frames == 15


class _Fixed:
    """A detector that always reports one box."""

    def __init__(self, box):
        self.box = box

    def __call__(self, image):
        return [Detection(self.box, 0.8, 0, "s1000")] if self.box else []


def test_estimate_lies_along_the_bearing_with_covariance_long_on_the_line_of_sight():
    cam = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
    fx = cam.focal_px[0]
    width = 1.42 * fx / 20.0  # an S1000 20 m away, box centred
    pipe = VisionPipeline(cam, _Fixed((160 - width / 2, 110, 160 + width / 2, 130)), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False, confirm_hits=1))
    from scipy.spatial.transform import Rotation

    pose = OwnshipPose(0.0, np.array([0.0, 0.0, 10.0]), np.zeros(3), Rotation.identity())
    est = pipe.process(Frame(0.0, np.zeros((240, 320, 3), np.uint8), 0), pose)
    assert est.range_m == pytest.approx(20.0, rel=1e-3)
    assert est.bearing_enu == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)
    assert est.position_enu == pytest.approx([20.0, 0.0, 10.0], rel=1e-3)
    w, v = np.linalg.eigh(est.covariance_enu)
    assert abs(v[:, -1] @ est.bearing_enu) == pytest.approx(1.0)  # largest uncertainty along the line of sight
    # Telemetry range overrides the box.
    est2 = VisionPipeline(cam, _Fixed((150, 110, 170, 130)), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False, confirm_hits=1)).process(
        Frame(0.0, np.zeros((240, 320, 3), np.uint8), 0), pose, target_range_m=33.0)
    assert est2.range_m == pytest.approx(33.0)


def test_no_detection_means_no_estimate_and_tracks_expire():
    pipe = VisionPipeline(CAM, _Fixed(None), PipelineConfig(detect_every=1))
    from scipy.spatial.transform import Rotation

    pose = OwnshipPose(0.0, np.zeros(3), np.zeros(3), Rotation.identity())
    assert pipe.process(Frame(0.0, np.zeros((480, 640, 3), np.uint8), 0), pose) is None


def test_a_camera_frame_that_cannot_be_one_is_dropped_and_counted(tmp_path):
    import cv2

    path = str(tmp_path / "clip.avi")
    writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    writer.write(np.zeros((48, 64, 3), np.uint8))
    writer.release()
    src = VideoCaptureSource(path)
    glitches = iter([np.zeros((48, 64), np.uint8), np.zeros((48, 64, 3), np.float32), np.zeros((0, 64, 3), np.uint8),
                     np.zeros((48, 64, 3), np.uint8), np.zeros((96, 128, 3), np.uint8)])
    src.capture = type("Glitchy", (), {"read": lambda self: (True, next(glitches)), "release": lambda self: None})()
    frames = [src.read(0.1 * k) for k in range(5)]
    assert [f is not None for f in frames] == [False, False, False, True, False]
    assert src.dropped == {"not_bgr8": 2, "empty": 1, "size_changed": 1}


def test_video_file_source_reads_frames_and_camera_sensor_runs_the_pipeline(tmp_path):
    import cv2

    path = str(tmp_path / "clip.avi")
    writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    for k in range(3):
        writer.write(np.full((48, 64, 3), 40 * k, np.uint8))
    writer.release()
    src = VideoCaptureSource(path, size=(32, 24))
    frames = [src.read(0.1 * k) for k in range(4)]
    assert [f.image.shape for f in frames[:3]] == [(24, 32, 3)] * 3 and frames[3] is None
    assert [f.index for f in frames[:3]] == [0, 1, 2]
    with pytest.raises(ValueError, match="cannot open"):
        VideoCaptureSource(str(tmp_path / "missing.avi"))
    src2 = VideoCaptureSource(path)
    sensor = CameraSensor(src2, VisionPipeline(CameraModel(width_px=64, height_px=48), _Fixed(None)))
    from scipy.spatial.transform import Rotation

    assert sensor.step(0.0, OwnshipPose(0.0, np.zeros(3), np.zeros(3), Rotation.identity())) is None


class _Script:
    """A detector that reports, at its n-th call, the n-th list of (box, score)."""

    def __init__(self, script):
        self.script = script
        self.n = 0

    def __call__(self, image):
        out = [Detection(b, s, 0, "s1000") for b, s in self.script[min(self.n, len(self.script) - 1)]]
        self.n += 1
        return out


def _run(pipe, n):
    from scipy.spatial.transform import Rotation

    pose = lambda t: OwnshipPose(t, np.array([0.0, 0.0, 10.0]), np.zeros(3), Rotation.identity())
    return [pipe.process(Frame(0.1 * k, np.zeros((240, 320, 3), np.uint8), k), pose(0.1 * k)) for k in range(n)]


def test_a_track_is_reported_after_confirm_hits_detections():
    cam = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
    box = [((150.0, 110.0, 170.0, 130.0), 0.8)]
    one = _run(VisionPipeline(cam, _Script([box]), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False)), 3)
    assert one[0] is None and one[1] is not None and one[2] is not None
    three = _run(VisionPipeline(cam, _Script([box]), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False, confirm_hits=3)), 3)
    assert [e is None for e in three] == [True, True, False]
    flicker = _run(VisionPipeline(cam, _Script([box, [], box, []]), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False)), 4)
    assert all(e is None for e in flicker)  # never two hits in a row: a one-frame false positive is never reported


def test_after_losing_the_target_the_track_nearest_its_last_bearing_is_picked():
    cam = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
    centre = ((150.0, 110.0, 170.0, 130.0), 0.8)
    near = ((180.0, 112.0, 200.0, 132.0), 0.5)  # 30 px right: no overlap with the lost track
    far = ((20.0, 20.0, 40.0, 40.0), 0.9)       # surer, but across the image
    script = [[centre], [centre], [near, far], [near, far]]
    cfg = PipelineConfig(detect_every=1, tracker_kinds=(), focus=False)
    est = _run(VisionPipeline(cam, _Script(script), cfg), 4)
    proj = Projector(cam)
    from scipy.spatial.transform import Rotation

    assert est[1] is not None and est[2] is None  # the centre track is gone, the new ones are not confirmed yet
    assert est[3].bearing_enu == pytest.approx(proj.bearing_enu(np.array([[190.0, 122.0]]), Rotation.identity())[0], abs=1e-9)
    # With no recent estimate to go by, the surer track wins.
    est = _run(VisionPipeline(cam, _Script(script), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False, reacquire_s=0.0)), 4)
    assert est[3].bearing_enu == pytest.approx(proj.bearing_enu(np.array([[30.0, 30.0]]), Rotation.identity())[0], abs=1e-9)


def test_the_trackers_get_the_detectors_refiner_and_its_reseed_rule_only_if_its_scores_are_ious():
    class _Refiner:
        def boxes(self, image, boxes):
            return np.asarray(boxes, float)

    cam = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
    for iou_scores, reseed in ((True, 0.5), (False, 0.0)):
        det = _Script([[((150.0, 110.0, 170.0, 130.0), 0.8)]])
        det.refiner, det.scores_are_iou = _Refiner(), iou_scores
        pipe = VisionPipeline(cam, det, PipelineConfig(detect_every=1, focus=False))
        _run(pipe, 1)
        assert pipe.trackers.reseed_min_score == reseed
        assert pipe.trackers.refine.__self__ is det.refiner
    plain = VisionPipeline(cam, _Script([[]]), PipelineConfig(detect_every=1, focus=False))  # a detector offering neither
    _run(plain, 1)
    assert plain.trackers.refine is None and plain.trackers.reseed_min_score == 0.0
    off = VisionPipeline(cam, det, PipelineConfig(detect_every=1, focus=False, refine_tracks=False))
    _run(off, 1)
    assert off.trackers.refine is None


# -- planning a frame before it is read (regions of interest) ----------------------------------------


class _RegionSource:
    """A source that reads out regions: records what it was asked for, returns a blank frame."""

    reads_regions = True

    def __init__(self, w: int = 640, h: int = 480) -> None:
        self.asked: list = []
        self.shape = (h, w, 3)

    def read(self, t, regions=None):
        self.asked.append(regions)
        return Frame(t, np.zeros(self.shape, np.uint8), len(self.asked) - 1, None if regions is None else tuple(regions))

    def close(self) -> None:
        pass


def test_the_plan_asks_for_the_focus_window_then_the_tracks_neighbourhood():
    from scipy.spatial.transform import Rotation

    from chaser_bt.cue import TargetCue

    cam = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
    # The detector sees the 2x focus window; its box (crop pixels) maps back to (300, 230, 316, 246) in the frame.
    script = _Script([[((120.0, 140.0, 152.0, 172.0), 0.9)]])
    pipe = VisionPipeline(cam, script, PipelineConfig(detect_every=2, tracker_kinds=()))
    source = _RegionSource()
    sensor = CameraSensor(source, pipe)
    pose = lambda t: OwnshipPose(t, np.array([0.0, 0.0, 10.0]), np.zeros(3), Rotation.identity())
    cue = TargetCue(0.0, np.array([100.0, 0.0, 10.0]), 4.0 * np.eye(3))  # dead ahead, 100 m: a few pixels wide
    est = sensor.step(0.0, pose(0.0), cue=cue)
    # Detector frame: the window at zoom 2 (320 / 2 = 160 px) centred on the cue's pixel (320, 240).
    assert source.asked[0] == ((240, 160, 400, 320),)
    assert est is not None and pipe.track.box == pytest.approx((300.0, 230.0, 316.0, 246.0))
    sensor.step(0.1, pose(0.1), cue=cue)
    # Tracker frame: only the track's neighbourhood, its box and 64 px around it.
    assert source.asked[1] == ((236, 166, 380, 310),)
    sensor.whole_frames = True  # a ground video stream or a recorder is watching
    sensor.step(0.2, pose(0.2), cue=cue)
    assert source.asked[2] is None


def test_a_turn_of_the_camera_moves_the_tracks_neighbourhood_with_it():
    from scipy.spatial.transform import Rotation

    from chaser_bt.cue import TargetCue

    cam = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
    script = _Script([[((120.0, 140.0, 152.0, 172.0), 0.9)]])  # the frame's box (300, 230, 316, 246), as above
    pipe = VisionPipeline(cam, script, PipelineConfig(detect_every=2, tracker_kinds=(), attitude_alpha=1.0, attitude_beta=0.0))
    source = _RegionSource()
    sensor = CameraSensor(source, pipe)
    cue = TargetCue(0.0, np.array([100.0, 0.0, 10.0]), 4.0 * np.eye(3))
    sensor.step(0.0, OwnshipPose(0.0, np.array([0.0, 0.0, 10.0]), np.zeros(3), Rotation.identity()), cue=cue)
    # The aircraft yaws 5 deg left (ENU z up): a target that holds still slides right on the image by
    # fx * tan(5 deg) at the image centre; the box's centre is 12 px left of it and 2 px up, so its
    # ray's turn moves it by fx * (tan(atan(-12 / fx) + 5 deg) + 12 / fx), and a pixel or less up (off
    # the axis, the ray's depth along it shrinks).
    turned = Rotation.from_euler("z", math.radians(5.0))
    sensor.step(0.1, OwnshipPose(0.1, np.array([0.0, 0.0, 10.0]), np.zeros(3), turned), cue=cue)
    fx = cam.focal_px[0]
    dx = fx * (math.tan(math.atan(-12.0 / fx) + math.radians(5.0)) + 12.0 / fx)
    x0, y0, x1, y1 = source.asked[1][0]
    # The neighbourhood holds the box as last seen and as turned, 64 px around both.
    assert x0 == 236 and y0 in (165, 166)
    assert x1 == math.ceil(316.0 + dx + 64.0) and x1 > 380 + 20
    assert y1 == 310


def test_a_frame_planned_before_a_detector_frame_is_processed_reads_where_that_detector_looked():
    from scipy.spatial.transform import Rotation

    cam = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
    pipe = VisionPipeline(cam, _Script([[((300.0, 230.0, 316.0, 246.0), 0.9)]]),
                          PipelineConfig(detect_every=3, tracker_kinds=(), focus=False))
    pose = lambda t: OwnshipPose(t, np.array([0.0, 0.0, 10.0]), np.zeros(3), Rotation.identity())
    image = np.zeros((480, 640, 3), np.uint8)

    # A camera one frame behind the tick: frame k is planned, then frame k - 1 processed.
    p0 = pipe.plan(0.0, pose(0.0))
    p1 = pipe.plan(0.1, pose(0.1))  # a detector frame, whole: nothing tracked yet
    assert p1.detect and p1.regions is None
    pipe.process(Frame(0.0, image, 0), pose(0.0), plan=p0)  # frame 0's detection starts a track
    # Frame 2 is planned before frame 1 is processed: a track frame 1's detector finds may be anywhere
    # it looked, so frame 2 reads all of that (the whole frame), not only frame 0's track's neighbourhood.
    p2 = pipe.plan(0.2, pose(0.2))
    assert not p2.detect and p2.regions is None
    pipe.process(Frame(0.1, image, 1), pose(0.1), plan=p1)
    # Planned with no detector frame pending: the track's neighbourhood only (its box and 64 px around it).
    p3 = pipe.plan(0.3, pose(0.3))
    assert not p3.detect and p3.regions == ((236, 166, 380, 310),)


def test_without_a_cue_or_a_track_the_detector_frame_is_read_whole():
    from scipy.spatial.transform import Rotation

    pipe = VisionPipeline(CAM, _Fixed(None), PipelineConfig(detect_every=1))
    plan = pipe.plan(0.0, OwnshipPose(0.0, np.zeros(3), np.zeros(3), Rotation.identity()))
    assert plan.detect and plan.window is None and plan.regions is None


def test_a_plan_made_before_the_frame_changes_nothing_of_what_the_pipeline_reports():
    from scipy.spatial.transform import Rotation

    cam = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
    box = [((150.0, 110.0, 170.0, 130.0), 0.8)]
    cfg = PipelineConfig(detect_every=2, tracker_kinds=(), focus=False)
    a = VisionPipeline(cam, _Script([box, [], box]), cfg)
    b = VisionPipeline(cam, _Script([box, [], box]), cfg)
    pose = lambda t: OwnshipPose(t, np.array([0.0, 0.0, 10.0]), np.zeros(3), Rotation.from_euler("z", 0.02 * t))
    for k in range(6):
        frame = Frame(0.1 * k, np.zeros((240, 320, 3), np.uint8), k)
        ea = a.process(frame, pose(frame.t))
        eb = b.process(frame, pose(frame.t), plan=b.plan(frame.t, pose(frame.t)))
        assert (ea is None) == (eb is None)
        if ea is not None:
            np.testing.assert_array_equal(ea.position_enu, eb.position_enu)


def test_a_source_that_cannot_read_regions_is_asked_for_whole_frames():
    from scipy.spatial.transform import Rotation

    class Plain:
        def __init__(self):
            self.calls = 0

        def read(self, t):  # no regions= keyword: a real camera
            self.calls += 1
            return Frame(t, np.zeros((480, 640, 3), np.uint8), self.calls)

        def close(self):
            pass

    src = Plain()
    CameraSensor(src, VisionPipeline(CAM, _Fixed(None))).step(0.0, OwnshipPose(0.0, np.zeros(3), np.zeros(3), Rotation.identity()))
    assert src.calls == 1


def test_a_gust_that_swings_the_image_by_more_than_the_box_keeps_the_track():
    from scipy.spatial.transform import Rotation

    cam = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
    fx = cam.focal_px[0]
    # A target 8 px wide, 40 px right of the centre, still; the aircraft yaws 5 deg right between two
    # frames (a gust), so the target slides left by fx * (tan(atan(40 / fx) + 5 deg) - 40 / fx), ~27 px:
    # three box widths.
    x = 320.0 + 40.0
    shift = fx * (math.tan(math.atan(40.0 / fx) + math.radians(5.0)) - 40.0 / fx)
    assert shift > 3 * 8.0
    script = _Script([[((x - 4, 236.0, x + 4, 244.0), 0.9)], [((x - shift - 4, 236.0, x - shift + 4, 244.0), 0.9)]])
    # The default attitude smoothing: a lagging attitude would move the box only part of the way.
    pipe = VisionPipeline(cam, script, PipelineConfig(detect_every=1, tracker_kinds=(), focus=False))
    level = OwnshipPose(0.0, np.array([0.0, 0.0, 10.0]), np.zeros(3), Rotation.identity())
    swung = OwnshipPose(0.1, np.array([0.0, 0.0, 10.0]), np.zeros(3), Rotation.from_euler("z", math.radians(-5.0)))
    # No cue: a track is reported from its second hit, so only the same track carried across the swing
    # gives an estimate at the second frame.
    assert pipe.process(Frame(0.0, np.zeros((480, 640, 3), np.uint8), 0), level) is None
    second = pipe.process(Frame(0.1, np.zeros((480, 640, 3), np.uint8), 1), swung)
    assert second is not None and pipe.track.hits == 2 and second.track_id == 1
    # The estimate's bearing is the still target's, whatever the image did (within the smoothing's lag).
    first_bearing = Projector(cam).bearing_enu(np.array([[x, 240.0]]), Rotation.identity())[0]
    assert math.degrees(math.acos(min(1.0, float(first_bearing @ second.bearing_enu)))) < 3.0


def _dash_range_errors(config: PipelineConfig) -> np.ndarray:
    """An S1000 dead ahead of a still camera dashes at it at 8 m/s from 40 m, from t = 1 s; its exact box
    each frame at 10 Hz and a radar cue on it with its velocity. The estimate's range error per frame."""
    from scipy.spatial.transform import Rotation

    from chaser_bt.cue import TargetCue

    cam = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
    fx, span = cam.focal_px[0], 1.42
    ahead = Projector(cam).bearing_enu(np.array([[320.0, 240.0]]), Rotation.identity())[0]
    at = np.array([0.0, 0.0, 10.0])
    dist = lambda t: 40.0 - 8.0 * max(0.0, t - 1.0)
    half = lambda t: fx * span / (2.0 * dist(t))  # half the box width: span / (2 tan(theta / 2)) inverted
    times = [0.1 * k for k in range(35)]
    pipe = VisionPipeline(cam, _Script([[((320 - half(t), 236.0, 320 + half(t), 244.0), 0.9)] for t in times]),
                          config)
    errors = []
    for k, t in enumerate(times):
        cue = TargetCue(t, at + dist(t) * ahead, 4.0 * np.eye(3), (-8.0 if t >= 1.0 else 0.0) * ahead, "radar", 7)
        est = pipe.process(Frame(t, np.zeros((480, 640, 3), np.uint8), k),
                           OwnshipPose(t, at, np.zeros(3), Rotation.identity()), cue=cue)
        errors.append(est.range_m - dist(t))
    return np.array(errors)


def test_the_radar_cues_velocity_keeps_the_range_of_a_target_dashing_at_the_camera():
    """Box sizes alone learn the dash late, so the range reads long while the target closes (the follow
    would back off too late); the cue's velocity along the bearing takes the lag out."""
    base = PipelineConfig(detect_every=1, tracker_kinds=(), focus=False)
    boxes = _dash_range_errors(replace(base, cue_fusion_max_age_s=0.0))[15:]
    both = _dash_range_errors(base)[15:]
    assert boxes.mean() > 1.0
    assert abs(both.mean()) < 0.5 * boxes.mean()


def test_a_radar_cue_corrects_the_range_of_a_distant_target_whose_box_is_drawn_too_wide():
    """150 m away an S1000 is a few pixels wide, and the detector's box half as wide again reads it
    100 m away; the radar's report (6 m error) seen along the bearing brings the estimate back."""
    from scipy.spatial.transform import Rotation

    from chaser_bt.cue import TargetCue

    cam = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
    ahead = Projector(cam).bearing_enu(np.array([[320.0, 240.0]]), Rotation.identity())[0]
    half = 1.5 * cam.focal_px[0] * 1.42 / (2.0 * 150.0)
    at = np.array([0.0, 0.0, 10.0])

    def last_range(config: PipelineConfig) -> float:
        pipe = VisionPipeline(cam, _Script([[((320 - half, 238.0, 320 + half, 242.0), 0.9)]]), config)
        for k in range(40):
            t = 0.1 * k
            cue = TargetCue(t, at + 150.0 * ahead, 36.0 * np.eye(3), np.zeros(3), "radar", 7)
            est = pipe.process(Frame(t, np.zeros((480, 640, 3), np.uint8), k),
                               OwnshipPose(t, at, np.zeros(3), Rotation.identity()), cue=cue)
        return est.range_m

    base = PipelineConfig(detect_every=1, tracker_kinds=(), focus=False)
    assert last_range(replace(base, cue_fusion_max_age_s=0.0)) == pytest.approx(100.0, rel=0.05)
    assert last_range(base) == pytest.approx(150.0, rel=0.1)


class _Thresholded(_Script):
    """A scripted detector that keeps only boxes scoring at least its threshold, 0.25 unless the call
    gives one, and says which threshold each call used."""

    def __init__(self, script):
        super().__init__(script)
        self.used: list[float] = []

    def __call__(self, image):
        return self.detect(image)

    def detect(self, image, conf_threshold=None):
        threshold = 0.25 if conf_threshold is None else conf_threshold
        self.used.append(threshold)
        return [d for d in super().__call__(image) if d.score >= threshold]


def test_with_a_cue_the_focus_window_keeps_boxes_down_to_the_cue_min_score():
    from scipy.spatial.transform import Rotation

    from chaser_bt.cue import TargetCue

    cam = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
    pose = OwnshipPose(0.0, np.array([0.0, 0.0, 10.0]), np.zeros(3), Rotation.identity())
    cue = TargetCue(0.0, np.array([100.0, 0.0, 10.0]), 4.0 * np.eye(3))  # dead ahead, 100 m: a focus window
    faint = [[((120.0, 140.0, 152.0, 172.0), 0.2)]]  # a far target's box, scoring 0.2
    for config, cued, found, used in [(PipelineConfig(tracker_kinds=()), cue, True, [0.15]),
                                      (PipelineConfig(tracker_kinds=(), cue_min_score=None), cue, False, [0.25]),
                                      (PipelineConfig(tracker_kinds=()), None, False, [0.25])]:
        det = _Thresholded(faint)
        est = VisionPipeline(cam, det, config).process(Frame(0.0, np.zeros((480, 640, 3), np.uint8), 0), pose, cue=cued)
        assert (est is not None) == found and det.used == used
    # A detector without a per-call threshold (a plain callable) is called as it is.
    est = VisionPipeline(cam, _Script(faint), PipelineConfig(tracker_kinds=())).process(
        Frame(0.0, np.zeros((480, 640, 3), np.uint8), 0), pose, cue=cue)
    assert est is not None
