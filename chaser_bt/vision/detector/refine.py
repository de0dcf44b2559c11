"""Second-stage box refinement: a detection's box re-placed from a full-resolution crop around it.

The detector sees a 640 x 480 frame shrunk to 416 and places boxes on a stride-8 grid, so a box's
centre is off by a pixel or two, more over clutter (a road under the target). As in two-stage
detectors (R-CNN's box head), a small network looks again at a square crop of the frame around each
detection (``context`` times its larger side, resized to ``input_px``) and regresses the target's
box in crop coordinates. It is trained on rendered frames with the labels jittered the way the
detector errs (:func:`make_refiner_set`, :func:`train_refiner`) and ships beside the detector whose
classes it knows, as ``<detector>_refiner.pt`` (:func:`refiner_path`).
"""

from __future__ import annotations

import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

import cv2
import numpy as np
import torch
from torch import nn

from chaser_bt.vision.detection import Detection
from chaser_bt.vision.detector.model import conv_bn_act

__all__ = ["RefinerConfig", "BoxRefinerNet", "BoxRefiner", "refiner_path", "crop_window", "jitter_boxes", "make_refiner_set", "train_refiner"]


def refiner_path(detector_weights: str | Path) -> Path:
    """Where the refiner paired with ``detector_weights`` lives: beside it, named ``<stem>_refiner.pt``."""
    p = Path(detector_weights)
    return p.with_name(f"{p.stem}_refiner.pt")


@dataclass(frozen=True)
class RefinerConfig:
    """Crop geometry and network width."""

    input_px: int = 64
    context: float = 1.6
    min_side_px: float = 24.0
    widths: tuple[int, ...] = (16, 32, 64, 64)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "RefinerConfig":
        return cls(int(d["input_px"]), float(d["context"]), float(d["min_side_px"]), tuple(d["widths"]))


