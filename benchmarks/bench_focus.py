"""What the detector's focus window buys (chaser_bt/vision/focus.py), on rendered S1000 views.

Two geometries, rendered at 640 x 480 with the shipped detector (one thread):

- acquisition: the chaser 30 m up looking level at a target 100-250 m out near the horizon; the
  share of views where a box is on the target, and false boxes per view, for the whole frame and
  for windows at 2x and 3x around the target's projection (as a cue would put them, 8 px off);
- follow: the chaser 25 or 40 m from the target looking down 40 deg; the median box-centre error
  (px) and the median ratio of box width to the target's true box width, whole frame vs windows.

Prints one JSON line. Run: .venv/bin/python benchmarks/bench_focus.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import torch
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from chaser_bt.vision.camera import CameraModel  # noqa: E402
from chaser_bt.vision.detector.inference import Detector  # noqa: E402
from chaser_bt.vision.focus import FocusWindow  # noqa: E402
from sitl.world.camera.renderer import Lighting, Renderer, TargetPose, attitude_from_velocity  # noqa: E402
from sitl.world.camera.scene import make_ground  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402

ZOOMS = (0.0, 2.0, 3.0)  # 0: the whole frame
BENCHMARK = Benchmark(
    "focus", __doc__,
    against="built-in simulator's rendered S1000 views (640 x 480), the shipped detector on one thread",
    units={
        "views_per_range": "rendered views per range",
        "acq_*_found_*": "share of views with a box on the target (_whole: the whole frame; _x2, _x3: the focus window)",
        "acq_*_false_per_view_*": "boxes off the target per view",
        "follow_*_centre_err_px_median_*": "px, median box-centre error",
        "follow_*_width_ratio_median_*": "median of the box's width over the target's true box width",
    },
    headline=("acq_250m_found_whole", "acq_250m_found_x3", "acq_250m_false_per_view_x3",
              "follow_25m_centre_err_px_median_whole"),
)


def _window(centre: tuple[float, float], zoom: float, size: tuple[int, int]) -> FocusWindow:
    side = int(round(416 / zoom))
    x0 = int(min(max(centre[0] - side / 2, 0), size[0] - side))
    y0 = int(min(max(centre[1] - side / 2, 0), size[1] - side))
    return FocusWindow(x0, y0, side, 416 / side)


def _detect(det: Detector, image: np.ndarray, zoom: float, centre: tuple[float, float]) -> list:
    if zoom == 0.0:
        return det(image)
    w = _window(centre, zoom, (image.shape[1], image.shape[0]))
    return [type(d)(w.to_frame(d.box), d.score, d.class_id, d.class_name) for d in det(w.crop(image))]


def _on(box, d) -> bool:
    return box[0] <= d.centre[0] <= box[2] and box[1] <= d.centre[1] <= box[3]


def acquisition(det: Detector, n: int, rng: np.random.Generator) -> dict:
    cam = CameraModel(width_px=640, height_px=480)
    renderer = Renderer(cam, make_ground(1004))
    att = Rotation.from_euler("ZYX", [math.pi / 2, 0.0, 0.0])
    out = {}
    for r in (100, 150, 200, 250):
        hits = {z: [] for z in ZOOMS}
        false = {z: 0 for z in ZOOMS}
        for _ in range(n):
            tgt = np.array([rng.uniform(-0.25, 0.25) * r, r, 30 + rng.uniform(-0.1, 0.15) * r])
            frame = renderer.render(np.array([0.0, 0.0, 30.0]), att, [TargetPose("s1000", tgt, attitude_from_velocity(rng.normal(0, 3, 3)))],
                                    Lighting(), rng)
            if not frame.labels:
                continue
            box, (cx, cy) = frame.labels[0].box, frame.labels[0].centre_px
            cue = (cx + rng.normal(0, 8), cy + rng.normal(0, 8))
            for z in ZOOMS:
                dets = _detect(det, frame.image, z, cue)
                hits[z].append(any(_on(box, d) for d in dets))
                grown = (box[0] - 3, box[1] - 3, box[2] + 3, box[3] + 3)
                false[z] += sum(not _on(grown, d) for d in dets)
        for z in ZOOMS:
            key = "whole" if z == 0 else f"x{z:g}"
            out[f"acq_{r}m_found_{key}"] = round(float(np.mean(hits[z])), 3) if hits[z] else None
            out[f"acq_{r}m_false_per_view_{key}"] = round(false[z] / max(len(hits[z]), 1), 3)
    return out


def follow(det: Detector, n: int, rng: np.random.Generator) -> dict:
    cam = CameraModel(width_px=640, height_px=480, tilt_rad=math.radians(40))
    renderer = Renderer(cam, make_ground(1004))
    out = {}
    for r in (25, 40):
        centre_err = {z: [] for z in ZOOMS}
        width_ratio = {z: [] for z in ZOOMS}
        for _ in range(n):
            yaw = rng.uniform(0, 2 * math.pi)
            own = np.array([rng.uniform(-300, 300), rng.uniform(-300, 300), 50.0])
            los = np.array([math.cos(yaw) * math.cos(math.radians(40)), math.sin(yaw) * math.cos(math.radians(40)), -math.sin(math.radians(40))])
            att = Rotation.from_euler("ZYX", [yaw, rng.normal(0, 0.03), rng.normal(0, 0.03)])
            frame = renderer.render(own, att, [TargetPose("s1000", own + r * los, attitude_from_velocity(rng.normal(0, 3, 3)))], Lighting(), rng)
            if not frame.labels:
                continue
            box, (cx, cy) = frame.labels[0].box, frame.labels[0].centre_px
            for z in ZOOMS:
                on = [d for d in _detect(det, frame.image, z, (cx, cy)) if _on(box, d)]
                if on:
                    centre_err[z].append(math.hypot(on[0].centre[0] - cx, on[0].centre[1] - cy))
                    width_ratio[z].append((on[0].box[2] - on[0].box[0]) / (box[2] - box[0]))
        for z in ZOOMS:
            key = "whole" if z == 0 else f"x{z:g}"
            out[f"follow_{r}m_centre_err_px_median_{key}"] = round(float(np.median(centre_err[z])), 3) if centre_err[z] else None
            out[f"follow_{r}m_width_ratio_median_{key}"] = round(float(np.median(width_ratio[z])), 3) if width_ratio[z] else None
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="8 views per range instead of 30")
    add_record_flag(parser)
    args = parser.parse_args()
    torch.set_num_threads(1)
    n = 8 if args.quick else 30
    det = Detector(image_size=416, threads=1)
    rng = np.random.default_rng(0)
    emit({"name": "focus", "views_per_range": n, **acquisition(det, n, rng), **follow(det, n, rng)}, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
