"""Farmland-like ground for the camera world: a patchwork of fields, roads and tracks, ponds, and
the clutter that lies on the ground seen from above (tree crowns and tree lines, bushes, buildings,
fences, parked cars), each with its shadow away from the sun.

The layout is a Voronoi patchwork of fields (cells of 40-200 m), each one material of the family
(:mod:`sitl.world.camera.materials`) with its own row direction. The result is a
:class:`~sitl.world.camera.scene.GroundScene` with a far-field copy (pre-filtered, so the ground does
not shimmer near the horizon) and a detail tile (grain finer than the texture for the near field).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from sitl.world.camera.materials import GROUND_M_PER_PX, MATERIALS, fractal_noise
from sitl.world.camera.scene import GroundScene

__all__ = ["GroundStyle", "make_field_ground", "DETAIL_M_PER_PX"]

DETAIL_M_PER_PX = 0.04  # the detail tile's grain: 2.5 cm, a pixel's footprint at 20 m range
_DETAIL_PX = 512


@dataclass(frozen=True)
class GroundStyle:
    """What a family's ground is made of.

    Args:
        materials: material name -> weight (share of fields).
        dryness: range of the grass and crop dryness (0 lush .. 1 straw).
        field_m: range of field sizes (m).
        roads: asphalt roads per km^2; tracks: dirt tracks per km^2; ponds: water bodies per km^2.
        trees, tree_lines, bushes, buildings, fences, cars: clutter per km^2.
        tree_colour: BGR of tree crowns (dark green; near black for conifers in snow).
        building_colours: BGR roof colours to choose from.
    """

    materials: dict[str, float]
    dryness: tuple[float, float] = (0.0, 0.5)
    field_m: tuple[float, float] = (40.0, 200.0)
    roads: float = 1.5
    tracks: float = 2.0
    ponds: float = 0.0
    trees: float = 60.0
    tree_lines: float = 5.0
    bushes: float = 200.0
    buildings: float = 3.0
    fences: float = 4.0
    cars: float = 4.0
    tree_colour: tuple[int, int, int] = (35, 75, 40)
    building_colours: tuple[tuple[int, int, int], ...] = ((60, 60, 150), (90, 90, 95), (150, 150, 155), (50, 70, 110))


def make_field_ground(style: GroundStyle, seed: int, sun_azimuth_rad: float, size_px: int = 2048,
                      shadow_scale: float = 1.0) -> GroundScene:
    """A ``size_px`` x ``size_px`` ground (0.5 m a pixel) laid out by ``seed`` in ``style``.

    Shadows fall away from ``sun_azimuth_rad`` (ENU, from east, counter-clockwise), ``shadow_scale``
    of their full length (an overcast sky shortens them; at 0 they hide under what casts them).
    """
    rng = np.random.default_rng([seed, 0x6e0])
    n = size_px
    km2 = (n * GROUND_M_PER_PX / 1000.0) ** 2
    img = _patchwork(style, rng, n)
    _ponds(img, style, rng, n, km2)
    _roads(img, rng, n, round(style.roads * km2), (70, 72, 74), (8, 16), lines=True)
    _roads(img, rng, n, round(style.tracks * km2), (95, 120, 140), (4, 7), lines=False)
    shadow = np.array([-math.cos(sun_azimuth_rad), math.sin(sun_azimuth_rad)])  # texture (col, row) direction
    if shadow_scale != 1.0:
        shadow = shadow * shadow_scale
    _fences(img, rng, n, round(style.fences * km2))
    _buildings(img, style, rng, n, round(style.buildings * km2), shadow)
    _cars(img, rng, n, round(style.cars * km2), shadow)
    _trees(img, style, rng, n, round(style.trees * km2), round(style.tree_lines * km2), round(style.bushes * km2), shadow)
    texture = np.clip(img, 0, 255).astype(np.uint8)
    far = cv2.resize(cv2.GaussianBlur(texture, (0, 0), 2.0), (n // 4, n // 4), interpolation=cv2.INTER_AREA)
    return GroundScene(texture=texture, metres_per_px=GROUND_M_PER_PX, far_texture=far, detail=_detail_tile(rng))


def _patchwork(style: GroundStyle, rng: np.random.Generator, n: int) -> np.ndarray:
    """Voronoi fields, each a material patch with its own direction; boundaries slightly wobbly."""
    cell, kinds = _field_layout(style, rng, n)
    img = _paint_fields(cell, kinds, style, rng)
    # Field margins: a thin darker strip where fields meet.
    edges = cv2.morphologyEx(cell.astype(np.float32), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
    img[edges] *= 0.8
    return img


def _field_layout(style: GroundStyle, rng: np.random.Generator, n: int) -> tuple[np.ndarray, list[str]]:
    """The fields: each pixel's field (n x n, 0..count-1), wobbly Voronoi cells; and each field's material."""
    mean_field_px = np.mean(style.field_m) / GROUND_M_PER_PX
    count = max(int((n / mean_field_px) ** 2), 4)
    seeds = rng.uniform(0, n, (count, 2)).astype(np.float32)
    half = n // 2  # fields found at 1 m, then upsampled: borders step by a metre, not by the texture's 0.5 m
    warp = cv2.resize((fractal_noise(rng, 256, (4, 16)) - 0.5) * mean_field_px * 0.3, (half, half))
    y, x = np.mgrid[0:half, 0:half].astype(np.float32) * 2.0
    points = np.column_stack([(x + warp).ravel(), (y - warp).ravel()])
    cell = cKDTree(seeds).query(points, workers=1)[1].reshape(half, half).astype(np.uint16)
    cell = cv2.resize(cell, (n, n), interpolation=cv2.INTER_NEAREST)
    names = list(style.materials)
    weights = np.array([style.materials[m] for m in names], float)
    choice = rng.choice(len(names), size=count, p=weights / weights.sum())
    return cell, [names[c] for c in choice]


def _paint_fields(cell: np.ndarray, kinds: list[str], style: GroundStyle, rng: np.random.Generator) -> np.ndarray:
    """Each field filled with its own patch of its material, drawn over the field's bounding box."""
    img = np.zeros(cell.shape + (3,), np.float32)
    # each field's bounding box in one pass over the image (labels 1..count; None: a field with no pixel)
    boxes = ndimage.find_objects(cell.astype(np.int32) + 1, max_label=len(kinds))
    for k, box in enumerate(boxes):
        if box is None:
            continue
        r0, r1, c0, c1 = box[0].start, box[0].stop, box[1].start, box[1].stop
        side = max(r1 - r0, c1 - c0)
        patch = MATERIALS[kinds[k]](rng, int(side), rng.uniform(0, math.pi), rng.uniform(*style.dryness))
        np.copyto(img[box], patch[: r1 - r0, : c1 - c0], where=(cell[box] == k)[..., None])
    return img


