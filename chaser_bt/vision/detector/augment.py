"""Training augmentations in the paper's style (appendix model card: HSV, scale, mosaic as in darknet/YOLO;
mixup and blur as in YOLOv4/v5's bag of freebies).

Boxes are (N, 5) float arrays of ``class, x0, y0, x1, y1`` in pixels. Every function takes the
numpy Generator it draws from, so a seeded run repeats exactly.
"""

from __future__ import annotations

from typing import Sequence

import cv2
import numpy as np

__all__ = ["hsv_jitter", "random_scale", "mosaic", "mixup", "motion_blur", "gaussian_blur", "random_blur", "letterbox",
           "flip_horizontal"]


def hsv_jitter(image: np.ndarray, rng: np.random.Generator, hue: float = 0.03, sat: float = 0.5, val: float = 0.4) -> np.ndarray:
    """Scale saturation and value by up to +-``sat``/``val`` and shift hue by up to +-``hue`` of a turn."""
    gains = rng.uniform(-1, 1, 3) * np.array([hue, sat, val]) + 1.0
    h, s, v = cv2.split(cv2.cvtColor(image, cv2.COLOR_BGR2HSV))
    x = np.arange(256, dtype=np.float32)
    lut_h = ((x * gains[0]) % 180).astype(np.uint8)
    lut_s = np.clip(x * gains[1], 0, 255).astype(np.uint8)
    lut_v = np.clip(x * gains[2], 0, 255).astype(np.uint8)
    hsv = cv2.merge([cv2.LUT(h, lut_h), cv2.LUT(s, lut_s), cv2.LUT(v, lut_v)])
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)


