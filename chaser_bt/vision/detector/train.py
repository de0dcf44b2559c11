"""Train the detector on a YOLO-format image folder (paper appendix model card: fine-tune all layers,
standard schedule and augmentation). Seeded, resumable from its checkpoint, with a progress line.

Images are letterboxed once to the detector scale (``image_size`` / longest side) and kept in memory;
each batch is made of mosaics (4 images, random scale), with probability ``mixup`` blended with a
second mosaic (weight Beta(``mixup_beta``, ``mixup_beta``), boxes of both), HSV jitter, with
probability ``blur`` a motion or Gaussian blur, and horizontal flips.
Optimiser: AdamW with a linear warm-up and a cosine decay; an exponential moving average of the
weights (YOLOv5) is what gets saved. ``init_weights`` fine-tunes from a saved model (same classes)
instead of starting from scratch, and ``widths`` grows its stages first
(:func:`chaser_bt.vision.detector.widen.widen`) or sizes a net trained from scratch; ``small_box_px`` > 0 draws the images holding a box narrower than
that ``small_weight`` times as often (small targets are the common misses); ``obj_iou`` > 0 makes
objectness learn the predicted box's IoU (:func:`chaser_bt.vision.detector.loss.detection_loss`).
"""

from __future__ import annotations

import copy
import logging
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np
import torch

from chaser_bt.vision.detector.augment import flip_horizontal, hsv_jitter, mixup, mosaic, random_blur
from chaser_bt.vision.detector.loss import detection_loss
from chaser_bt.vision.detector.model import DetectorConfig, TinyYolo

