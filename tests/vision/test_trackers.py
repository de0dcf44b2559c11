"""OpenCV trackers seeded and pruned by detections (paper section 3.1)."""

from __future__ import annotations

import cv2
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
    cv2.setRNGSeed(0)  # MIL samples with OpenCV's global RNG: what ran before in the process must not move it
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # ... and the RNG is per thread: OpenCV's worker threads would each draw from their own
    try:
        bank = TrackerBank([kind])
        bank.correct(_scene(100, 100), [_det(100, 100)], 0.0)
        for k in range(1, 6):
            tracks = bank.advance(_scene(100 + 2 * k, 100 + k), 0.1 * k)
    finally:
        cv2.setNumThreads(threads)
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


def _confirmed(bank: TrackerBank, x=100, y=100) -> int:
    bank.correct(_scene(x, y), [_det(x, y)], 0.0)
    bank.correct(_scene(x, y), [_det(x, y)], 0.1)
    assert bank.tracks[0].hits == 2
    return bank.tracks[0].track_id


def test_a_confirmed_track_coasts_through_max_misses_detector_frames_then_is_pruned():
    bank = TrackerBank(["mosse"], max_misses=2)
    tid = _confirmed(bank)
    for k in (1, 2):
        tracks = bank.correct(_scene(100, 100), [], 0.1 + 0.1 * k)
        assert [t.track_id for t in tracks] == [tid] and tracks[0].misses == k
        assert tracks[0].t_detected == 0.1  # coasting is not a detection
    assert bank.correct(_scene(100, 100), [], 0.4) == [] and bank.pruned == 1
    # A match resets the count.
    tid = _confirmed(bank)
    bank.correct(_scene(100, 100), [], 0.2)
    bank.correct(_scene(100, 100), [_det(101, 100)], 0.3)
    assert bank.tracks[0].track_id == tid and bank.tracks[0].misses == 0


def test_an_unconfirmed_or_contradicted_track_does_not_coast():
    bank = TrackerBank(["mosse"], max_misses=2)
    bank.correct(_scene(100, 100), [_det(100, 100)], 0.0)
    assert bank.correct(_scene(100, 100), [], 0.1) == []  # one hit only
    tid = _confirmed(bank)
    sure = Detection((250.0, 30.0, 270.0, 50.0), 0.95, 0, "s1000")  # surer than the track's 0.9, elsewhere
    assert [t.track_id for t in bank.correct(_scene(100, 100), [sure], 0.2)] != [tid]
    tid = _confirmed(bank)
    weak = Detection((250.0, 30.0, 270.0, 50.0), 0.4, 0, "s1000")
    ids = [t.track_id for t in bank.correct(_scene(100, 100), [weak], 0.2)]
    assert tid in ids and len(ids) == 2  # the weak one starts its own track, the confirmed one coasts


def test_an_oversized_detection_around_a_track_neither_reseeds_it_nor_starts_a_track():
    bank = TrackerBank(["mosse"], max_misses=2)
    tid = _confirmed(bank)
    big = Detection((70.0, 75.0, 160.0, 150.0), 0.5, 0, "s1000")  # the target and its surroundings: 4.1x the width
    tracks = bank.correct(_scene(100, 100), [big], 0.2)
    assert [t.track_id for t in tracks] == [tid] and tracks[0].misses == 1
    assert tracks[0].size == (20.0, 20.0) and tracks[0].t_detected == 0.1
    # Without coasting (the paper's rule) the same detection replaces the track.
    bank0 = TrackerBank(["mosse"])
    tid0 = _confirmed(bank0)
    assert [t.track_id for t in bank0.correct(_scene(100, 100), [big], 0.2)] not in ([], [tid0])


def test_a_small_box_that_moved_its_own_width_still_agrees_but_one_further_does_not():
    def small(x):
        return Detection((x, 100.0, x + 6.0, 106.0), 0.9, 0, "s1000")

    bank = TrackerBank([])
    (first,) = bank.correct(_scene(0, 0), [small(100.0)], 0.0)
    (track,) = bank.correct(_scene(0, 0), [small(106.0)], 0.1)   # no overlap, centre 6 px = one box width away
    assert track.track_id == first.track_id and track.hits == 2
    tracks = bank.correct(_scene(0, 0), [small(113.0)], 0.2)     # 7 px: a different object
    assert [tr.track_id for tr in tracks] != [first.track_id]