def random_scale(image: np.ndarray, boxes: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Resize by ``scale``; boxes follow."""
    h, w = image.shape[:2]
    out = cv2.resize(image, (max(int(round(w * scale)), 1), max(int(round(h * scale)), 1)), interpolation=cv2.INTER_LINEAR)
    b = boxes.copy()
    b[:, 1:] *= scale
    return out, b


def flip_horizontal(image: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    w = image.shape[1]
    b = boxes.copy()
    b[:, 1], b[:, 3] = w - boxes[:, 3], w - boxes[:, 1]
    return image[:, ::-1].copy(), b


def letterbox(image: np.ndarray, size: int, fill: int = 114) -> tuple[np.ndarray, float, tuple[int, int]]:
    """Fit ``image`` into a ``size`` x ``size`` square keeping its aspect; returns (image, scale, (pad_x, pad_y))."""
    h, w = image.shape[:2]
    scale = size / max(h, w)
    nw, nh = int(round(w * scale)), int(round(h * scale))
    resized = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)
    px, py = (size - nw) // 2, (size - nh) // 2
    out = np.full((size, size, 3), fill, np.uint8)
    out[py:py + nh, px:px + nw] = resized
    return out, scale, (px, py)


def clip_boxes(boxes: np.ndarray, width: int, height: int, min_size: float = 2.0, min_kept: float = 0.4) -> np.ndarray:
    """Clip to the image; drop boxes smaller than ``min_size`` or with less than ``min_kept`` of their area left."""
    if len(boxes) == 0:
        return boxes.reshape(0, 5)
    b = boxes.copy()
    area = (b[:, 3] - b[:, 1]) * (b[:, 4] - b[:, 2])
    b[:, [1, 3]] = b[:, [1, 3]].clip(0, width)
    b[:, [2, 4]] = b[:, [2, 4]].clip(0, height)
    w, h = b[:, 3] - b[:, 1], b[:, 4] - b[:, 2]
    keep = (w >= min_size) & (h >= min_size) & (w * h >= min_kept * np.maximum(area, 1e-9))
    return b[keep]


def mosaic(images: Sequence[np.ndarray], boxes: Sequence[np.ndarray], size: int, rng: np.random.Generator,
           scale_range: tuple[float, float] = (0.7, 1.3), fill: int = 114, focus: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Four images around a random centre on a 2*size canvas, each randomly scaled, then a size x size crop.

    YOLOv4's mosaic: objects keep their scale (up to ``scale_range``) while context is mixed. With
    probability ``focus`` the crop is placed to contain a random box (more positives per batch).
    """
    canvas = np.full((2 * size, 2 * size, 3), fill, np.uint8)
    cx, cy = (int(v) for v in rng.uniform(0.5 * size, 1.5 * size, 2))
    out_boxes = []
    for k, (img, b) in enumerate(zip(images[:4], boxes[:4])):
        img, b = random_scale(img, b, float(rng.uniform(*scale_range)))
        h, w = img.shape[:2]
        # Quadrant k: the image's inner corner sits at the centre.
        x0 = cx - w if k in (0, 2) else cx
        y0 = cy - h if k in (0, 1) else cy
        cx0, cy0 = max(x0, 0), max(y0, 0)
        cx1, cy1 = min(x0 + w, 2 * size), min(y0 + h, 2 * size)
        if cx1 <= cx0 or cy1 <= cy0:
            continue
        canvas[cy0:cy1, cx0:cx1] = img[cy0 - y0:cy1 - y0, cx0 - x0:cx1 - x0]
        b = b.copy()
        b[:, [1, 3]] += x0
        b[:, [2, 4]] += y0
        # Keep only the part of each box inside this quadrant's pasted region.
        b[:, [1, 3]] = b[:, [1, 3]].clip(cx0, cx1)
        b[:, [2, 4]] = b[:, [2, 4]].clip(cy0, cy1)
        out_boxes.append(b)
    allb = np.concatenate(out_boxes) if out_boxes else np.zeros((0, 5))
    allb = allb[(allb[:, 3] > allb[:, 1]) & (allb[:, 4] > allb[:, 2])]
    ox, oy = (int(v) for v in rng.integers(0, size + 1, 2))
    if len(allb) and rng.random() < focus:
        _, x0, y0, x1, y1 = allb[int(rng.integers(len(allb)))]
        lo_x, hi_x = max(0, int(x1) - size + 1), min(size, int(x0))
        lo_y, hi_y = max(0, int(y1) - size + 1), min(size, int(y0))
        if hi_x >= lo_x and hi_y >= lo_y:
            ox, oy = int(rng.integers(lo_x, hi_x + 1)), int(rng.integers(lo_y, hi_y + 1))
    crop = canvas[oy:oy + size, ox:ox + size].copy()
    allb = allb.copy()
    allb[:, [1, 3]] -= ox
    allb[:, [2, 4]] -= oy
    return crop, clip_boxes(allb, size, size)


def mixup(image_a: np.ndarray, boxes_a: np.ndarray, image_b: np.ndarray, boxes_b: np.ndarray,
          weight: float) -> tuple[np.ndarray, np.ndarray]:
    """YOLOv4/v5's mixup of two same-size images: ``weight * a + (1 - weight) * b`` (rounded to uint8)
    and the union of both images' boxes (every object stays a target)."""
    if image_a.shape != image_b.shape:
        raise ValueError(f"mixup needs images of one size, got {image_a.shape} and {image_b.shape}")
    if not 0.0 <= weight <= 1.0:
        raise ValueError(f"mixup weight must be in [0, 1], got {weight}")
    mixed = weight * image_a.astype(np.float32) + (1.0 - weight) * image_b.astype(np.float32)
    boxes = np.concatenate([boxes_a.reshape(-1, 5), boxes_b.reshape(-1, 5)])
    return np.clip(np.rint(mixed), 0, 255).astype(np.uint8), boxes


def motion_kernel(length: int, angle_rad: float) -> np.ndarray:
    """A normalised line kernel of ``length`` px (odd size) along ``angle_rad`` (0 = along x)."""
    length = max(int(length), 1)
    size = length if length % 2 else length + 1
    k = np.zeros((size, size), np.float32)
    c = (size - 1) / 2.0
    for t in np.linspace(-(length - 1) / 2.0, (length - 1) / 2.0, length):
        k[int(round(c + t * np.sin(angle_rad))), int(round(c + t * np.cos(angle_rad)))] += 1.0
    return k / k.sum()


def motion_blur(image: np.ndarray, length: int, angle_rad: float) -> np.ndarray:
    """Blur along a line of ``length`` px at ``angle_rad`` (camera or target motion over the exposure);
    the kernel sums to one, so the mean brightness is kept (up to the reflected border)."""
    if length <= 1:
        return image.copy()
    return cv2.filter2D(image, -1, motion_kernel(length, angle_rad), borderType=cv2.BORDER_REFLECT_101)


def gaussian_blur(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian blur of ``sigma_px`` (defocus, soft optics); the mean brightness is kept."""
    if sigma_px <= 0:
        return image.copy()
    return cv2.GaussianBlur(image, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT_101)


def random_blur(image: np.ndarray, rng: np.random.Generator, motion_px: tuple[int, int] = (3, 9),
                sigma_px: tuple[float, float] = (0.5, 1.5), motion_share: float = 0.5) -> np.ndarray:
    """Motion blur (length uniform in ``motion_px``, any direction) with probability ``motion_share``,
    else a Gaussian blur (sigma uniform in ``sigma_px``). Boxes are unchanged."""
    if rng.random() < motion_share:
        return motion_blur(image, int(rng.integers(motion_px[0], motion_px[1] + 1)), float(rng.uniform(0.0, np.pi)))
    return gaussian_blur(image, float(rng.uniform(*sigma_px)))