__all__ = ["TrainConfig", "TrainingInterrupted", "iter_yolo_folder", "load_yolo_folder", "train_detector", "yolo_classes"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrainConfig:
    """Training settings (see module docstring)."""

    data_dir: str
    out_path: str
    steps: int = 1500
    batch: int = 24
    crop: int = 288
    image_size: int = 416
    lr: float = 2e-3
    weight_decay: float = 5e-4
    scale_range: tuple[float, float] = (0.55, 1.8)
    seed: int = 0
    threads: int = 1
    checkpoint_every: int = 50
    ema_decay: float = 0.995
    init_weights: str = ""
    widths: tuple[int, ...] | None = None
    small_box_px: float = 0.0
    small_weight: float = 3.0
    obj_iou: float = 0.0
    mixup: float = 0.1
    mixup_beta: float = 32.0
    blur: float = 0.3
    blur_motion_px: tuple[int, int] = (3, 9)
    blur_sigma_px: tuple[float, float] = (0.5, 1.5)


def load_yolo_folder(data_dir: str | Path, image_size: int) -> tuple[list[np.ndarray], list[np.ndarray], tuple[str, ...]]:
    """Images (resized so the longest side is ``image_size``) and (N, 5) pixel boxes from a YOLO folder."""
    images, boxes = [], []
    for chunk_images, chunk_boxes in iter_yolo_folder(data_dir, image_size):
        images += chunk_images
        boxes += chunk_boxes
    return images, boxes, yolo_classes(data_dir)


def yolo_classes(data_dir: str | Path) -> tuple[str, ...]:
    """A YOLO folder's class names (``classes.txt``, one a line)."""
    return tuple(x.strip() for x in (Path(data_dir) / "classes.txt").read_text().splitlines() if x.strip())


def iter_yolo_folder(data_dir: str | Path, image_size: int, chunk: int = 256) -> Iterator[tuple[list[np.ndarray], list[np.ndarray]]]:
    """:func:`load_yolo_folder`'s images and boxes, ``chunk`` frames at a time in the same order, so a
    pass over a large folder holds one chunk in memory, not the whole folder."""
    root = Path(data_dir)
    paths = sorted((root / "images").glob("*.jpg"))
    if not paths:
        raise ValueError(f"{root / 'images'}: no .jpg images")
    for start in range(0, len(paths), chunk):
        images, boxes = [], []
        for img_path in paths[start:start + chunk]:
            img = cv2.imread(str(img_path), cv2.IMREAD_COLOR)
            if img is None:
                raise ValueError(f"{img_path}: not a readable image")
            h, w = img.shape[:2]
            s = image_size / max(h, w)
            img = cv2.resize(img, (int(round(w * s)), int(round(h * s))), interpolation=cv2.INTER_AREA)
            images.append(img)
            boxes.append(_read_labels(root / "labels" / (img_path.stem + ".txt"), img.shape[1], img.shape[0]))
        yield images, boxes


def _read_labels(lab: Path, width: int, height: int) -> np.ndarray:
    """(N, 5) class, x0, y0, x1, y1 pixel boxes of a YOLO label file (none when it is absent)."""
    rows = []
    for n, line in enumerate(lab.read_text().splitlines() if lab.exists() else [], 1):
        parts = line.split()
        if not parts:
            continue
        if len(parts) != 5:
            raise ValueError(f"{lab}:{n}: expected 'class cx cy w h', got {line!r}")
        c, cx, cy, bw, bh = int(parts[0]), *map(float, parts[1:])
        rows.append([c, (cx - bw / 2) * width, (cy - bh / 2) * height, (cx + bw / 2) * width, (cy + bh / 2) * height])
    return np.array(rows, float).reshape(-1, 5)


def sampling_weights(boxes: list[np.ndarray], small_box_px: float, small_weight: float) -> np.ndarray | None:
    """Per-image draw probabilities: ``small_weight`` for images with a box narrower than ``small_box_px``
    (in the letterboxed image), 1 for the rest; None (uniform) when ``small_box_px`` is 0."""
    if small_box_px <= 0:
        return None
    w = np.array([small_weight if len(b) and float(np.min(b[:, 3] - b[:, 1])) < small_box_px else 1.0 for b in boxes])
    return w / w.sum()


def _mosaic(images: list[np.ndarray], boxes: list[np.ndarray], cfg: TrainConfig, rng: np.random.Generator,
            p: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    idx = rng.integers(len(images), size=4) if p is None else rng.choice(len(images), size=4, p=p)
    return mosaic([images[i] for i in idx], [boxes[i] for i in idx], cfg.crop, rng, cfg.scale_range, focus=0.8)


def _batch(images, boxes, cfg: TrainConfig, rng: np.random.Generator, p: np.ndarray | None = None) -> tuple[torch.Tensor, list[torch.Tensor]]:
    xs, ts = [], []
    for _ in range(cfg.batch):
        img, b = _mosaic(images, boxes, cfg, rng, p)
        if cfg.mixup > 0 and rng.random() < cfg.mixup:  # no draw when off: older recipes repeat exactly
            img2, b2 = _mosaic(images, boxes, cfg, rng, p)
            img, b = mixup(img, b, img2, b2, float(rng.beta(cfg.mixup_beta, cfg.mixup_beta)))
        img = hsv_jitter(img, rng)
        if cfg.blur > 0 and rng.random() < cfg.blur:
            img = random_blur(img, rng, cfg.blur_motion_px, cfg.blur_sigma_px)
        if rng.random() < 0.5:
            img, b = flip_horizontal(img, b)
        xs.append(img)
        ts.append(torch.from_numpy(b).float())
    x = torch.from_numpy(np.stack(xs)[..., ::-1].copy()).permute(0, 3, 1, 2).float() / 255.0
    return x, ts


class TrainingInterrupted(KeyboardInterrupt):
    """Ctrl-C during training; the checkpoint at ``step`` (if any were trained) is at ``checkpoint``."""

    def __init__(self, checkpoint: Path, step: int) -> None:
        super().__init__(f"interrupted at step {step}")
        self.checkpoint, self.step = checkpoint, step


def train_detector(cfg: TrainConfig, resume: bool = True, progress="stderr") -> Path:
    """Train and save ``{"config", "state_dict", "step"}`` to ``cfg.out_path``; resumes from ``<out>.ckpt``."""
    if progress == "stderr":  # the stream at call time, not at import (a test runner swaps it)
        progress = sys.stderr
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    images, boxes, classes = load_yolo_folder(cfg.data_dir, cfg.image_size)
    det_cfg = DetectorConfig(num_classes=len(classes), class_names=classes)
    if cfg.widths is not None:
        det_cfg = replace(det_cfg, widths=tuple(cfg.widths))
    model = TinyYolo(det_cfg)
    if cfg.init_weights:
        from chaser_bt.vision.detector.inference import load_model
        from chaser_bt.vision.detector.widen import widen

        start = load_model(cfg.init_weights)
        if start.config.class_names != classes:
            raise ValueError(f"init weights {cfg.init_weights}: classes {start.config.class_names} differ from the data's {classes}")
        model = widen(start, cfg.widths) if cfg.widths is not None else start
        det_cfg = model.config
    p_small = sampling_weights(boxes, cfg.small_box_px, cfg.small_weight)
    ema = copy.deepcopy(model).eval()
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    out = Path(cfg.out_path)
    ckpt = out.with_suffix(".ckpt")
    step = 0
    if resume and ckpt.exists():
        state = torch.load(ckpt, weights_only=False)
        model.load_state_dict(state["model"])
        ema.load_state_dict(state["ema"])
        opt.load_state_dict(state["opt"])
        rng.bit_generator.state = state["rng"]
        torch.set_rng_state(state["torch_rng"])
        step = int(state["step"])
        log.info("resumed from %s at step %d", ckpt, step)
        if progress is not None:
            progress.write(f"resuming from {ckpt} at step {step} of {cfg.steps} (--fresh starts again)\n")
            if step >= cfg.steps:
                progress.write(f"the checkpoint is already at step {step} >= {cfg.steps} steps: nothing to train "
                               "(ask for more --steps, or --fresh)\n")
    warm = min(100, cfg.steps // 10)
    t0 = time.monotonic()
    first = step
    model.train()

    def checkpoint() -> None:
        out.parent.mkdir(parents=True, exist_ok=True)
        torch.save({"model": model.state_dict(), "ema": ema.state_dict(), "opt": opt.state_dict(), "rng": rng.bit_generator.state,
                    "torch_rng": torch.get_rng_state(), "step": step}, ckpt)
        save_weights(ema, out, step, cfg.obj_iou)

    try:
        while step < cfg.steps:
            lr = cfg.lr * (step + 1) / warm if step < warm else cfg.lr * 0.5 * (1 + math.cos(math.pi * (step - warm) / max(cfg.steps - warm, 1)))
            for g in opt.param_groups:
                g["lr"] = lr
            x, ts = _batch(images, boxes, cfg, rng, p_small)
            loss, parts = detection_loss(model(x), ts, det_cfg.stride, cfg.obj_iou)
            opt.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
            opt.step()
            d = cfg.ema_decay * (1 - math.exp(-(step + 1) / 200))
            with torch.no_grad():
                for pe, pm in zip(ema.state_dict().values(), model.state_dict().values()):
                    if pe.dtype.is_floating_point:
                        pe.mul_(d).add_(pm.detach(), alpha=1 - d)
                    else:
                        pe.copy_(pm)
            step += 1
            if progress is not None and (step % 10 == 0 or step == cfg.steps):
                rate = (time.monotonic() - t0) / max(step - first, 1)
                bar = "#" * int(30 * step / cfg.steps)
                progress.write(f"\r[{bar:<30}] {step}/{cfg.steps} loss {float(loss.detach()):.3f} (obj {parts['obj']:.3f} box {parts['box']:.3f} "
                               f"cls {parts['cls']:.3f}) lr {lr:.1e} {rate:.2f} s/step eta {rate * (cfg.steps - step) / 60:.1f} min\n")
                progress.flush()
            if step % cfg.checkpoint_every == 0 or step == cfg.steps:
                checkpoint()
    except KeyboardInterrupt:  # Ctrl-C: keep what was trained; the next run resumes from here
        if step > first:
            checkpoint()
            log.warning("interrupted at step %d: checkpoint %s written (run again to resume)", step, ckpt)
        raise TrainingInterrupted(ckpt, step) from None
    return out


def save_weights(model: TinyYolo, path: str | Path, step: int, obj_iou: float = 0.0) -> None:
    """The shipped file: config, half-precision weights (loads back as float32) and ``obj_iou``
    (the last training's; > 0 means scores predict the box's IoU)."""
    sd = {k: (v.half() if v.dtype == torch.float32 else v) for k, v in model.state_dict().items()}
    torch.save({"config": model.config.to_dict(), "state_dict": sd, "step": step, "obj_iou": obj_iou}, path)
