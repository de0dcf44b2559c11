"""Labelled camera datasets from the renderer, in YOLO txt format (paper appendix: the model card's data).

:func:`sample_frame` draws one random view: a chaser pose (altitude, yaw, some roll and pitch), the
lighting and sensor settings, and zero to two targets placed along random rays at a distance that
gives them an apparent span between ``span_px`` pixels (at the frame's width); people (kind
"person", for search and rescue) stand or lie on the ground where a random pixel's ray meets it,
kept when they span at least ``min_person_px``. ``follow_share`` of the drone frames are chase
views instead: the chaser behind and above one target 15-120 px wide, nose on it (the pipeline's
use, targets against the ground). ``kinds`` picks the classes drawn (and written to
``classes.txt`` in that order). The ``split`` picks
disjoint ground seeds and shifted lighting ranges, so a held-out set differs from training in seed,
background and lighting. :func:`write_dataset` writes ``images/NNNNNN.jpg`` and ``labels/NNNNNN.txt``
(``class cx cy w h``, normalised) plus ``classes.txt``, optionally as mosaics with HSV and scale
jitter (:mod:`chaser_bt.vision.detector.augment`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detector.augment import hsv_jitter, mosaic
from sitl.world.camera.models import PERSON_HEIGHT_M, model_for, variant_count
from sitl.world.camera.renderer import (
    Lighting,
    RenderedFrame,
    Renderer,
    TargetPose,
    attitude_from_velocity,
)
from sitl.world.camera.scene import make_ground
from sitl.world.camera.world import FAMILIES, WorldSpec, build_world

__all__ = ["CLASSES", "PERSON_CLASSES", "SplitSpec", "SPLITS", "DatasetRenderer", "write_dataset", "read_yolo_labels"]

CLASSES: tuple[str, ...] = ("s1000", "phantom")
PERSON_CLASSES: tuple[str, ...] = ("person",)


@dataclass(frozen=True)
class SplitSpec:
    """What varies between a training and a held-out set."""

    ground_seeds: tuple[int, ...]
    sun_elevation_deg: tuple[float, float]
    brightness: tuple[float, float]
    span_px: tuple[float, float] = (8.0, 160.0)
    min_person_px: float = 10.0  # a person's 1.75 m length, at its distance
    person_altitude_m: tuple[float, float] = (4.0, 40.0)  # search altitudes for people-only sets


SPLITS: dict[str, SplitSpec] = {
    "train": SplitSpec(ground_seeds=(0, 1, 2, 3, 4, 5), sun_elevation_deg=(25.0, 75.0), brightness=(0.75, 1.25)),
    # The training lighting over four times the grounds (the sixth session's fine-tune: fewer false boxes on unseen ground).
    "train_wide": SplitSpec(ground_seeds=tuple(range(24)), sun_elevation_deg=(25.0, 75.0), brightness=(0.75, 1.25)),
    "heldout": SplitSpec(ground_seeds=(1001, 1002), sun_elevation_deg=(12.0, 85.0), brightness=(0.65, 1.35)),
}


class DatasetRenderer:
    """Random labelled frames for one split (see module docstring)."""

    def __init__(self, split: str = "train", width_px: int = 640, height_px: int = 480, ground_size_px: int = 2048,
                 kinds: tuple[str, ...] = CLASSES, follow_share: float = 0.0, families: tuple[str, ...] = ()) -> None:
        """``families``: camera-world families (:mod:`sitl.world.camera.world`) to render in, one world
        per family and split ground seed, each frame at a random time (birds, drift) in the world's
        lighting, jittered; empty: the plain field under random lighting."""
        if split not in SPLITS:
            raise ValueError(f"unknown split {split!r}; known: {sorted(SPLITS)}")
        if not kinds:
            raise ValueError("kinds: at least one target kind is needed")
        for k in kinds:
            model_for(k)  # a ValueError naming the known kinds
        if not 0.0 <= follow_share <= 1.0:
            raise ValueError(f"follow_share must be in [0, 1], got {follow_share}")
        self.kinds = tuple(kinds)
        self.follow_share = follow_share
        self.spec = SPLITS[split]
        self.camera = CameraModel(width_px=width_px, height_px=height_px)
        self.worlds = [build_world(WorldSpec(f), s, width_px, height_px) for f in families for s in self.spec.ground_seeds]
        if self.worlds:
            self.renderers = [Renderer(self.camera, world=w, noise_seed=k) for k, w in enumerate(self.worlds)]
        else:
            self.renderers = [Renderer(self.camera, make_ground(s, ground_size_px), noise_seed=s) for s in self.spec.ground_seeds]

    def sample(self, rng: np.random.Generator) -> RenderedFrame:
        spec = self.spec
        index = int(rng.integers(len(self.renderers)))
        renderer = self.renderers[index]
        cam = self.camera
        people_only = self.kinds == ("person",)
        alt = spec.person_altitude_m if people_only else (4.0, 60.0)
        pos = np.array([rng.uniform(-300, 300), rng.uniform(-300, 300), rng.uniform(*alt)])
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
        t = 0.0
        if self.worlds:
            world_light = self.worlds[index].lighting
            light = dataclasses.replace(world_light, brightness=world_light.brightness * rng.uniform(0.85, 1.15),
                                        noise_sigma=light.noise_sigma, jpeg_quality=light.jpeg_quality)
            t = float(rng.uniform(0.0, 600.0))
        airborne = [k for k in self.kinds if k != "person"]
        if self.follow_share > 0 and airborne and rng.random() < self.follow_share:
            return self._follow_view(renderer, light, airborne[int(rng.integers(len(airborne)))], rng, t)
        n = int(rng.choice([0, 1, 2, 3], p=[0.1, 0.6, 0.2, 0.1])) if people_only else int(rng.choice([0, 1, 2], p=[0.1, 0.75, 0.15]))
        targets = []
        fx = cam.focal_px[0]
        for _ in range(n):
            kind = self.kinds[int(rng.integers(len(self.kinds)))]
            if kind == "person":
                person = _person_on_ground(cam, pos, att, spec.min_person_px, rng)
                if person is not None:
                    targets.append(person)
                continue
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
        return renderer.render(pos, att, targets, light, rng, blur_px=blur, blur_angle_rad=rng.uniform(0, math.pi), t=t)

    def _follow_view(self, renderer: Renderer, light: Lighting, kind: str, rng: np.random.Generator,
                     t: float = 0.0) -> RenderedFrame:
        """The chaser 5-35 deg above and behind a ``kind`` target, nose on it give or take a few degrees."""
        cam = self.camera
        px = math.exp(rng.uniform(math.log(15.0), math.log(120.0)))
        d = max(model_for(kind).span_m * cam.focal_px[0] / px, 3.0)
        tp = np.array([rng.uniform(-300, 300), rng.uniform(-300, 300), rng.uniform(8.0, 60.0)])
        heading = rng.uniform(-math.pi, math.pi)
        elev = math.radians(rng.uniform(5.0, 35.0))
        pos = tp + d * np.array([-math.cos(elev) * math.cos(heading), -math.cos(elev) * math.sin(heading), math.sin(elev)])
        att = Rotation.from_euler("ZYX", [heading + rng.normal(0, math.radians(6)), elev - cam.tilt_rad + rng.normal(0, math.radians(4)),
                                          rng.normal(0, math.radians(4))])
        speed = rng.uniform(0.0, 8.0)
        course = heading + rng.normal(0, math.radians(30))
        t_att = attitude_from_velocity(np.array([speed * math.cos(course), speed * math.sin(course), 0.0]))
        blur = rng.uniform(2.0, 8.0) if rng.random() < 0.4 else 0.0
        return renderer.render(pos, att, [TargetPose(kind, tp, t_att)], light, rng, blur_px=blur,
                               blur_angle_rad=rng.uniform(0, math.pi), t=t)


def _person_on_ground(cam: CameraModel, pos: np.ndarray, att: Rotation, min_px: float, rng: np.random.Generator) -> TargetPose | None:
    """A standing (50 %) or lying person where a random pixel's ray meets the ground, or None when ten
    tries give no ground point near enough to span ``min_px`` pixels."""
    c = cam.position_enu(pos, att)
    for _try in range(10):
        pix = np.array([[rng.uniform(0.03, 0.97) * cam.width_px, rng.uniform(0.03, 0.97) * cam.height_px]])
        ray = cam.ray_enu(pix, att)[0]
        if ray[2] > -0.02:
            continue
        d = c[2] / -ray[2]
        if PERSON_HEIGHT_M * cam.focal_px[0] / d < min_px:
            continue
        p = c + d * ray
        yaw = rng.uniform(-math.pi, math.pi)
        variant = int(rng.integers(variant_count("person")))
        if rng.random() < 0.5:
            return TargetPose("person", np.array([p[0], p[1], 0.0]), Rotation.from_euler("Z", [yaw]), variant)
        # Lying on the back or front: the body's up axis turned horizontal, the torso's half-depth above ground.
        roll = math.pi / 2 if rng.random() < 0.5 else -math.pi / 2
        return TargetPose("person", np.array([p[0], p[1], 0.16]), Rotation.from_euler("ZX", [yaw, roll]), variant)
    return None


def _yolo_lines(boxes: np.ndarray, width: int, height: int) -> list[str]:
    lines = []
    for c, x0, y0, x1, y1 in boxes:
        lines.append(f"{int(c)} {(x0 + x1) / 2 / width:.6f} {(y0 + y1) / 2 / height:.6f} {(x1 - x0) / width:.6f} {(y1 - y0) / height:.6f}")
    return lines


def frame_boxes(frame: RenderedFrame, classes: tuple[str, ...] = CLASSES) -> np.ndarray:
    """(N, 5) class (index in ``classes``), x0, y0, x1, y1 of a rendered frame's labels."""
    return np.array([[classes.index(lab.kind), *lab.box] for lab in frame.labels], float).reshape(-1, 5)


