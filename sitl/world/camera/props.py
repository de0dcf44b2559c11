"""Upright clutter the ground texture cannot show: poles and the power lines strung between them.

Drawn by projecting their 3-D points into the frame, so they lean, shrink and cross the sky as a
real camera sees them: thin dark lines, the kind of edge a tracker drifts onto.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import cv2
import numpy as np

__all__ = ["PowerLine", "make_power_lines", "boxes_reach"]

Projector = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]  # ENU (N, 3) -> pixels (N, 2), depth (N,)


@dataclass(frozen=True)
class PowerLine:
    """Poles at ``poles_enu`` (K, 2) ground points, ``height_m`` tall, ``wires`` strung pole to pole
    with ``sag_m`` of sag at mid-span."""

    poles_enu: np.ndarray
    height_m: float = 9.0
    wires: int = 3
    sag_m: float = 0.8
    colour: tuple[int, int, int] = (40, 40, 45)

    def draw(self, img: np.ndarray, project: Projector, focal_px: float, views=None) -> None:
        """Draw the poles and wires; ``views`` ((x0, y0, x1, y1) pixel rectangles, None: the whole
        image): a pole or wire that cannot reach any of them is not drawn."""
        if views is None:
            views = [(0, 0, img.shape[1], img.shape[0])]
        k = len(self.poles_enu)
        px, z = project(self._poles)  # feet, then tops
        px_b, px_t, z_b, z_t = px[:k], px[k:], z[:k], z[k:]
        ahead = np.minimum(z_b, z_t) > 1.0
        width = np.maximum(np.round(0.25 * focal_px / np.where(ahead, z_b, 1.0)), 1.0)
        ok = ahead & (width <= 40) & np.isfinite(px_b).all(1) & np.isfinite(px_t).all(1)
        ok &= np.maximum(np.abs(px_b).max(1), np.abs(px_t).max(1)) < 1e5
        reach = (width + 2.0)[:, None]
        ok &= boxes_reach(np.minimum(px_b, px_t) - reach, np.maximum(px_b, px_t) + reach, views)
        for i in np.flatnonzero(ok):
            a, b = px_b[i], px_t[i]
            cv2.line(img, (int(a[0] * 16), int(a[1] * 16)), (int(b[0] * 16), int(b[1] * 16)), self.colour, int(width[i]), cv2.LINE_AA, 4)
        spans = k - 1
        if spans < 1:
            return
        px, z = project(self._wire_points)
        px, z = px.reshape(spans * self.wires, 12, 2), z.reshape(spans * self.wires, 12)
        keep = (z > 1.0).all(axis=1) & (np.abs(px) < 1e5).all(axis=(1, 2))
        keep &= boxes_reach(px.min(axis=1) - 3.0, px.max(axis=1) + 3.0, views)
        if keep.any():
            cv2.polylines(img, list(np.round(px[keep] * 16).astype(np.int32)), False, self.colour, 1, cv2.LINE_AA, 4)

    @functools.cached_property
    def _poles(self) -> np.ndarray:
        """The poles' feet, then their tops (2K, 3): fixed, so worked out once, not every frame."""
        base = np.column_stack([self.poles_enu, np.zeros(len(self.poles_enu))])
        return np.vstack([base, base + [0.0, 0.0, self.height_m]])

    @functools.cached_property
    def _wire_points(self) -> np.ndarray:
        """The wires' points (spans * wires * 12, 3), each wire 12 points along its sagging span."""
        top = self._poles[len(self.poles_enu):]
        s = np.linspace(0.0, 1.0, 12)
        drop = np.array([0.0, 0.0, 1.0])
        a = top[:-1, None, None, :] - 0.6 * np.arange(self.wires)[None, :, None, None] * drop  # (spans, wires, 1, 3)
        b = top[1:, None, None, :] - 0.6 * np.arange(self.wires)[None, :, None, None] * drop
        pts = a + s[None, None, :, None] * (b - a) - (4 * self.sag_m * s * (1 - s))[None, None, :, None] * drop
        return pts.reshape(-1, 3)


def boxes_reach(lo: np.ndarray, hi: np.ndarray, views) -> np.ndarray:
    """Which of the (N, 2) pixel boxes ``lo``-``hi`` overlap any of ``views``."""
    hit = np.zeros(len(lo), bool)
    for x0, y0, x1, y1 in views:
        hit |= (hi[:, 0] >= x0) & (lo[:, 0] < x1) & (hi[:, 1] >= y0) & (lo[:, 1] < y1)
    return hit


def make_power_lines(rng: np.random.Generator, count: int, half_extent_m: float) -> list[PowerLine]:
    """``count`` straight lines of poles 40-60 m apart across a field ``half_extent_m`` in each direction."""
    lines = []
    for _ in range(count):
        start = rng.uniform(-half_extent_m, half_extent_m, 2)
        heading = rng.uniform(0, 2 * np.pi)
        spacing = rng.uniform(40, 60)
        n = int(rng.integers(6, 20))
        poles = start + np.outer(np.arange(n) * spacing, [np.cos(heading), np.sin(heading)])
        lines.append(PowerLine(poles, height_m=float(rng.uniform(7, 12))))
    return lines
