"""Ground materials for the camera world, generated from multi-octave noise: grasses, crop rows,
ploughed soil, sand, gravel, asphalt, water, snow, rock, heather.

Each material is a function ``(rng, size_px, angle_rad, palette) -> BGR float32 image`` of a square
patch at the ground texture's scale (:data:`GROUND_M_PER_PX`); ``angle_rad`` orients what has a
direction (crop rows, furrows, dune ripples). Families of the world (:mod:`sitl.world.camera.world`)
choose among them, so a family held out of training can use materials no training family has.
"""

from __future__ import annotations

import math
from typing import Callable

import cv2
import numpy as np

__all__ = ["GROUND_M_PER_PX", "MATERIALS", "Material", "value_noise", "fractal_noise", "ridged_noise",
           "periodic_fractal_noise"]

GROUND_M_PER_PX = 0.5  # the ground texture's resolution; finer grain comes from the detail layer

Material = Callable[[np.random.Generator, int, float, float], np.ndarray]


def value_noise(rng: np.random.Generator, size: int, cells: int) -> np.ndarray:
    """Smooth noise in [0, 1]: a random ``cells`` x ``cells`` grid upsampled bicubically to ``size``."""
    base = rng.random((max(cells, 2), max(cells, 2))).astype(np.float32)
    up = cv2.resize(base, (size, size), interpolation=cv2.INTER_CUBIC)
    lo, hi = float(up.min()), float(up.max())
    return (up - lo) / max(hi - lo, 1e-6)


def fractal_noise(rng: np.random.Generator, size: int, octaves: tuple[int, ...], gain: float = 0.5) -> np.ndarray:
    """Octaves of :func:`value_noise` (cells per side each), weights falling by ``gain``; in [0, 1]."""
    out = np.zeros((size, size), np.float32)
    weight, total = 1.0, 0.0
    for cells in octaves:
        out += weight * value_noise(rng, size, cells)
        total += weight
        weight *= gain
    return out / total


def periodic_fractal_noise(rng: np.random.Generator, size: int, octaves: tuple[int, ...], gain: float = 0.5) -> np.ndarray:
    """:func:`fractal_noise` that tiles seamlessly: each octave's grid wraps around before it is upsampled."""
    out = np.zeros((size, size), np.float32)
    weight, total = 1.0, 0.0
    for cells in octaves:
        cells = max(cells, 2)
        grid = np.pad(rng.random((cells, cells)).astype(np.float32), 2, mode="wrap")
        scale = size / cells
        up = cv2.resize(grid, (int(round((cells + 4) * scale)),) * 2, interpolation=cv2.INTER_CUBIC)
        o = int(round(2 * scale))
        out += weight * up[o:o + size, o:o + size]
        total += weight
        weight *= gain
    out /= total
    lo, hi = float(out.min()), float(out.max())
    return (out - lo) / max(hi - lo, 1e-6)


def ridged_noise(rng: np.random.Generator, size: int, octaves: tuple[int, ...]) -> np.ndarray:
    """Ridged multifractal: sharp crests where the noise crosses its middle (rock, heather clumps)."""
    return 1.0 - np.abs(2.0 * fractal_noise(rng, size, octaves) - 1.0)


def _stripes(size: int, angle: float, period_px: float, rng: np.random.Generator) -> np.ndarray:
    """Parallel rows across the patch at ``angle``, with a little wander: in [0, 1], 1 on a row."""
    y, x = np.mgrid[0:size, 0:size].astype(np.float32)
    wander = (fractal_noise(rng, size, (4, 16)) - 0.5) * period_px * 0.6
    phase = (x * math.cos(angle) + y * math.sin(angle) + wander) * (2.0 * math.pi / period_px)
    return 0.5 + 0.5 * np.cos(phase)


