"""A detector's failures on a labelled set, as a picture: the highest-scoring false boxes and the missed
labels at the operating confidence, each cropped from its frame (``chaser-bt eval-detector --failures``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from chaser_bt.vision.detector.evaluate import iou_matrix

__all__ = ["find_failures", "failure_sheet"]

Failure = tuple[str, float, int, np.ndarray]  # kind ("false" or "missed"), score or width, image index, box


def find_failures(preds: Sequence[list], gts: Sequence[np.ndarray], conf: float = 0.25, iou: float = 0.5) -> list[Failure]:
    """Per image, the boxes scored >= ``conf`` that overlap no label by ``iou`` ("false", with their score)
    and the labels no such box overlaps by ``iou`` ("missed", with their width); classes are ignored."""
    out: list[Failure] = []
    for k, (pred, gt) in enumerate(zip(preds, gts)):
        kept = [(np.asarray(b, float), s) for b, s, _ in pred if s >= conf]
        boxes = np.array([b for b, _ in kept]).reshape(-1, 4)
        labels = np.asarray(gt, float).reshape(-1, 5)[:, 1:5]
        overlap = iou_matrix(boxes, labels) if len(boxes) and len(labels) else np.zeros((len(boxes), len(labels)))
        for (b, s), row in zip(kept, overlap):
            if not len(labels) or row.max() < iou:
                out.append(("false", float(s), k, b))
        for j, g in enumerate(labels):
            if not len(boxes) or overlap[:, j].max() < iou:
                out.append(("missed", float(g[2] - g[0]), k, g))
    return out


def failure_sheet(failures: Sequence[Failure], paths: Sequence[str | Path], per_kind: int = 16, tile: int = 96,
                  columns: int = 8) -> np.ndarray:
    """A BGR picture: up to ``per_kind`` of the highest-scoring false boxes (first rows, red) and of the
    missed labels (then, green, largest first), each a square crop twice its box's size around it."""
    chosen = sorted((f for f in failures if f[0] == "false"), key=lambda f: -f[1])[:per_kind]
    chosen += sorted((f for f in failures if f[0] == "missed"), key=lambda f: -f[1])[:per_kind]
    tiles = []
    for kind, value, k, box in chosen:
        img = cv2.imread(str(paths[k]), cv2.IMREAD_COLOR)
        x0, y0, x1, y1 = box
        half = max(x1 - x0, y1 - y0, 24.0)
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        scale = tile / (2 * half)
        warp = np.array([[scale, 0, tile / 2 - cx * scale], [0, scale, tile / 2 - cy * scale]])
        crop = cv2.warpAffine(img, warp, (tile, tile), borderMode=cv2.BORDER_CONSTANT)
        colour = (0, 0, 255) if kind == "false" else (0, 200, 0)
        bx = np.round(warp @ np.array([[x0, x1], [y0, y1], [1, 1]])).astype(int)
        cv2.rectangle(crop, tuple(bx[:, 0]), tuple(bx[:, 1]), colour, 1)
        text = f"false {value:.2f}" if kind == "false" else f"missed {value:.0f}px"
        cv2.putText(crop, text, (2, 11), cv2.FONT_HERSHEY_SIMPLEX, 0.35, colour, 1)
        cv2.putText(crop, Path(paths[k]).stem[-18:], (2, tile - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.28, (255, 255, 255), 1)
        tiles.append(crop)
    if not tiles:
        return np.zeros((tile, tile * columns, 3), np.uint8)
    tiles += [np.zeros_like(tiles[0])] * (-len(tiles) % columns)
    return np.vstack([np.hstack(tiles[r:r + columns]) for r in range(0, len(tiles), columns)])
