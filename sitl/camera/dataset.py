"""Labelled camera datasets from the renderer, in YOLO txt format (paper appendix: the model card's data).

:func:`sample_frame` draws one random view: a chaser pose (altitude, yaw, some roll and pitch), the
lighting and sensor settings, and zero to two targets placed along random rays at a distance that
gives them an apparent span between ``span_px`` pixels (at the frame's width). The ``split`` picks
disjoint ground seeds and shifted lighting ranges, so a held-out set differs from training in seed,
background and lighting. :func:`write_dataset` writes ``images/NNNNNN.jpg`` and ``labels/NNNNNN.txt``
(``class cx cy w h``, normalised) plus ``classes.txt``, optionally as mosaics with HSV and scale
jitter (:mod:`chaser_bt.vision.detector.augment`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detector.augment import hsv_jitter, mosaic
from sitl.camera.models import model_for
from sitl.camera.renderer import Lighting, RenderedFrame, Renderer, TargetPose
from sitl.camera.scene import make_ground

__all__ = ["CLASSES", "SplitSpec", "SPLITS", "DatasetRenderer", "write_dataset", "read_yolo_labels"]

CLASSES: tuple[str, ...] = ("s1000", "phantom")


@dataclass(frozen=True)
class SplitSpec:
    """What varies between a training and a held-out set."""

    ground_seeds: tuple[int, ...]
    sun_elevation_deg: tuple[float, float]
    brightness: tuple[float, float]
    span_px: tuple[float, float] = (8.0, 160.0)


SPLITS: dict[str, SplitSpec] = {
    "train": SplitSpec(ground_seeds=(0, 1, 2, 3, 4, 5), sun_elevation_deg=(25.0, 75.0), brightness=(0.75, 1.25)),
    "heldout": SplitSpec(ground_seeds=(1001, 1002), sun_elevation_deg=(12.0, 85.0), brightness=(0.65, 1.35)),
}


class DatasetRenderer:
    """Random labelled frames for one split (see module docstring)."""

    def __init__(self, split: str = "train", width_px: int = 640, height_px: int = 480, ground_size_px: int = 2048) -> None:
        if split not in SPLITS:
            raise ValueError(f"unknown split {split!r}; known: {sorted(SPLITS)}")
        self.spec = SPLITS[split]
        self.camera = CameraModel(width_px=width_px, height_px=height_px)
        self.renderers = [Renderer(self.camera, make_ground(s, ground_size_px), noise_seed=s) for s in self.spec.ground_seeds]

    def sample(self, rng: np.random.Generator) -> RenderedFrame:
        spec = self.spec
        renderer = self.renderers[int(rng.integers(len(self.renderers)))]
        cam = self.camera
        pos = np.array([rng.uniform(-300, 300), rng.uniform(-300, 300), rng.uniform(4.0, 60.0)])
        att = Rotation.from_euler("ZYX", [rng.uniform(-math.pi, math.pi), rng.normal(0, math.radians(8)), rng.normal(0, math.radians(8))])
        zen = np.array([200.0, 140.0, 90.0]) * rng.uniform(0.8, 1.15, 3)
        light = Lighting(
            sun_azimuth_rad=rng.uniform(-math.pi, math.pi),
            sun_elevation_rad=math.radians(rng.uniform(*spec.sun_elevation_deg)),
            brightness=rng.uniform(*spec.brightness),
            haze_m=rng.uniform(400.0, 2000.0),
            sky_zenith=tuple(zen.clip(0, 255)),
            sky_horizon=tuple((np.array([235.0, 215.0, 200.0]) * rng.uniform(0.85, 1.08, 3)).clip(0, 255)),
            noise_sigma=rng.uniform(1.0, 6.0),
            jpeg_quality=int(rng.integers(40, 96)),
        )
        n = int(rng.choice([0, 1, 2], p=[0.1, 0.75, 0.15]))
        targets = []
        fx = cam.focal_px[0]
        for _ in range(n):
            kind = CLASSES[int(rng.integers(len(CLASSES)))]
            span = model_for(kind).span_m
            for _try in range(10):
                px = math.exp(rng.uniform(math.log(spec.span_px[0]), math.log(spec.span_px[1])))
                dist = max(span * fx / px, 1.5)
                pix = np.array([[rng.uniform(0.03, 0.97) * cam.width_px, rng.uniform(0.03, 0.97) * cam.height_px]])
                ray = cam.ray_enu(pix, att)[0]
                p = cam.position_enu(pos, att) + dist * ray
                if p[2] > 0.7:
                    break
            else:
                continue
            t_att = Rotation.from_euler("ZYX", [rng.uniform(-math.pi, math.pi), rng.normal(0, math.radians(10)), rng.normal(0, math.radians(10))])
            targets.append(TargetPose(kind, p, t_att))
        blur = rng.uniform(2.0, 8.0) if rng.random() < 0.4 else 0.0
        return renderer.render(pos, att, targets, light, rng, blur_px=blur, blur_angle_rad=rng.uniform(0, math.pi))


def _yolo_lines(boxes: np.ndarray, width: int, height: int) -> list[str]:
    lines = []
    for c, x0, y0, x1, y1 in boxes:
        lines.append(f"{int(c)} {(x0 + x1) / 2 / width:.6f} {(y0 + y1) / 2 / height:.6f} {(x1 - x0) / width:.6f} {(y1 - y0) / height:.6f}")
    return lines


def frame_boxes(frame: RenderedFrame) -> np.ndarray:
    """(N, 5) class, x0, y0, x1, y1 of a rendered frame's labels."""
    return np.array([[CLASSES.index(lab.kind), *lab.box] for lab in frame.labels], float).reshape(-1, 5)


