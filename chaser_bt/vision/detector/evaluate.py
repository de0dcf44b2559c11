"""Detector metrics as in the paper's model card: 11-point interpolated AP at IoU 0.5 (PASCAL VOC 2007),
average IoU of the true positives, and precision / recall / F1 at 0.25 confidence; plus frames/s.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

__all__ = ["DetectionMetrics", "iou_matrix", "ap11", "evaluate_detections", "frames_per_second"]


@dataclass(frozen=True)
class DetectionMetrics:
    ap50: float            # mean over classes with ground truth of the 11-point AP@0.5
    ap50_per_class: dict
    iou: float             # mean IoU of the true positives at ``conf``
    precision: float
    recall: float
    f1: float
    conf: float


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, M) IoU of boxes (N, 4) and (M, 4), x0 y0 x1 y1."""
    a = np.asarray(a, float).reshape(-1, 4)
    b = np.asarray(b, float).reshape(-1, 4)
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(rb - lt, 0, None), axis=2)
    area_a = np.prod(a[:, 2:] - a[:, :2], axis=1)
    area_b = np.prod(b[:, 2:] - b[:, :2], axis=1)
    return inter / np.maximum(area_a[:, None] + area_b[None, :] - inter, 1e-12)


def ap11(recall: np.ndarray, precision: np.ndarray) -> float:
    """11-point interpolated AP: mean over r in {0, 0.1, ..., 1} of the best precision at recall >= r."""
    total = 0.0
    for r in np.linspace(0.0, 1.0, 11):
        p = precision[recall >= r]
        total += float(p.max()) if len(p) else 0.0
    return total / 11.0


def _match(preds: list, gts: np.ndarray, iou_thr: float):
    """Greedy VOC matching of one image's predictions (box, score, cls), best score first: (is_tp, iou)."""
    used = np.zeros(len(gts), bool)
    out = []
    for box, score, cls in sorted(preds, key=lambda p: -p[1]):
        cand = np.where((gts[:, 0] == cls) & ~used)[0] if len(gts) else np.zeros(0, int)
        if len(cand):
            ious = iou_matrix(np.asarray(box)[None], gts[cand, 1:5])[0]
            j = int(np.argmax(ious))
            if ious[j] >= iou_thr:
                used[cand[j]] = True
                out.append((score, cls, True, float(ious[j])))
                continue
        out.append((score, cls, False, 0.0))
    return out


def evaluate_detections(predictions: Sequence[list], ground_truth: Sequence[np.ndarray], num_classes: int,
                        conf: float = 0.25, iou_thr: float = 0.5) -> DetectionMetrics:
    """Metrics over images; ``predictions[i]`` is a list of (box, score, class), ``ground_truth[i]`` (N, 5) rows."""
    records = []
    for preds, gts in zip(predictions, ground_truth):
        records.extend(_match(list(preds), np.asarray(gts, float).reshape(-1, 5), iou_thr))
    n_gt = np.zeros(num_classes, int)
    for g in ground_truth:
        for c in np.asarray(g).reshape(-1, 5)[:, 0].astype(int):
            n_gt[c] += 1
    aps = {}
    for c in range(num_classes):
        if n_gt[c] == 0:
            continue
        rc = sorted([r for r in records if r[1] == c], key=lambda r: -r[0])
        tp = np.cumsum([r[2] for r in rc]) if rc else np.zeros(0)
        fp = np.cumsum([not r[2] for r in rc]) if rc else np.zeros(0)
        rec = tp / n_gt[c] if len(rc) else np.zeros(0)
        prec = tp / np.maximum(tp + fp, 1) if len(rc) else np.zeros(0)
        aps[c] = ap11(rec, prec)
    sel = [r for r in records if r[0] >= conf]
    tp = sum(r[2] for r in sel)
    fp = len(sel) - tp
    total = int(n_gt.sum())
    p = tp / max(tp + fp, 1)
    r = tp / max(total, 1)
    f1 = 2 * p * r / max(p + r, 1e-12)
    ious = [r[3] for r in sel if r[2]]
    return DetectionMetrics(float(np.mean(list(aps.values()))) if aps else 0.0, aps, float(np.mean(ious)) if ious else 0.0, p, r, f1, conf)


def frames_per_second(fn: Callable[[np.ndarray], object], frames: Sequence[np.ndarray], warmup: int = 3, clock=time.perf_counter) -> float:
    """Frames per second of ``fn`` over ``frames`` after ``warmup`` calls (a benchmark, not an algorithm: it reads the clock)."""
    for f in frames[:warmup]:
        fn(f)
    t0 = clock()
    for f in frames:
        fn(f)
    return len(frames) / max(clock() - t0, 1e-9)