def _polyline(rng: np.random.Generator, n: int, bends: int = 4) -> np.ndarray:
    start = rng.uniform(0, n, 2)
    heading = rng.uniform(0, 2 * math.pi)
    pts = [start]
    for _ in range(bends):
        heading += rng.normal(0, 0.35)
        pts.append(pts[-1] + rng.uniform(0.15, 0.4) * n * np.array([math.cos(heading), math.sin(heading)]))
    return np.array(pts)


def _roads(img, rng, n, count, colour, width_px, lines: bool) -> None:
    for _ in range(count):
        pts = _polyline(rng, n).astype(np.int32)
        w = int(rng.integers(*width_px))
        col = tuple(float(c) * rng.uniform(0.9, 1.1) for c in colour)
        cv2.polylines(img, [pts], False, col, w, cv2.LINE_AA)
        if lines:  # a broken centre line
            cv2.polylines(img, [pts], False, (200, 200, 200), 1, cv2.LINE_4)
        else:  # wheel ruts
            cv2.polylines(img, [pts], False, tuple(c * 0.8 for c in col), max(w // 3, 1), cv2.LINE_AA)


def _ponds(img, style, rng, n, km2) -> None:
    for _ in range(int(round(style.ponds * km2))):
        c = rng.uniform(0, n, 2)
        axes = rng.uniform(10, 80, 2)
        blob = MATERIALS["water"](rng, 256, rng.uniform(0, math.pi), 0.0).mean(axis=(0, 1))
        cv2.ellipse(img, (int(c[0]), int(c[1])), (int(axes[0]), int(axes[1])), rng.uniform(0, 180), 0, 360,
                    tuple(float(v) for v in blob), -1, cv2.LINE_AA)


def _fences(img, rng, n, count) -> None:
    for _ in range(count):
        a = rng.uniform(0, n, 2)
        b = a + rng.normal(0, n / 10, 2)
        cv2.line(img, tuple(int(v) for v in a), tuple(int(v) for v in b), (60, 75, 85), 1, cv2.LINE_AA)


def _buildings(img, style, rng, n, count, shadow) -> None:
    for _ in range(count):
        c = rng.uniform(0, n, 2)
        size = rng.uniform(8, 30, 2)
        angle = rng.uniform(0, 180)
        height_px = rng.uniform(4, 14)
        box = cv2.boxPoints(((float(c[0]), float(c[1])), (float(size[0]), float(size[1])), float(angle)))
        cv2.fillPoly(img, [(box + shadow * height_px).astype(np.int32)], (25, 30, 35), cv2.LINE_AA)
        roof = style.building_colours[int(rng.integers(len(style.building_colours)))]
        cv2.fillPoly(img, [box.astype(np.int32)], tuple(float(v) * rng.uniform(0.85, 1.1) for v in roof), cv2.LINE_AA)
        # the ridge: one half of the roof in the light, one in shade
        mid = 0.5 * (box[0] + box[1]), 0.5 * (box[2] + box[3])
        cv2.line(img, tuple(int(v) for v in mid[0]), tuple(int(v) for v in mid[1]), (40, 40, 45), 1, cv2.LINE_AA)


def _cars(img, rng, n, count, shadow) -> None:
    colours = ((200, 200, 200), (30, 30, 30), (40, 40, 160), (140, 90, 30), (150, 150, 150))
    for _ in range(count):
        base = rng.uniform(0, n, 2)
        angle = rng.uniform(0, 180)
        for k in range(int(rng.integers(1, 6))):  # a few parked side by side
            c = base + k * 5.0 * np.array([math.cos(math.radians(angle + 90)), math.sin(math.radians(angle + 90))])
            box = cv2.boxPoints(((float(c[0]), float(c[1])), (9.0, 4.0), float(angle)))
            cv2.fillPoly(img, [(box + shadow * 2.0).astype(np.int32)], (25, 28, 30), cv2.LINE_AA)
            col = colours[int(rng.integers(len(colours)))]
            cv2.fillPoly(img, [box.astype(np.int32)], col, cv2.LINE_AA)


def _crown(img, c, r, colour, shadow, rng) -> None:
    cv2.circle(img, (int(c[0] + shadow[0] * r * 1.2), int(c[1] + shadow[1] * r * 1.2)), int(r), (15, 25, 20), -1, cv2.LINE_AA)
    col = np.asarray(colour, float) * rng.uniform(0.7, 1.25)
    cv2.circle(img, (int(c[0]), int(c[1])), int(r), tuple(col), -1, cv2.LINE_AA)
    lit = c - shadow * r * 0.35
    cv2.circle(img, (int(lit[0]), int(lit[1])), max(int(r * 0.5), 1), tuple(np.clip(col * 1.3, 0, 255)), -1, cv2.LINE_AA)


def _trees(img, style, rng, n, trees, lines, bushes, shadow) -> None:
    for _ in range(lines):
        a = rng.uniform(0, n, 2)
        b = a + rng.normal(0, n / 6, 2)
        for s in np.linspace(0.0, 1.0, int(np.linalg.norm(b - a) / 6) + 2):
            _crown(img, a + s * (b - a) + rng.normal(0, 2.0, 2), rng.uniform(4, 10), style.tree_colour, shadow, rng)
    for _ in range(trees):
        _crown(img, rng.uniform(0, n, 2), rng.uniform(3, 9), style.tree_colour, shadow, rng)
    for _ in range(bushes):
        _crown(img, rng.uniform(0, n, 2), rng.uniform(1, 3), style.tree_colour, shadow, rng)


def _detail_tile(rng: np.random.Generator) -> np.ndarray:
    """A tileable grain (uint8, 128 = no change) of stalks, pebbles and clods at 2.5 cm a pixel."""
    n = _DETAIL_PX
    def wrapped_blur(sigma: float) -> np.ndarray:  # blurred across the tile's edges, so it tiles seamlessly
        big = cv2.GaussianBlur(np.tile(rng.standard_normal((n, n)).astype(np.float32), (3, 3)), (0, 0), sigma)
        return big[n:2 * n, n:2 * n]

    fine, clods = wrapped_blur(0.8), wrapped_blur(4.0)
    tile = fine / max(float(fine.std()), 1e-6) * 0.6 + clods / max(float(clods.std()), 1e-6) * 0.4
    return np.clip(128 + 14 * tile, 0, 255).astype(np.uint8)  # +-11 % of the ground's brightness (1 sigma)