def _mix(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    return a + (b - a) * t[..., None]


def _colour(bgr: tuple[float, float, float], rng: np.random.Generator, spread: float = 0.12) -> np.ndarray:
    return np.asarray(bgr, np.float32) * rng.uniform(1.0 - spread, 1.0 + spread, 3).astype(np.float32)


def grass(rng, n, angle, dry):
    """Meadow grass: green to straw with ``dry`` (0..1), clumps at several scales."""
    lush = _colour((45 + 30 * dry, 115 + 35 * dry, 60 + 100 * dry), rng)
    dark = lush * rng.uniform(0.55, 0.7)
    return _mix(dark, lush, fractal_noise(rng, n, (8, 32, 128, 512)))


def lawn(rng, n, angle, dry):
    """Mown grass: even green with the mower's stripes."""
    base = _colour((50 + 20 * dry, 140 + 20 * dry, 70 + 60 * dry), rng, 0.08)
    stripe = _stripes(n, angle, rng.uniform(6, 12), rng) > 0.5
    tone = 0.9 + 0.1 * stripe.astype(np.float32) + 0.08 * (fractal_noise(rng, n, (64, 256)) - 0.5)
    return base * tone[..., None]


def crop(rng, n, angle, dry):
    """Crop rows on bare soil: green (or ripe yellow when dry) lines every 1.5-3 m."""
    leaf = _colour((40, 130 + 40 * dry, 70 + 120 * dry), rng)
    soil = _colour((60, 85, 110), rng)
    rows = _stripes(n, angle, rng.uniform(3, 6), rng)
    cover = np.clip(rows * 1.3 - 0.2 + 0.3 * (fractal_noise(rng, n, (16, 64)) - 0.5), 0, 1)
    return _mix(soil, leaf, cover)


def soil(rng, n, angle, dry):
    """Ploughed soil: brown furrows, lighter ridges, drier patches."""
    wet = _colour((45, 65, 90), rng)
    light = _colour((90 + 40 * dry, 120 + 40 * dry, 150 + 30 * dry), rng)
    furrows = _stripes(n, angle, rng.uniform(1.5, 3), rng)
    t = np.clip(0.55 * furrows + 0.45 * fractal_noise(rng, n, (8, 32, 256)), 0, 1)
    return _mix(wet, light, t)


def sand(rng, n, angle, dry):
    """Sand with dune ripples."""
    base = _colour((140, 185, 215), rng, 0.08)
    ripples = _stripes(n, angle, rng.uniform(4, 9), rng)
    tone = 0.85 + 0.1 * ripples + 0.12 * fractal_noise(rng, n, (6, 24))
    return base * tone[..., None]


def gravel(rng, n, angle, dry):
    """Gravel: grey with a coarse speckle of stones."""
    base = _colour((125, 128, 132), rng, 0.1)
    grain = rng.random((n, n)).astype(np.float32)
    tone = 0.75 + 0.3 * grain + 0.15 * fractal_noise(rng, n, (16, 64))
    return base * tone[..., None]


def asphalt(rng, n, angle, dry):
    """Asphalt: dark grey, fine grain, patched."""
    base = _colour((68, 70, 72), rng, 0.1)
    tone = 0.85 + 0.2 * fractal_noise(rng, n, (32, 256)) + 0.1 * (rng.random((n, n)).astype(np.float32) - 0.5)
    return base * tone[..., None]


def water(rng, n, angle, dry):
    """Open water: dark blue-green, wind streaks."""
    deep = _colour((70, 60, 30), rng)
    shallow = _colour((110, 110, 70), rng)
    streaks = _stripes(n, angle, rng.uniform(8, 20), rng)
    return _mix(deep, shallow, np.clip(0.6 * fractal_noise(rng, n, (4, 16)) + 0.25 * streaks, 0, 1))


def snow(rng, n, angle, dry):
    """Snow: near white with blue-grey drifts and tracks."""
    white = _colour((245, 245, 240), rng, 0.04)
    shade = _colour((200, 185, 170), rng, 0.05)
    return _mix(shade, white, fractal_noise(rng, n, (4, 16, 64)) ** 0.6)


def rock(rng, n, angle, dry):
    """Bare rock: ridged grey-brown slabs (held-out families only)."""
    dark = _colour((70, 80, 90), rng)
    light = _colour((150, 160, 170), rng)
    return _mix(dark, light, ridged_noise(rng, n, (6, 24, 96, 384)))


def heather(rng, n, angle, dry):
    """Heather moor: purple-brown clumps on peat (held-out families only)."""
    peat = _colour((40, 45, 60), rng)
    bloom = _colour((110, 70, 120), rng)
    return _mix(peat, bloom, ridged_noise(rng, n, (16, 64, 256)) ** 1.5)


MATERIALS: dict[str, Material] = {
    "grass": grass, "lawn": lawn, "crop": crop, "soil": soil, "sand": sand, "gravel": gravel,
    "asphalt": asphalt, "water": water, "snow": snow, "rock": rock, "heather": heather,
}