def write_dataset(out_dir: str | Path, count: int, seed: int, split: str = "train", mosaic_size: int = 0,
                  width_px: int = 640, height_px: int = 480) -> Path:
    """Render ``count`` labelled frames into ``out_dir`` (YOLO layout); ``mosaic_size`` > 0 writes HSV-jittered mosaics."""
    out = Path(out_dir)
    (out / "images").mkdir(parents=True, exist_ok=True)
    (out / "labels").mkdir(parents=True, exist_ok=True)
    (out / "classes.txt").write_text("\n".join(CLASSES) + "\n")
    rng = np.random.default_rng(seed)
    source = DatasetRenderer(split, width_px, height_px)
    for i in range(count):
        if mosaic_size > 0:
            frames = [source.sample(rng) for _ in range(4)]
            image, boxes = mosaic([f.image for f in frames], [frame_boxes(f) for f in frames], mosaic_size, rng)
            image = hsv_jitter(image, rng)
        else:
            f = source.sample(rng)
            image, boxes = f.image, frame_boxes(f)
        cv2.imwrite(str(out / "images" / f"{i:06d}.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, 95])
        h, w = image.shape[:2]
        (out / "labels" / f"{i:06d}.txt").write_text("\n".join(_yolo_lines(boxes, w, h)) + ("\n" if len(boxes) else ""))
    return out


def read_yolo_labels(path: str | Path, width: int, height: int) -> np.ndarray:
    """A YOLO label file back to (N, 5) class, x0, y0, x1, y1 pixels."""
    rows = [line.split() for line in Path(path).read_text().splitlines() if line.strip()]
    out = []
    for r in rows:
        c, cx, cy, bw, bh = int(r[0]), float(r[1]) * width, float(r[2]) * height, float(r[3]) * width, float(r[4]) * height
        out.append([c, cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2])
    return np.array(out, float).reshape(-1, 5)


def main(argv: list[str] | None = None) -> int:
    """``python -m sitl.camera.dataset OUT --count N --seed S --split train|heldout [--mosaic 416]``."""
    import argparse

    p = argparse.ArgumentParser(prog="python -m sitl.camera.dataset", description="Render a labelled YOLO dataset.")
    p.add_argument("out")
    p.add_argument("--count", type=int, default=3000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--split", choices=sorted(SPLITS), default="train")
    p.add_argument("--mosaic", type=int, default=0, help="write HSV-jittered mosaics of this size")
    a = p.parse_args(argv)
    write_dataset(a.out, a.count, a.seed, a.split, mosaic_size=a.mosaic)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
