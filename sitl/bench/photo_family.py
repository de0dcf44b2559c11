"""The ``photo`` family: drones, or people, drawn over photographs, an independent test of the drone
detector and of the search-and-rescue person detector.

Neither half comes from what the detector learns on. The backgrounds are scikit-image's bundled
sample photographs of outdoor scenes (grass, gravel, brick, a launch site against the sky, a man
with a camera on a lawn before buildings), a source reserved for testing that never enters
training. The drones are drawn here, by code of their own and not the renderer's models: multirotors
of four, six or eight arms, seen from 15-75 degrees above, 8-80 px across, in several colours, with
rotor discs, sometimes landing gear, drawn at four times the size and shrunk (anti-aliasing), then
the frame blurred a little, given sensor noise and JPEG-compressed. People (``kind="person"``) are
drawn the same way, as a searcher sees them: standing or lying, seen from 25-90 degrees above, 1.75 m
long at 10-80 px, with head, hair, arms, legs and torso in clothing colours of their own. A label is
the tight box of the drawn pixels (coverage >= 25 %).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

__all__ = ["PHOTOS", "KINDS", "PhotoFamily", "PhotoFrame", "draw_multirotor", "draw_person", "write_folder"]

#: scikit-image's sample photographs used as backgrounds (``skimage.data.<name>``).
PHOTOS = ("grass", "gravel", "brick", "rocket", "camera")
_COLOURS = {"white": (235, 235, 235), "light grey": (170, 170, 170), "dark grey": (70, 70, 70), "black": (25, 25, 25),
            "red": (40, 40, 200), "yellow": (40, 200, 220), "blue": (170, 90, 30)}
_SUPERSAMPLE = 4
#: What a family's frames hold: drones, or people for the search-and-rescue detector.
KINDS = ("drone", "person")
_CLOTHES = ((30, 30, 180), (160, 110, 40), (0, 165, 255), (50, 110, 60), (200, 200, 205), (30, 30, 30), (120, 60, 140),
            (60, 200, 230), (110, 110, 110), (140, 170, 200))
_SKIN = ((160, 190, 230), (110, 140, 185), (60, 85, 125))


@dataclass(frozen=True)
class PhotoFrame:
    """One test frame: BGR ``image`` and (N, 5) ``boxes`` (class 0, x0, y0, x1, y1 in pixels)."""

    image: np.ndarray
    boxes: np.ndarray


def draw_multirotor(span_px: float, arms: int, elevation_deg: float, yaw_deg: float, colour: tuple[int, int, int],
                    gear: bool) -> tuple[np.ndarray, np.ndarray]:
    """A multirotor ``span_px`` across (motor to motor), seen from ``elevation_deg`` above: (BGR patch,
    coverage in [0, 1]), both of the same size, the drone centred."""
    s = _SUPERSAMPLE
    half = int(math.ceil(span_px * 0.75 * s)) + 2 * s
    size = 2 * half + 1
    img = np.zeros((size, size, 3), np.float32)
    cover = np.zeros((size, size), np.float32)
    squash = math.sin(math.radians(elevation_deg))
    reach = span_px / 2 * s
    rotor = max(span_px * 0.2 * s, 1.5 * s)
    arm_w = max(int(round(span_px * 0.05 * s)), s)
    dark = tuple(int(c * 0.5) for c in colour)

    def to_px(x: float, y: float, z: float = 0.0) -> tuple[int, int]:
        # Image x right, y down: the horizontal plane squashed by the elevation, height up by its cosine.
        return int(round(half + x)), int(round(half + y * squash - z * math.cos(math.radians(elevation_deg))))

    def paint(layer: np.ndarray, bgr, alpha: float) -> None:
        m = layer.astype(np.float32) * alpha
        img[:] = img * (1 - m[..., None]) + np.asarray(bgr, np.float32) * m[..., None]
        cover[:] = np.maximum(cover, m)

    tips = []
    for k in range(arms):
        a = math.radians(yaw_deg + 360.0 * (k + 0.5) / arms)
        tips.append((reach * math.cos(a), reach * math.sin(a)))
    if gear:
        layer = np.zeros_like(cover, np.uint8)
        for dx in (-reach * 0.35, reach * 0.35):
            cv2.line(layer, to_px(dx, 0), to_px(dx, 0, -reach * 0.45), 1, max(arm_w // 2, 1))
        paint(layer, dark, 1.0)
    for x, y in sorted(tips, key=lambda t: t[1]):  # far arms first
        layer = np.zeros_like(cover, np.uint8)
        cv2.line(layer, to_px(0, 0), to_px(x, y), 1, arm_w)
        paint(layer, dark, 1.0)
        layer = np.zeros_like(cover, np.uint8)
        cv2.ellipse(layer, to_px(x, y), (int(rotor), max(int(rotor * squash), 1)), 0, 0, 360, 1, -1)
        paint(layer, (150, 150, 150), 0.45)  # a spinning rotor: a translucent disc
        layer = np.zeros_like(cover, np.uint8)
        cv2.circle(layer, to_px(x, y), max(arm_w, s), 1, -1)
        paint(layer, dark, 1.0)
    body = reach * 0.32
    layer = np.zeros_like(cover, np.uint8)
    cv2.ellipse(layer, to_px(0, 0), (int(body), max(int(body * max(squash, 0.45)), s)), 0, 0, 360, 1, -1)
    paint(layer, colour, 1.0)
    small = (size // s, size // s)
    return (cv2.resize(img, small, interpolation=cv2.INTER_AREA),
            cv2.resize(cover, small, interpolation=cv2.INTER_AREA))


def draw_person(length_px: float, lying: bool, elevation_deg: float, yaw_deg: float, top: tuple[int, int, int],
                legs: tuple[int, int, int], skin: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """A person 1.75 m tall drawn ``length_px`` per 1.75 m, standing or ``lying``, seen from ``elevation_deg``
    above (orthographic): (BGR patch, coverage in [0, 1]), of the same size, the person centred."""
    s = _SUPERSAMPLE
    unit = length_px * s / 1.75  # px per metre
    half = int(math.ceil(length_px * 0.7 * s)) + 2 * s
    size = 2 * half + 1
    img = np.zeros((size, size, 3), np.float32)
    cover = np.zeros((size, size), np.float32)
    el, yaw = math.radians(elevation_deg), math.radians(yaw_deg)

    def to_px(x: float, y: float, z: float) -> tuple[int, int]:
        # Body metres (x forward, y left, z up; lying: the body axis along x) -> image, centred on the hips.
        if lying:
            x, z = z - 0.9, 0.15 + x
        else:
            z -= 0.9
        gx, gy = x * math.cos(yaw) - y * math.sin(yaw), x * math.sin(yaw) + y * math.cos(yaw)
        return int(round(half + gx * unit)), int(round(half + (gy * math.sin(el) - z * math.cos(el)) * unit))

    def limb(a: tuple[float, float, float], b: tuple[float, float, float], width_m: float, bgr) -> None:
        layer = np.zeros_like(cover, np.uint8)
        cv2.line(layer, to_px(*a), to_px(*b), 1, max(int(round(width_m * unit)), 1))
        m = layer.astype(np.float32)
        img[:] = img * (1 - m[..., None]) + np.asarray(bgr, np.float32) * m[..., None]
        cover[:] = np.maximum(cover, m)

    def blob(c: tuple[float, float, float], r_m: float, bgr) -> None:
        layer = np.zeros_like(cover, np.uint8)
        cv2.circle(layer, to_px(*c), max(int(round(r_m * unit)), 1), 1, -1)
        m = layer.astype(np.float32)
        img[:] = img * (1 - m[..., None]) + np.asarray(bgr, np.float32) * m[..., None]
        cover[:] = np.maximum(cover, m)

    for side in (-1.0, 1.0):
        limb((0.0, side * 0.1, 0.9), (0.05 * side, side * 0.12, 0.05), 0.14, legs)
        blob((0.08, side * 0.12, 0.04), 0.06, (35, 35, 40))  # shoes
    limb((0.0, 0.0, 0.92), (0.0, 0.0, 1.42), 0.36, top)
    for side in (-1.0, 1.0):
        limb((0.0, side * 0.22, 1.42), (0.1, side * 0.3, 0.95), 0.09, top)
        blob((0.12, side * 0.3, 0.9), 0.05, skin)
    blob((0.0, 0.0, 1.62), 0.11, skin)
    blob((-0.03, 0.0, 1.66), 0.1, tuple(int(c * 0.3) for c in legs))  # hair
    small = (size // s, size // s)
    return (cv2.resize(img, small, interpolation=cv2.INTER_AREA),
            cv2.resize(cover, small, interpolation=cv2.INTER_AREA))


class PhotoFamily:
    """Frames of the ``photo`` family (see the module docstring) of ``kind`` (:data:`KINDS`), ``width`` x ``height``.

    Raises:
        ImportError: scikit-image is not installed (``pip install scikit-image``).
    """

    def __init__(self, width: int = 640, height: int = 480, kind: str = "drone") -> None:
        import skimage.data

        if kind not in KINDS:
            raise ValueError(f"photo family kind {kind!r}: one of {', '.join(KINDS)}")
        self.width, self.height, self.kind = width, height, kind
        self.photos = []
        for name in PHOTOS:
            photo = getattr(skimage.data, name)()
            photo = cv2.cvtColor(photo, cv2.COLOR_GRAY2BGR) if photo.ndim == 2 else cv2.cvtColor(photo, cv2.COLOR_RGB2BGR)
            self.photos.append(photo)

    def _background(self, rng: np.random.Generator) -> np.ndarray:
        photo = self.photos[int(rng.integers(len(self.photos)))]
        h, w = photo.shape[:2]
        scale = max(self.width / w, self.height / h) * rng.uniform(1.0, 2.5)
        big = cv2.resize(photo, (int(math.ceil(w * scale)), int(math.ceil(h * scale))), interpolation=cv2.INTER_LINEAR)
        y0 = int(rng.integers(big.shape[0] - self.height + 1))
        x0 = int(rng.integers(big.shape[1] - self.width + 1))
        out = big[y0:y0 + self.height, x0:x0 + self.width].astype(np.float32)
        if rng.random() < 0.5:
            out = out[:, ::-1]
        tint = rng.uniform(0.85, 1.15, 3) * rng.uniform(0.7, 1.2)
        return out * tint

    def sample(self, rng: np.random.Generator) -> PhotoFrame:
        """One frame with one or two drones, or people (30 % two)."""
        img = self._background(rng)
        boxes = []
        for _ in range(1 + int(rng.random() < 0.3)):
            if self.kind == "person":
                patch, cover = draw_person(float(np.exp(rng.uniform(math.log(10), math.log(80)))), bool(rng.random() < 0.5),
                                           rng.uniform(25, 90), rng.uniform(0, 360), _CLOTHES[int(rng.integers(len(_CLOTHES)))],
                                           _CLOTHES[int(rng.integers(len(_CLOTHES)))], _SKIN[int(rng.integers(len(_SKIN)))])
            else:
                patch, cover = draw_multirotor(float(np.exp(rng.uniform(math.log(8), math.log(80)))), int(rng.choice([4, 6, 8])),
                                               rng.uniform(15, 75), rng.uniform(0, 360),
                                               list(_COLOURS.values())[int(rng.integers(len(_COLOURS)))], bool(rng.random() < 0.4))
            ph, pw = cover.shape
            cx = int(rng.integers(pw // 2, self.width - pw // 2)) if pw < self.width else self.width // 2
            cy = int(rng.integers(ph // 2, self.height - ph // 2)) if ph < self.height else self.height // 2
            x0, y0 = cx - pw // 2, cy - ph // 2
            region = img[y0:y0 + ph, x0:x0 + pw]
            region[:] = region * (1 - cover[..., None]) + patch * cover[..., None]
            ys, xs = np.nonzero(cover >= 0.25)
            if len(xs):
                boxes.append([0, x0 + xs.min(), y0 + ys.min(), x0 + xs.max() + 1, y0 + ys.max() + 1])
        img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.3, 0.9))
        img = img + rng.normal(0.0, rng.uniform(1.0, 4.0), img.shape)
        ok, jpg = cv2.imencode(".jpg", np.clip(img, 0, 255).astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(80, 96))])
        assert ok
        return PhotoFrame(cv2.imdecode(jpg, cv2.IMREAD_COLOR), np.array(boxes, float).reshape(-1, 5))


def write_folder(out: str | Path, count: int, seed: int, kind: str = "drone") -> Path:
    """``count`` frames of the family of ``kind`` as a YOLO folder (class ``drone`` or ``person``) that
    ``chaser-bt eval-detector --class-agnostic`` reads; seed 780 draws the benchmark's frames."""
    from chaser_bt.vision.footage.yolo_folder import box_line, prepare_parts, write_example

    root = Path(out)
    family, rng = PhotoFamily(kind=kind), np.random.default_rng(seed)
    prepare_parts(root, ("",), (kind,))
    for k in range(count):
        frame = family.sample(rng)
        h, w = frame.image.shape[:2]
        lines = [box_line(0, x0, y0, x1, y1, w, h) for _, x0, y0, x1, y1 in frame.boxes]
        write_example(root, f"photo_{kind}_{k:06d}", frame.image, [x for x in lines if x is not None])
    return root


def main(argv: list[str] | None = None) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="python -m sitl.bench.photo_family", description=write_folder.__doc__)
    p.add_argument("out")
    p.add_argument("--count", type=int, default=150)
    p.add_argument("--seed", type=int, default=780)
    p.add_argument("--kind", choices=KINDS, default="drone")
    args = p.parse_args(argv)
    print(write_folder(args.out, args.count, args.seed, args.kind))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
