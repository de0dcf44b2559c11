"""Pixel <-> world for the on-board camera (paper section 3.1, "Coordinate Transformation").

The transform needs (1) the ownship attitude in ENU, (2) the camera mount, (3) the FOV and (4) the
resolution; (2)-(4) are the :class:`~chaser_bt.vision.camera.CameraModel`. As in the paper, frames are
chained with quaternions: q(optical -> ENU) = q(body -> ENU) * q(optical -> body), and a vector is
rotated by v' = q v q*. The attitude from the IMU is smoothed first by an alpha-beta (g-h) filter
(filterpy's GHFilter) run in the tangent space of the rotation group: each update works on the
rotation vector from the last estimate to the new measurement, so the filter never leaves SO(3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from filterpy.gh import GHFilter
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel

__all__ = ["quat_multiply", "quat_conjugate", "quat_rotate", "Projector", "AttitudeSmoother"]


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p * q of scalar-last quaternions (x, y, z, w)."""
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return np.array([pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw,
                     pw * qw - px * qx - py * qy - pz * qz])


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    return np.array([-q[0], -q[1], -q[2], q[3]])


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate 3-vectors v (N, 3) by unit quaternion q: v' = q v q*, written out (v + 2w(u x v) + 2u x (u x v))."""
    u, w = np.asarray(q[:3], float), float(q[3])
    v = np.asarray(v, float).reshape(-1, 3)
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


@dataclass(frozen=True)
class Projector:
    """Pixel -> ENU bearing and ENU point -> pixel for one camera, with quaternion frame chaining."""

    camera: CameraModel

    def camera_quaternion(self, body_attitude: Rotation) -> np.ndarray:
        """q(optical -> ENU) = q(mount -> ENU) * q(optical -> mount), scalar-last; the mount is the body
        itself for a fixed camera (:meth:`CameraModel.mount_attitude`)."""
        q = quat_multiply(self.camera.mount_attitude(body_attitude).as_quat(), self.camera._cam_to_body.as_quat())
        return q / np.linalg.norm(q)

    def bearing_enu(self, pixels: np.ndarray, body_attitude: Rotation) -> np.ndarray:
        """Unit ENU rays (N, 3) through pixels (N, 2) (u right, v down, origin top-left corner)."""
        px = np.asarray(pixels, float).reshape(-1, 2)
        fx, fy = self.camera.focal_px
        d = np.stack([(px[:, 0] - 0.5 * self.camera.width_px) / fx, (px[:, 1] - 0.5 * self.camera.height_px) / fy, np.ones(len(px))], axis=1)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return quat_rotate(self.camera_quaternion(body_attitude), d)

    def pixel_of(self, points_enu: np.ndarray, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> tuple[np.ndarray, np.ndarray]:
        """ENU points (N, 3) -> (pixels (N, 2), in_front (N,)); pixels behind the camera are nan."""
        c = self._optical(points_enu, vehicle_pos_enu, body_attitude)
        fx, fy = self.camera.focal_px
        front = c[:, 2] > 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(front, 0.5 * self.camera.width_px + fx * c[:, 0] / c[:, 2], np.nan)
            v = np.where(front, 0.5 * self.camera.height_px + fy * c[:, 1] / c[:, 2], np.nan)
        return np.stack([u, v], axis=1), front

    def _optical(self, points_enu: np.ndarray, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> np.ndarray:
        """ENU points (N, 3) in the optical frame (x right, y down, z along the axis), from the camera."""
        rel = np.asarray(points_enu, float).reshape(-1, 3) - self.camera.position_enu(vehicle_pos_enu, body_attitude)
        return quat_rotate(quat_conjugate(self.camera_quaternion(body_attitude)), rel)

    def angle_outside_rad(self, point_enu: np.ndarray, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> float:
        """A lower bound on the angle between the ray to ``point_enu`` and any ray through the image
        (0 inside it): the largest angle by which the ray lies outside one of the four planes through
        the camera and an image edge (the view is inside each of them, so it is at least that far)."""
        c = self._optical(point_enu, vehicle_pos_enu, body_attitude)[0]
        n = float(np.linalg.norm(c))
        if n <= 0.0:
            return 0.0
        fx, fy = self.camera.focal_px
        th, tv = 0.5 * self.camera.width_px / fx, 0.5 * self.camera.height_px / fy
        inward = np.array([[-1.0, 0.0, th], [1.0, 0.0, th], [0.0, -1.0, tv], [0.0, 1.0, tv]])
        inward /= np.linalg.norm(inward, axis=1, keepdims=True)
        outside = float(np.max(-(inward @ c) / n))
        return math.asin(min(outside, 1.0)) if outside > 0.0 else 0.0

    def point_enu(self, pixels: np.ndarray, range_m: np.ndarray, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> np.ndarray:
        """ENU points at ``range_m`` from the camera along the rays through ``pixels``."""
        cam = self.camera.position_enu(vehicle_pos_enu, body_attitude)
        return cam + np.asarray(range_m, float).reshape(-1, 1) * self.bearing_enu(pixels, body_attitude)

    def pixel_angle_rad(self) -> float:
        """Angle subtended by one pixel at the image centre (horizontal)."""
        return math.atan(1.0 / self.camera.focal_px[0])


class AttitudeSmoother:
    """Alpha-beta (g-h) smoothing of the ownship attitude on SO(3) (paper section 3.1).

    Args:
        alpha, beta: the g and h gains of the filter (alpha=1, beta=0 passes measurements through).
    """

    def __init__(self, alpha: float = 0.6, beta: float = 0.1) -> None:
        if not (0.0 < alpha <= 1.0 and 0.0 <= beta < 2.0):
            raise ValueError(f"alpha must be in (0, 1] and beta in [0, 2), got {alpha}, {beta}")
        self.alpha, self.beta = alpha, beta
        self._est: Rotation | None = None
        self._rate = np.zeros(3)  # ENU rotation-vector rate (rad/s)
        self._t: float | None = None

    def update(self, t: float, attitude: Rotation) -> Rotation:
        """Feed the measured attitude at time ``t``; returns the smoothed attitude."""
        if self._est is None or self._t is None or t <= self._t:
            if self._est is None:
                self._est, self._t = attitude, t
                return attitude
            if t <= self._t:
                return self._est
        dt = t - self._t
        # Chart centred on the last estimate: measurement as the rotation vector taking it there.
        z = (attitude * self._est.inv()).as_rotvec()
        f = GHFilter(x=np.zeros(3), dx=self._rate.copy(), dt=dt, g=self.alpha, h=self.beta)
        x, dx = f.update(z)
        self._est = Rotation.from_rotvec(x) * self._est
        self._rate = np.asarray(dx, float)
        self._t = t
        return self._est

    @property
    def attitude(self) -> Rotation | None:
        return self._est
