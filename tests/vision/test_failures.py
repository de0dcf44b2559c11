"""A detector's failures: false boxes and misses found by hand-checked overlaps, and drawn as a picture."""

from __future__ import annotations

import cv2
import numpy as np

from chaser_bt.vision.detector.failures import failure_sheet, find_failures


def test_false_boxes_and_misses_at_the_operating_confidence():
    gts = [np.array([[0, 10, 10, 30, 30], [0, 100, 100, 110, 120]], float), np.zeros((0, 5))]
    preds = [
        # (11, 11, 31, 31) overlaps the first label 19 x 19 = 361 px of a 400 + 400 - 361 = 439 px union: IoU
        # 0.82, a hit. (60, 60, 70, 70) overlaps nothing: false. The 0.1 box is below the confidence and
        # counts for nothing, though it sits on the second label: that label is missed.
        [((11, 11, 31, 31), 0.9, 0), ((60, 60, 70, 70), 0.4, 1), ((100, 100, 110, 120), 0.1, 0)],
        [((5, 5, 15, 15), 0.3, 0)],  # a frame without labels: every box kept is false
    ]
    found = find_failures(preds, gts, conf=0.25)
    summary = sorted((kind, round(v, 2), k, tuple(np.round(b, 1))) for kind, v, k, b in found)
    assert summary == [("false", 0.3, 1, (5.0, 5.0, 15.0, 15.0)), ("false", 0.4, 0, (60.0, 60.0, 70.0, 70.0)),
                       ("missed", 10.0, 0, (100.0, 100.0, 110.0, 120.0))]


def test_the_sheet_has_a_tile_a_failure_in_rows_of_eight(tmp_path):
    paths = []
    for k in range(2):
        paths.append(tmp_path / f"f{k}.jpg")
        cv2.imwrite(str(paths[-1]), np.full((120, 160, 3), 90, np.uint8))
    failures = [("false", 0.5, 0, np.array([10, 10, 20, 20.0]))] * 5 + [("missed", 12.0, 1, np.array([50, 50, 62, 70.0]))] * 6
    sheet = failure_sheet(failures, paths, per_kind=4, tile=32)
    assert sheet.shape == (32, 8 * 32, 3)  # 4 false + 4 missed
    assert failure_sheet([], paths, tile=32).shape == (32, 8 * 32, 3)