def write_dataset(out_dir: str | Path, count: int, seed: int, split: str = "train", mosaic_size: int = 0,
                  width_px: int = 640, height_px: int = 480, kinds: tuple[str, ...] = CLASSES, follow_share: float = 0.0,
                  ground_size_px: int = 2048, families: tuple[str, ...] = ()) -> Path:
    """Render ``count`` labelled frames of ``kinds`` into ``out_dir`` (YOLO layout, class ids in ``kinds``
    order); ``mosaic_size`` > 0 writes HSV-jittered mosaics."""
    kinds = tuple(kinds)
    source = DatasetRenderer(split, width_px, height_px, ground_size_px, kinds=kinds, follow_share=follow_share,
                             families=tuple(families))
    out = Path(out_dir)
    (out / "images").mkdir(parents=True, exist_ok=True)
    (out / "labels").mkdir(parents=True, exist_ok=True)
    (out / "classes.txt").write_text("\n".join(kinds) + "\n")
    rng = np.random.default_rng(seed)
    for i in range(count):
        if mosaic_size > 0:
            frames = [source.sample(rng) for _ in range(4)]
            image, boxes = mosaic([f.image for f in frames], [frame_boxes(f, kinds) for f in frames], mosaic_size, rng)
            image = hsv_jitter(image, rng)
        else:
            f = source.sample(rng)
            image, boxes = f.image, frame_boxes(f, kinds)
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
    """``python -m sitl.bench.camera_dataset OUT --count N --seed S --split train|heldout [--mosaic 416] [--kinds person]``."""
    import argparse

    p = argparse.ArgumentParser(prog="python -m sitl.bench.camera_dataset", description="Render a labelled YOLO dataset.")
    p.add_argument("out")
    p.add_argument("--count", type=int, default=3000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--split", choices=sorted(SPLITS), default="train")
    p.add_argument("--mosaic", type=int, default=0, help="write HSV-jittered mosaics of this size")
    p.add_argument("--kinds", nargs="+", default=list(CLASSES), help="target kinds drawn, in class-id order (e.g. person)")
    p.add_argument("--follow-share", type=float, default=0.0, help="share of drone frames drawn as chase views (0..1)")
    p.add_argument("--families", nargs="+", default=[], choices=sorted(FAMILIES), metavar="FAMILY",
                   help=f"render in these camera-world families ({', '.join(FAMILIES)}); default: the plain field")
    a = p.parse_args(argv)
    try:
        write_dataset(a.out, a.count, a.seed, a.split, mosaic_size=a.mosaic, kinds=tuple(a.kinds), follow_share=a.follow_share,
                      families=tuple(a.families))
    except ValueError as e:
        p.error(f"--kinds: {e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
