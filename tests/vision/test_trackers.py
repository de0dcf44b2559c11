"""OpenCV trackers seeded and pruned by detections (paper section 3.1)."""

from __future__ import annotations

import numpy as np
import pytest

from chaser_bt.vision.detector.inference import Detection
from chaser_bt.vision.trackers import TRACKER_KINDS, TrackerBank


def _scene(x: int, y: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    img = (rng.random((240, 320, 3)) * 60 + 100).astype(np.uint8)
    patch = np.zeros((20, 20, 3), np.uint8)
    patch[5:15, 5:15] = 255
    patch[8:12, :] = 30
    img[y:y + 20, x:x + 20] = patch
    return img


def _det(x, y) -> Detection:
    return Detection((x, y, x + 20.0, y + 20.0), 0.9, 0, "s1000")


@pytest.mark.parametrize("kind", sorted(TRACKER_KINDS))
def test_tracker_follows_a_moving_target_between_detections(kind):
    bank = TrackerBank([kind])
    bank.correct(_scene(100, 100), [_det(100, 100)], 0.0)
    for k in range(1, 6):
        tracks = bank.advance(_scene(100 + 2 * k, 100 + k), 0.1 * k)
    assert len(tracks) == 1
    cx, cy = tracks[0].centre
    tol = 8 if kind == "mil" else 3  # MIL's boosting search steps coarsely on this small synthetic patch
    assert abs(cx - 120) <= tol and abs(cy - 115) <= tol


def test_a_track_no_detection_agrees_with_is_pruned_and_a_new_detection_starts_a_track():
    bank = TrackerBank(["kcf"])
    bank.correct(_scene(100, 100), [_det(100, 100)], 0.0)
    first = bank.tracks[0].track_id
    tracks = bank.correct(_scene(100, 100), [_det(250, 30)], 0.3)  # the detector now sees only another place
    assert [t.track_id for t in tracks] != [first] and len(tracks) == 1
    assert bank.pruned == 1
    assert tracks[0].box == (250.0, 30.0, 270.0, 50.0)


def test_agreeing_detection_reseeds_the_track_and_keeps_its_id():
    bank = TrackerBank(["kcf"])
    bank.correct(_scene(100, 100), [_det(100, 100)], 0.0)
    tid = bank.tracks[0].track_id
    bank.correct(_scene(104, 102), [_det(104, 102)], 0.1)
    assert bank.tracks[0].track_id == tid and bank.tracks[0].hits == 2
    assert bank.tracks[0].box == (104.0, 102.0, 124.0, 122.0)


def test_unknown_tracker_kind_is_refused():
    with pytest.raises(ValueError, match="available"):
        TrackerBank(["goturn"])
