"""The one camera model: a forward-looking pinhole camera on the airframe (paper sections 3.1 and 3.4).

The paper's e-con e-CAM130CUXVR sees 95 deg horizontally and 73 deg vertically (appendix table).
It looks forward, tilted down by ``tilt_rad``, at ``offset_body_m`` from the vehicle's reference
point, on one of two mounts (``mount``):

- ``fixed``: bolted to the airframe, so it leans with it: tilted ``tilt_rad`` below the body's
  forward axis. The paper's follow controller was designed for this camera.
- ``stabilised``: a two-axis (pitch and roll) gimbal, the paper's hardware and its lesson ("mounting
  the camera on a tilt-stabilizing gimbal is critical to mitigate against winds aloft and platform
  motion"): the camera keeps ``tilt_rad`` below the horizon and turns only with the airframe's
  heading, so a chaser leaning 30 deg into a dash or into the wind does not tip its target out of
  the top of the image. The gimbal is taken as perfect (no lag, no travel limit).

Frames:

- body: FLU (x forward, y left, z up); ``body_attitude`` rotates body -> ENU (VehicleState.attitude).
- camera (optical): x right, y down, z along the optical axis; pixel (u, v) has u to the right and
  v down from the top-left corner, principal point at the image centre.

:meth:`CameraModel.visible` is the search's sensor footprint (inside the frustum and within the
detection range); :meth:`project` and :meth:`ray_enu` are the pixel <-> world transforms the
vision modules build on. Everything is vectorised over points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["CameraModel", "MOUNTS"]

#: The camera mounts (module docstring).
MOUNTS = ("fixed", "stabilised")

# Camera optical frame -> FLU body for an untilted camera looking forward: optical z (axis) is
# body x, optical x (right) is body -y, optical y (down) is body -z.
_OPTICAL_TO_BODY = Rotation.from_matrix(np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]))


@dataclass(frozen=True)
class CameraModel:
    """A forward-looking pinhole camera on the airframe, fixed or on a stabilising gimbal.

    Args:
        hfov_rad, vfov_rad: full horizontal and vertical field of view (e-con: 95 x 73 deg).
        width_px, height_px: image size in pixels (focal lengths follow from size and FOV).
        tilt_rad: tilt of the optical axis (positive = down) below the body's forward axis (``fixed``)
            or below the horizon (``stabilised``).
        offset_body_m: camera position in the FLU body frame (m).
        max_range_m: farthest distance at which the detector finds the target (m).
        min_range_m: nearest such distance (m).
        p_detect: probability the detector finds a target that is inside the footprint.
        mount: ``fixed`` or ``stabilised`` (module docstring).
    """

    hfov_rad: float = math.radians(95.0)
    vfov_rad: float = math.radians(73.0)
    width_px: int = 1920
    height_px: int = 1080
    tilt_rad: float = math.radians(10.0)
    offset_body_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_range_m: float = 80.0
    min_range_m: float = 0.0
    p_detect: float = 0.9
    mount: str = "fixed"
    _cam_to_body: Rotation = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (0.0 < self.hfov_rad < math.pi and 0.0 < self.vfov_rad < math.pi):
            raise ValueError(f"camera FOV must be in (0, 180) deg, got {math.degrees(self.hfov_rad):.1f} x {math.degrees(self.vfov_rad):.1f}")
        if self.width_px <= 0 or self.height_px <= 0:
            raise ValueError(f"camera resolution must be positive, got {self.width_px} x {self.height_px}")
        if not 0.0 <= self.min_range_m < self.max_range_m:
            raise ValueError(f"camera ranges need 0 <= min_range_m < max_range_m, got {self.min_range_m}, {self.max_range_m}")
        if not 0.0 < self.p_detect <= 1.0:
            raise ValueError(f"camera p_detect must be in (0, 1], got {self.p_detect}")
        if self.mount not in MOUNTS:
            raise ValueError(f"camera mount must be one of {', '.join(MOUNTS)}, got {self.mount!r}")
        if len(self.offset_body_m) != 3:
            raise ValueError(f"camera offset_body_m needs 3 numbers, got {self.offset_body_m!r}")
        tilt = Rotation.from_euler("y", self.tilt_rad)  # about body y (left): positive pitches the axis down
        object.__setattr__(self, "_cam_to_body", tilt * _OPTICAL_TO_BODY)

    @property
    def focal_px(self) -> tuple[float, float]:
        """(fx, fy) in pixels."""
        return (0.5 * self.width_px / math.tan(0.5 * self.hfov_rad), 0.5 * self.height_px / math.tan(0.5 * self.vfov_rad))

    def mount_attitude(self, body_attitude: Rotation) -> Rotation:
        """The frame the camera is tilted in (FLU -> ENU): the body's own (``fixed``) or the body's
        heading alone, level (``stabilised``)."""
        if self.mount == "fixed":
            return body_attitude
        forward = body_attitude.apply([1.0, 0.0, 0.0])
        return Rotation.from_euler("z", math.atan2(forward[1], forward[0]))

    def camera_to_enu(self, body_attitude: Rotation) -> Rotation:
        """Rotation optical frame -> ENU for a body attitude (FLU -> ENU)."""
        return self.mount_attitude(body_attitude) * self._cam_to_body

    def position_enu(self, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> np.ndarray:
        """Where the camera is, given the vehicle's position and attitude."""
        return np.asarray(vehicle_pos_enu, dtype=float) + body_attitude.apply(np.asarray(self.offset_body_m, dtype=float))

    def to_camera(self, points_enu: np.ndarray, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> np.ndarray:
        """ENU points (N, 3) -> optical-frame coordinates (N, 3)."""
        rel = np.asarray(points_enu, dtype=float).reshape(-1, 3) - self.position_enu(vehicle_pos_enu, body_attitude)
        return self.camera_to_enu(body_attitude).inv().apply(rel)

    def visible(self, points_enu: np.ndarray, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> np.ndarray:
        """Boolean mask (N,): inside the FOV and within [min_range_m, max_range_m] of the camera."""
        c = self.to_camera(points_enu, vehicle_pos_enu, body_attitude)
        x, y, z = c[:, 0], c[:, 1], c[:, 2]
        dist = np.linalg.norm(c, axis=1)
        tan_h, tan_v = math.tan(0.5 * self.hfov_rad), math.tan(0.5 * self.vfov_rad)
        return (
            (z > 0.0)
            & (np.abs(x) <= tan_h * z)
            & (np.abs(y) <= tan_v * z)
            & (dist <= self.max_range_m)
            & (dist >= self.min_range_m)
        )

    def project(self, points_enu: np.ndarray, vehicle_pos_enu: np.ndarray, body_attitude: Rotation) -> tuple[np.ndarray, np.ndarray]:
        """ENU points (N, 3) -> (pixels (N, 2) as (u, v), in_front (N,)); pixels behind the camera are nan."""
        c = self.to_camera(points_enu, vehicle_pos_enu, body_attitude)
        fx, fy = self.focal_px
        in_front = c[:, 2] > 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(in_front, 0.5 * self.width_px + fx * c[:, 0] / c[:, 2], np.nan)
            v = np.where(in_front, 0.5 * self.height_px + fy * c[:, 1] / c[:, 2], np.nan)
        return np.stack([u, v], axis=1), in_front

    def ray_enu(self, pixels: np.ndarray, body_attitude: Rotation) -> np.ndarray:
        """Pixels (N, 2) -> unit ENU directions (N, 3) of the rays through them (inverse of project)."""
        px = np.asarray(pixels, dtype=float).reshape(-1, 2)
        fx, fy = self.focal_px
        d = np.stack([(px[:, 0] - 0.5 * self.width_px) / fx, (px[:, 1] - 0.5 * self.height_px) / fy, np.ones(len(px))], axis=1)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return self.camera_to_enu(body_attitude).apply(d)