def test_only_tracks_the_detector_could_see_are_pruned():
    bank = TrackerBank([])
    bank.correct(_scene(0, 0), [_det(100, 100), _det(250, 200)], 0.0)
    # A focus window over the first track: the second, outside it, is carried though nothing saw it.
    tracks = bank.correct(_scene(0, 0), [_det(101, 100)], 0.1, region=(50.0, 50.0, 180.0, 180.0))
    assert sorted(tr.box[0] for tr in tracks) == [101.0, 250.0]
    # The whole frame at a coarse scale (judge=False) prunes nothing; judged, the unseen track goes.
    assert len(bank.correct(_scene(0, 0), [], 0.2, judge=False)) == 2
    assert bank.correct(_scene(0, 0), [], 0.3) == []


def test_a_low_scoring_detection_confirms_a_followed_track_without_moving_it():
    """With reseed_min_score, a detection scoring less (an IoU-scoring detector's badly placed box)
    counts as a hit but the track keeps the box its trackers follow; a confident one reseeds it."""
    bank = TrackerBank(["kcf"], reseed_min_score=0.5)
    _confirmed(bank)
    hits = bank.tracks[0].hits
    off = Detection((104.0, 97.0, 128.0, 121.0), 0.3, 0, "s1000")  # overlaps the target, misplaced
    (track,) = bank.correct(_scene(100, 100), [off], 1.0)
    assert track.hits == hits + 1 and track.t_detected == 1.0
    assert track.centre == pytest.approx((110.0, 110.0), abs=1.0)  # the trackers' box, not the detection's (116, 109)
    (track,) = bank.correct(_scene(100, 100), [Detection(off.box, 0.9, 0, "s1000")], 2.0)
    assert track.box == off.box


def test_tracked_boxes_go_through_the_refine_hook_between_detections():
    seen = []

    def refine(frame, boxes):
        seen.append(np.asarray(boxes, float))
        return np.asarray(boxes, float) + [1.0, 0.0, 1.0, 0.0]  # one pixel right

    bank = TrackerBank(["kcf"], refine=refine)
    bank.correct(_scene(100, 100), [_det(100, 100)], 0.0)
    (track,) = bank.advance(_scene(102, 100), 0.1)
    assert len(seen) == 1 and seen[0][0] == pytest.approx([102, 100, 122, 120], abs=3.0)
    assert track.box == pytest.approx(tuple(seen[0][0] + [1.0, 0.0, 1.0, 0.0]))


def test_trackers_start_only_when_needed_and_move_the_box_as_trackers_started_at_the_seed_would():
    import cv2

    bank = TrackerBank(["mosse", "medianflow"])
    first = _scene(100, 100)
    bank.correct(first, [_det(100, 100)], 0.0)
    bank.correct(_scene(102, 101), [_det(102, 101)], 0.1)  # reseeded before any tracker moved the box
    (track,) = bank.tracks
    assert track.trackers == [] and track.seed is not None  # nothing started yet
    seed_frame = _scene(102, 101)
    # The same trackers started at once on the seed and moved by hand: the bank must agree with them.
    ref = [cv2.legacy.TrackerMOSSE_create(), cv2.legacy.TrackerMedianFlow_create()]
    for tr in ref:
        tr.init(seed_frame, (96, 95, 32, 32))  # the 32-px window (min_window_px) around the 20-px box
    later = _scene(106, 103)
    (moved,) = bank.advance(later, 0.2)
    centres = [(x + w / 2, y + h / 2) for ok, (x, y, w, h) in (tr.update(later) for tr in ref) if ok]
    cx, cy = np.mean(centres, axis=0)
    assert moved.centre == pytest.approx((cx, cy), abs=1e-6)
    assert len(moved.trackers) == 2 and moved.seed is None
