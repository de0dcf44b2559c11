"""Scripted camera sequences for scoring the vision pipeline (benchmarks and tests; uses ground truth).

:func:`follow_sequence` flies a target around a circle and puts the chaser behind and above it at a
slowly varying distance, nose on the target with some attitude wobble, as a follow controller
would; it yields frames with the ownship pose the mission would know (attitude with IMU noise) and
the truth needed to score bearing and range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel
from sitl.world.camera.renderer import (
    Lighting,
    Renderer,
    TargetLabel,
    TargetPose,
    attitude_from_velocity,
)
from sitl.world.camera.scene import make_ground
from sitl.world.targets import CirclePath

__all__ = ["FollowView", "follow_sequence"]


@dataclass(frozen=True)
class FollowView:
    t: float
    image: np.ndarray
    position_enu: np.ndarray       # ownship, truth (the EKF is good to centimetres here)
    velocity_enu: np.ndarray
    attitude_measured: Rotation     # truth with IMU noise: what the mission sees
    attitude_true: Rotation
    target_enu: np.ndarray
    label: TargetLabel | None


def follow_sequence(camera: CameraModel, n_frames: int, seed: int, kind: str = "s1000", fps: float = 30.0,
                    ground_seed: int = 1003, lighting: Lighting = Lighting(), imu_noise_rad: float = math.radians(0.1),
                    distance_m: tuple[float, float] = (6.0, 18.0)) -> Iterator[FollowView]:
    rng = np.random.default_rng(seed)
    renderer = Renderer(camera, make_ground(ground_seed), noise_seed=seed)
    path = CirclePath(center_enu=(0.0, 0.0, 25.0), radius_m=40.0, speed_mps=4.0)
    prev = None
    for k in range(n_frames):
        t = k / fps
        tp = path.position_enu(t)
        tv = path.velocity_enu(t)
        d = distance_m[0] + (distance_m[1] - distance_m[0]) * 0.5 * (1 - math.cos(2 * math.pi * t / 12.0))
        back = -tv / max(np.linalg.norm(tv), 1e-6)
        lateral = np.array([-back[1], back[0], 0.0]) * 2.0 * math.sin(2 * math.pi * t / 7.0)
        pos = tp + back * d * 0.95 + lateral + np.array([0.0, 0.0, 0.3 * d + 1.0])
        vel = (pos - prev) * fps if prev is not None else tv
        prev = pos
        look = tp - pos
        yaw = math.atan2(look[1], look[0]) + math.radians(4.0) * math.sin(2 * math.pi * t / 3.0)
        pitch = math.radians(6.0) + math.radians(3.0) * math.sin(2 * math.pi * t / 2.3)  # flying forward: nose down
        roll = math.radians(3.0) * math.sin(2 * math.pi * t / 1.7)
        att = Rotation.from_euler("ZYX", [yaw, pitch, roll])
        target = TargetPose(kind, tp, attitude_from_velocity(tv))
        frame = renderer.render(pos, att, [target], lighting, rng, blur_px=1.0)
        measured = Rotation.from_rotvec(rng.normal(0.0, imu_noise_rad, 3)) * att
        yield FollowView(t, frame.image, pos, vel, measured, att, tp, frame.labels[0] if frame.labels else None)
