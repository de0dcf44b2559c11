"""Procedural ground for the rendered camera: grass, gravel and sand patches, roads and tree lines.

The ground is one texture image laid on the ENU plane z = 0, centred on the origin; the renderer
maps it into the image with a homography; beyond its edges the ground is its mean colour. A seed fixes the layout
and the palette, so training and held-out sets can use different backgrounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["GroundScene", "make_ground"]


@dataclass(frozen=True)
class GroundScene:
    """A ground texture (BGR uint8, row 0 = north edge) and where it lies.

    Args:
        texture: (N, N, 3) BGR image.
        metres_per_px: ground size of one texture pixel.
        far_texture: the texture pre-filtered and smaller (any size), drawn where the ground is far
            enough that one image pixel covers several texture pixels; None: the texture everywhere.
        detail: a tileable grey grain (uint8, 128 = no change) at
            :data:`sitl.world.camera.fields.DETAIL_M_PER_PX`, modulating the near ground; None: none.
    """

    texture: np.ndarray
    metres_per_px: float
    far_texture: np.ndarray | None = None
    detail: np.ndarray | None = None

    @property
    def half_extent_m(self) -> float:
        return 0.5 * self.texture.shape[1] * self.metres_per_px

    def texture_to_ground(self) -> np.ndarray:
        """3x3 homogeneous map from texture pixel (col, row, 1) to ground (east, north, 1)."""
        h = self.half_extent_m
        r = self.metres_per_px
        return np.array([[r, 0.0, -h], [0.0, -r, h], [0.0, 0.0, 1.0]])


def _noise(rng: np.random.Generator, size: int, cells: int) -> np.ndarray:
    """Smooth value noise in [0, 1]: a random ``cells`` x ``cells`` grid upsampled bicubically."""
    base = rng.random((cells, cells)).astype(np.float32)
    up = cv2.resize(base, (size, size), interpolation=cv2.INTER_CUBIC)
    lo, hi = float(up.min()), float(up.max())
    return (up - lo) / max(hi - lo, 1e-6)


def _fractal(rng: np.random.Generator, size: int, octaves: tuple[int, ...]) -> np.ndarray:
    out = np.zeros((size, size), np.float32)
    weight = 1.0
    for cells in octaves:
        out += weight * _noise(rng, size, cells)
        weight *= 0.5
    return out / out.max()


def make_ground(seed: int, size_px: int = 2048, metres_per_px: float = 0.5) -> GroundScene:
    """A procedural field of ``size_px`` * ``metres_per_px`` metres a side, laid out by ``seed``."""
    rng = np.random.default_rng(seed)
    n = size_px
    # Palette (BGR): grass hue and dryness vary by seed, so backgrounds differ between sets.
    dry = rng.uniform(0.0, 0.6)
    grass = np.array([40 + 30 * dry, 110 + 30 * dry, 60 + 90 * dry]) * rng.uniform(0.8, 1.15)
    grass_dark = grass * rng.uniform(0.55, 0.75)
    gravel = np.array([120, 125, 130]) * rng.uniform(0.8, 1.1)
    sand = np.array([120, 170, 200]) * rng.uniform(0.85, 1.1)
    field = _fractal(rng, n, (8, 32, 128, 512))[..., None]
    img = grass_dark + (grass - grass_dark) * field
    for colour, threshold in ((gravel, rng.uniform(0.72, 0.8)), (sand, rng.uniform(0.74, 0.82))):
        mask = _fractal(rng, n, (6, 24, 96))
        patch = np.clip((mask - threshold) * 12.0, 0.0, 1.0)[..., None]
        grain = 0.85 + 0.3 * _noise(rng, n, 512)[..., None]
        img = img * (1 - patch) + colour * grain * patch
    img = np.clip(img, 0, 255).astype(np.uint8)
    # Roads: a few long straight or bent asphalt / dirt strips.
    for _ in range(int(rng.integers(1, 4))):
        pts = np.cumsum(rng.normal(0, n / 4, size=(4, 2)), axis=0) + rng.uniform(0, n, size=2)
        colour = tuple(int(c) for c in (rng.choice([70, 150]) + rng.integers(-10, 10, 3)))
        width = int(rng.integers(6, 16))
        cv2.polylines(img, [pts.astype(np.int32)], False, colour, width, cv2.LINE_AA)
    # Tree lines: rows of dark crowns with a shadow side.
    for _ in range(int(rng.integers(3, 8))):
        a = rng.uniform(0, n, 2)
        b = a + rng.normal(0, n / 5, 2)
        count = int(np.linalg.norm(b - a) / 5) + 2
        for s in np.linspace(0.0, 1.0, count):
            c = a + s * (b - a) + rng.normal(0, 2.0, 2)
            r = int(rng.integers(4, 10))
            crown = tuple(int(x) for x in np.array([30, 70, 35]) * rng.uniform(0.6, 1.2))
            cv2.circle(img, (int(c[0]) + 2, int(c[1]) + 2), r, (15, 30, 20), -1, cv2.LINE_AA)
            cv2.circle(img, (int(c[0]), int(c[1])), r, crown, -1, cv2.LINE_AA)
    # Bushes: scattered dark blobs (the paper's tracker drifted onto one).
    for _ in range(int(rng.integers(100, 300))):
        c = rng.uniform(0, n, 2).astype(int)
        cv2.circle(img, (int(c[0]), int(c[1])), int(rng.integers(1, 4)), (25, 55, 30), -1, cv2.LINE_AA)
    return GroundScene(texture=img, metres_per_px=metres_per_px)