class BoxRefinerNet(nn.Module):
    """(B, 3, P, P) crops in [0, 1] and (B, 4) the boxes they were cut around -> (B, 4) refined boxes;
    boxes are x0, y0, x1, y1 as fractions of the crop side, and the network predicts the correction."""

    def __init__(self, config: RefinerConfig = RefinerConfig()) -> None:
        super().__init__()
        self.config = config
        layers, cin = [], 3
        for w in config.widths:
            layers += [conv_bn_act(cin, w, 3, 2), conv_bn_act(w, w, 3, 1)]
            cin = w
        self.features = nn.Sequential(*layers)
        cells = (config.input_px // 2 ** len(config.widths)) ** 2
        self.head = nn.Sequential(nn.Flatten(), nn.Linear(cin * cells, 128), nn.LeakyReLU(0.1, inplace=True), nn.Linear(128, 4))

    def forward(self, x: torch.Tensor, boxes: torch.Tensor) -> torch.Tensor:
        return boxes + self.head(self.features(x))


def crop_window(box: Sequence[float], config: RefinerConfig) -> tuple[float, float, float]:
    """(x0, y0, side) of the square crop around ``box``: ``context`` times its larger side, at least ``min_side_px``."""
    cx, cy = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
    side = max(config.context * max(box[2] - box[0], box[3] - box[1]), config.min_side_px)
    return cx - side / 2, cy - side / 2, side


def _crops(image: np.ndarray, windows: Sequence[tuple[float, float, float]], px: int) -> np.ndarray:
    """(N, px, px, 3) crops of ``image`` (outside the frame: border replicated), by affine warps."""
    out = np.empty((len(windows), px, px, 3), np.uint8)
    for k, (x0, y0, side) in enumerate(windows):
        s = px / side
        m = np.array([[s, 0.0, -x0 * s], [0.0, s, -y0 * s]])
        out[k] = cv2.warpAffine(image, m, (px, px), flags=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out


def _fractions(boxes: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """(N, 4) frame-pixel boxes as fractions of their (N, 3) x0, y0, side crop windows."""
    return (boxes - windows[:, [0, 1, 0, 1]]) / windows[:, [2, 2, 2, 2]]


def _to_tensor(crops: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(crops[..., ::-1])).permute(0, 3, 1, 2).float().div_(255.0)


class BoxRefiner:
    """Detections in, the same detections with refined boxes out.

    Args:
        weights: a file written by :func:`train_refiner`.
        max_shift: a refined box whose centre moved more than this many of the old box's sizes is
            not trusted and the old box kept (the crop held something else).
    """

    def __init__(self, weights: str | Path, max_shift: float = 0.5) -> None:
        p = Path(weights)
        if not p.exists():
            raise FileNotFoundError(f"box refiner weights not found: {p}")
        blob = torch.load(p, map_location="cpu", weights_only=False)
        self.config = RefinerConfig.from_dict(blob["config"])
        self.net = BoxRefinerNet(self.config)
        self.net.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in blob["state_dict"].items()})
        self.net.eval()
        self.max_shift = max_shift

    def boxes(self, image: np.ndarray, boxes: Sequence[Sequence[float]]) -> np.ndarray:
        """(N, 4) refined boxes (frame pixels) for ``boxes``."""
        if len(boxes) == 0:
            return np.zeros((0, 4))
        old = np.asarray(boxes, float)
        windows = [crop_window(b, self.config) for b in old]
        w = np.array(windows, float)
        given = torch.from_numpy(_fractions(old, w).astype(np.float32))
        with torch.inference_mode():
            frac = self.net(_to_tensor(_crops(image, windows, self.config.input_px)), given).numpy()
        out = w[:, [0, 1, 0, 1]] + frac * w[:, [2, 2, 2, 2]]
        size = np.maximum(old[:, 2:] - old[:, :2], 1.0).max(1)
        shift = np.linalg.norm(0.5 * (out[:, :2] + out[:, 2:] - old[:, :2] - old[:, 2:]), axis=1)
        bad = (shift > self.max_shift * size) | (out[:, 2] <= out[:, 0]) | (out[:, 3] <= out[:, 1])
        out[bad] = old[bad]
        return out

    def __call__(self, image: np.ndarray, detections: Sequence[Detection]) -> list[Detection]:
        h, w = image.shape[:2]
        new = np.clip(self.boxes(image, [d.box for d in detections]), 0, [w, h, w, h])
        return [Detection(tuple(float(v) for v in b), d.score, d.class_id, d.class_name) for b, d in zip(new, detections)]


def jitter_boxes(box: np.ndarray, n: int, rng: np.random.Generator, shift_sigma: float = 0.12, scale_sigma: float = 0.2) -> np.ndarray:
    """``n`` boxes around ``box`` as a detector misplaces it: centre moved by N(0, shift_sigma * size)
    per axis (a fifth of them three times as far), each side's length scaled by exp(N(0, scale_sigma))."""
    x0, y0, x1, y1 = box
    w, h = x1 - x0, y1 - y0
    far = np.where(rng.random(n) < 0.2, 3.0, 1.0)[:, None]
    c = np.array([(x0 + x1) / 2, (y0 + y1) / 2]) + rng.normal(0, shift_sigma, (n, 2)) * far * np.array([w, h])
    s = np.array([w, h]) * np.exp(rng.normal(0, scale_sigma, (n, 2)))
    return np.concatenate([c - s / 2, c + s / 2], 1)


def make_refiner_set(images: Sequence[np.ndarray], boxes: Sequence[np.ndarray], config: RefinerConfig, per_label: int,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Crops (N, P, P, 3), the jittered boxes they were cut around and the label boxes (both (N, 4),
    crop fractions) from frames and their (M, 5) class, x0, y0, x1, y1 labels: ``per_label`` crops
    around jittered copies of each label."""
    crops, given, targets = [], [], []
    for image, labels in zip(images, boxes):
        for lb in np.asarray(labels, float).reshape(-1, 5)[:, 1:]:
            if min(lb[2] - lb[0], lb[3] - lb[1]) < 2.0:
                continue
            jittered = jitter_boxes(lb, per_label, rng)
            windows = [crop_window(b, config) for b in jittered]
            crops.append(_crops(image, windows, config.input_px))
            w = np.array(windows, float)
            given.append(_fractions(jittered, w))
            targets.append(_fractions(lb[None, :], w))
    if not crops:
        raise ValueError("no labelled targets in the frames given")
    return np.concatenate(crops), np.concatenate(given).astype(np.float32), np.concatenate(targets).astype(np.float32)


def train_refiner(crops: np.ndarray, given: np.ndarray, targets: np.ndarray, out_path: str | Path, config: RefinerConfig = RefinerConfig(),
                  steps: int = 3000, batch: int = 128, lr: float = 2e-3, seed: int = 0, progress="stderr") -> Path:
    """Fit :class:`BoxRefinerNet` (smooth L1 on the box fractions, horizontal flips, AdamW with a cosine decay)
    and save ``{"config", "state_dict"}`` (fp16) to ``out_path``."""
    if progress == "stderr":  # the stream at call time, not at import (a test runner swaps it)
        progress = sys.stderr
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = BoxRefinerNet(config)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    x_all = _to_tensor(crops)
    g_all = torch.from_numpy(given)
    y_all = torch.from_numpy(targets)
    net.train()
    for step in range(steps):
        for g in opt.param_groups:
            g["lr"] = lr * 0.5 * (1 + math.cos(math.pi * step / steps))
        idx = torch.from_numpy(rng.integers(len(x_all), size=batch))
        x, g, y = x_all[idx], g_all[idx].clone(), y_all[idx].clone()
        flip = torch.from_numpy(rng.random(batch) < 0.5)
        x[flip] = x[flip].flip(3)
        for b in (g, y):
            b[flip] = torch.stack([1 - b[flip, 2], b[flip, 1], 1 - b[flip, 0], b[flip, 3]], 1)
        loss = nn.functional.smooth_l1_loss(net(x, g), y, beta=0.02)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if progress is not None and ((step + 1) % 100 == 0 or step + 1 == steps):
            progress.write(f"refiner {step + 1}/{steps} loss {float(loss.detach()):.4f}\n")
            progress.flush()
    net.eval()
    sd = {k: (v.half() if v.dtype == torch.float32 else v) for k, v in net.state_dict().items()}
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"config": config.to_dict(), "state_dict": sd}, out)
    return out
