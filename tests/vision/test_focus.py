"""The detector's focus window, and the pipeline looking through it and gating by a cue."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from chaser_bt.cue import TargetCue
from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detection import Detection
from chaser_bt.vision.focus import FocusWindow, focus_window
from chaser_bt.vision.frame_source import Frame
from chaser_bt.vision.pipeline import OwnshipPose, PipelineConfig, VisionPipeline
from chaser_bt.vision.projection import Projector


def test_window_zooms_the_expected_box_to_box_px_and_stays_in_the_frame():
    w = focus_window((320.0, 240.0), 16.0, (640, 480), input_px=416, box_px=32.0, max_zoom=3.0)
    assert w == FocusWindow(216, 136, 208, 2.0)
    # A big target is not shrunk: zoom 1, a 416 px window.
    assert focus_window((320.0, 240.0), 100.0, (640, 480)) == FocusWindow(112, 32, 416, 1.0)
    # A tiny one is zoomed at most max_zoom (side 416 / 3 = 138.67 -> 139 px, zoom 416 / 139).
    w = focus_window((320.0, 240.0), 2.0, (640, 480), max_zoom=3.0)
    assert (w.side_px, w.zoom) == (139, pytest.approx(416 / 139))
    # At a corner the window shifts inside rather than being cut.
    assert focus_window((5.0, 470.0), 16.0, (640, 480)) == FocusWindow(0, 272, 208, 2.0)
    assert focus_window((-1.0, 10.0), 16.0, (640, 480)) is None
    assert focus_window((10.0, float("nan")), 16.0, (640, 480)) is None
    with pytest.raises(ValueError, match="min_zoom"):
        focus_window((-1.0, 10.0), 16.0, (640, 480), min_zoom=2.0, max_zoom=1.0)  # refused even off the frame


@settings(max_examples=200, deadline=None)
@given(cx=st.floats(0, 639.99), cy=st.floats(0, 479.99), size=st.floats(0.5, 300), max_zoom=st.floats(1, 4))
def test_window_properties(cx, cy, size, max_zoom):
    w = focus_window((cx, cy), size, (640, 480), input_px=416, box_px=32.0, max_zoom=max_zoom)
    assert 0 <= w.x0 and w.x0 + w.side_px <= 640 and 0 <= w.y0 and w.y0 + w.side_px <= 480
    assert round(w.side_px * w.zoom) == 416
    assert 1.0 - 1e-9 <= w.zoom <= max_zoom * 1.01
    assert w.x0 <= cx <= w.x0 + w.side_px and w.y0 <= cy <= w.y0 + w.side_px
    assert w.to_frame((0.0, 0.0, 416.0, 416.0)) == pytest.approx((w.x0, w.y0, w.x0 + w.side_px, w.y0 + w.side_px))


class _BlobDetector:
    """Boxes the dark pixels of the image it is given (a real detector, for test images), and
    remembers the size of every image it saw."""

    def __init__(self):
        self.shapes: list[tuple[int, ...]] = []

    def __call__(self, image):
        self.shapes.append(image.shape)
        ys, xs = np.nonzero(image[..., 0] < 64)
        if not len(xs):
            return []
        return [Detection((float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1)), 0.9, 0, "s1000")]


def _frame(k: int, square=(400, 200, 6)) -> Frame:
    img = np.full((480, 640, 3), 128, np.uint8)
    x, y, s = square
    img[y:y + s, x:x + s] = 0
    return Frame(0.1 * k, img, k)


CAM = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
POSE = OwnshipPose(0.0, np.array([0.0, 0.0, 30.0]), np.zeros(3), Rotation.identity())


def test_crop_and_back_recover_the_box_at_any_zoom():
    det = _BlobDetector()
    frame = _frame(0)
    for size in (6.0, 12.0, 40.0):
        w = focus_window((403.0, 203.0), size, (640, 480))
        (d,) = det(w.crop(frame.image))
        assert w.to_frame(d.box) == pytest.approx((400, 200, 406, 206), abs=1.0 / w.zoom + 1e-9)


def test_the_pipeline_looks_at_its_track_through_a_zoomed_window():
    det = _BlobDetector()
    pipe = VisionPipeline(CAM, det, PipelineConfig(detect_every=1, tracker_kinds=(), full_frame_every=3, focus_max_zoom=3.0))
    ests = [pipe.process(_frame(k), POSE) for k in range(4)]
    # Frames 0 and 1 see the whole frame (nothing followed yet; the track confirms at frame 1),
    # frame 2 the zoomed window on the track, frame 3 the whole frame again (every 3rd).
    assert det.shapes == [(480, 640, 3), (480, 640, 3), (320, 320, 3), (480, 640, 3)]
    assert pipe.focused_frames == 1
    truth = Projector(CAM).bearing_enu(np.array([[403.0, 203.0]]), Rotation.identity())[0]
    for est in ests[1:]:
        assert math.degrees(math.acos(min(1.0, float(est.bearing_enu @ truth)))) < 0.1
    # Focus off: always the whole frame.
    det2 = _BlobDetector()
    pipe2 = VisionPipeline(CAM, det2, PipelineConfig(detect_every=1, tracker_kinds=(), focus=False))
    [pipe2.process(_frame(k), POSE) for k in range(4)]
    assert set(det2.shapes) == {(480, 640, 3)}


def _cue_at(pixel, range_m, sigma_m=1.0):
    proj = Projector(CAM)
    p = proj.point_enu(np.array([pixel]), np.array([range_m]), POSE.position_enu, Rotation.identity())[0]
    return TargetCue(t=0.0, position_enu=p, covariance_enu=sigma_m**2 * np.eye(3), source="telemetry")


def test_before_a_track_the_window_is_on_the_cue_sized_by_its_range():
    det = _BlobDetector()
    pipe = VisionPipeline(CAM, det, PipelineConfig(detect_every=1, tracker_kinds=(), full_frame_every=3))
    cue = _cue_at((403.0, 203.0), 140.0)
    ests = [pipe.process(_frame(k), POSE, cue=cue) for k in range(4)]
    # With a cue every detector frame looks through the window (the gate would refuse what the
    # whole frame found outside it): first on the cue, then on the track.
    assert det.shapes == [(320, 320, 3)] * 4 and pipe.focused_frames == 4
    assert all(e is not None for e in ests)  # one hit the cue agrees with is enough: no second hit needed
    # A cue behind the camera: nothing in view could pass its gate, so the detector does not run; so
    # uncertain that its gate reaches into the view (4 deg + atan(3 * 200 / 50) = 89 deg, the view's
    # nearest edge plane 47.5 deg away): no window, the whole frame.
    for sigma_m, shapes in ((1.0, []), (200.0, [(480, 640, 3)])):
        behind = TargetCue(t=0.0, position_enu=np.array([-50.0, 0.0, 30.0]), covariance_enu=sigma_m**2 * np.eye(3), source="telemetry")
        det2 = _BlobDetector()
        est = VisionPipeline(CAM, det2, PipelineConfig(detect_every=1, tracker_kinds=())).process(_frame(0), POSE, cue=behind)
        assert det2.shapes == shapes and est is None


def test_a_cue_just_off_the_image_is_looked_for_at_its_edge_and_one_far_off_not_at_all():
    # The square sits against the top edge; the cue is 20 px above the image on its column, 140 m out
    # (2 deg outside the top edge's plane, inside the 4 deg gate): the window is pushed down into the image.
    det = _BlobDetector()
    pipe = VisionPipeline(CAM, det, PipelineConfig(detect_every=1, tracker_kinds=()))
    est = pipe.process(_frame(0, square=(400, 0, 6)), POSE, cue=_cue_at((403.0, -20.0), 140.0))
    assert det.shapes == [(320, 320, 3)] and pipe.focused_frames == 1 and est is not None
    # 200 px above the image (17 deg outside it): beyond the gate, the detector is not run.
    det = _BlobDetector()
    pipe = VisionPipeline(CAM, det, PipelineConfig(detect_every=1, tracker_kinds=()))
    assert pipe.process(_frame(0, square=(400, 0, 6)), POSE, cue=_cue_at((403.0, -200.0), 140.0)) is None
    assert det.shapes == []


def test_without_a_cue_a_track_needs_confirm_hits_but_with_one_a_single_hit_in_its_gate():
    near = _cue_at((406.0, 200.0), 60.0)
    for cue, first in ((None, 1), (near, 0)):
        pipe = VisionPipeline(CAM, _BlobDetector(), PipelineConfig(detect_every=1, tracker_kinds=(), confirm_hits=2))
        ests = [pipe.process(_frame(k), POSE, cue=cue) for k in range(3)]
        assert min(k for k, e in enumerate(ests) if e is not None) == first


def test_tracks_far_from_the_cue_are_not_the_target():
    far = _cue_at((100.0, 400.0), 60.0)    # 59 deg from the dark square (gate: 4 deg + atan(3 / 60))
    near = _cue_at((406.0, 200.0), 60.0)   # a few pixels off
    for cue, seen in ((far, False), (near, True), (None, True)):
        pipe = VisionPipeline(CAM, _BlobDetector(), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False))
        ests = [pipe.process(_frame(k), POSE, cue=cue) for k in range(3)]
        assert (ests[-1] is not None) is seen
    # A cue uncertain by 40 m at 60 m widens the gate to 4 deg + atan(120 / 60) = 67 deg.
    loose = _cue_at((100.0, 400.0), 60.0, sigma_m=40.0)
    pipe = VisionPipeline(CAM, _BlobDetector(), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False))
    assert [pipe.process(_frame(k), POSE, cue=loose) for k in range(3)][-1] is not None


def test_a_track_whose_box_range_disagrees_with_the_cue_s_distance_is_not_the_target():
    # The 6 px square read as an S1000 (1.42 m across): its box-size range, worked out by hand.
    fx = 320.0 / math.tan(math.radians(47.5))
    box_range = 1.42 / (math.atan((406 - 320) / fx) - math.atan((400 - 320) / fx))
    assert 60.0 < box_range < 80.0
    # Cues on the square's bearing (1 m sigma) at several distances: the gate keeps ratios up to 5.
    for cue_range, seen in ((box_range, True), (4.0 * box_range, True), (0.3 * box_range, True),
                            (6.0 * box_range, False), (0.1 * box_range, False)):
        pipe = VisionPipeline(CAM, _BlobDetector(), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False))
        ests = [pipe.process(_frame(k), POSE, cue=_cue_at((403.0, 203.0), cue_range)) for k in range(3)]
        assert (ests[-1] is not None) is seen, cue_range
    # A cue far uncertain widens it: 6x the range but 300 m sigma.
    pipe = VisionPipeline(CAM, _BlobDetector(), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False))
    cue = _cue_at((403.0, 203.0), 6.0 * box_range, sigma_m=300.0)
    assert [pipe.process(_frame(k), POSE, cue=cue) for k in range(3)][-1] is not None
