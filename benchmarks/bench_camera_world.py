"""Render speed of each camera world at 640 x 480 on one core, beside the plain field in the same run.

A chase-like pass: the camera 30 m up, turning slowly, an S1000 40 m ahead, birds and drift on.
Prints one JSON line: {"name": "camera_world", "fps_<family>": frames/s (median of the repeats),
"ratio_<family>": fps / plain fps in this run, "build_s_<family>": making the world, ...}.
Run: .venv/bin/python benchmarks/bench_camera_world.py [--frames 120] [--repeats 3]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from chaser_bt.vision.camera import CameraModel  # noqa: E402
from sitl.world.camera.renderer import Renderer, TargetPose, attitude_from_velocity  # noqa: E402
from sitl.world.camera.world import FAMILIES, WorldSpec, build_world  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402

BENCHMARK = Benchmark(
    "camera_world", __doc__,
    against="built-in simulator's camera renderer (sitl/world/camera), one core",
    units={
        "width_px": "px", "height_px": "px", "threads": "OpenCV threads",
        "build_s_*": "s to build the camera world",
        "fps_*": "frames rendered per wall second (median of the repeats)",
        "ratio_*": "the family's frames/s over the plain field's, in the same run",
    },
    headline=("fps_plain", "fps_meadow", "fps_suburb", "ratio_suburb"),
)


def _fps(renderer: Renderer, lighting, frames: int) -> float:
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    for k in range(frames):
        yaw = math.radians(40.0 + 0.5 * k)
        pos = np.array([0.3 * k, 0.2 * k, 30.0])
        ahead = pos + 40.0 * np.array([math.cos(yaw), math.sin(yaw), 0.1])
        target = TargetPose("s1000", ahead, attitude_from_velocity(np.array([math.cos(yaw), math.sin(yaw), 0.0]) * 4.0))
        renderer.render(pos, Rotation.from_euler("ZY", [yaw, math.radians(4.0)]), [target], lighting, rng,
                        blur_px=2.0, t=0.1 * k)
    return frames / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1)
    add_record_flag(parser)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    camera = CameraModel(width_px=640, height_px=480)
    out: dict = {"name": "camera_world", "width_px": 640, "height_px": 480, "threads": 1}
    for family in ("plain", *FAMILIES):
        start = time.perf_counter()
        world = build_world(WorldSpec(family), args.seed)
        out[f"build_s_{family}"] = round(time.perf_counter() - start, 2)
        renderer = Renderer(camera, world=world, noise_seed=1)
        _fps(renderer, world.lighting, 5)  # warm up
        out[f"fps_{family}"] = round(statistics.median(_fps(renderer, world.lighting, args.frames)
                                                       for _ in range(args.repeats)), 1)
    for family in FAMILIES:
        out[f"ratio_{family}"] = round(out[f"fps_{family}"] / out["fps_plain"], 3)
    emit(out, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
