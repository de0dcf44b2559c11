"""The radar's own frame and its pose in the mission's ENU frame (paper appendix A).

The radar reports range, azimuth and elevation in its own frame. That frame is FLU: x along the
boresight, y to the left, z up. Azimuth is measured from the boresight and is positive to the
right (clockwise seen from above, as a compass and as the EchoGuard reports it); elevation is
positive up. The radar's attitude is given like an aircraft's: yaw is the compass heading of the
boresight, pitch positive nose (boresight) up, roll positive right side down, so
:func:`chaser_bt.geo.body_to_enu_rotation` turns it into the radar-frame -> ENU rotation.

The attitude is taken in the ENU frame of the mission's origin, not the tangent plane at the radar;
over the few hundred metres between them the two differ by a few thousandths of a degree.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.geo import GeoPoint, LocalFrame, body_to_enu_rotation, euler_ned_from_rotation

__all__ = ["RadarPose", "rae_to_xyz", "xyz_to_rae", "rae_covariance_xyz"]


def rae_to_xyz(range_m: np.ndarray, az_rad: np.ndarray, el_rad: np.ndarray) -> np.ndarray:
    """Range/azimuth/elevation -> radar-frame (FLU) Cartesian points, shape (..., 3)."""
    r, az, el = np.asarray(range_m, float), np.asarray(az_rad, float), np.asarray(el_rad, float)
    ce = np.cos(el)
    return np.stack([r * ce * np.cos(az), -r * ce * np.sin(az), r * np.sin(el)], axis=-1)


def xyz_to_rae(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Radar-frame Cartesian points (..., 3) -> (range, azimuth, elevation)."""
    p = np.asarray(xyz, float)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    r = np.sqrt(x * x + y * y + z * z)
    return r, np.arctan2(-y, x), np.arctan2(z, np.hypot(x, y))


def rae_covariance_xyz(range_m: float, az_rad: float, el_rad: float,
                       sigma_range_m: float, sigma_az_rad: float, sigma_el_rad: float) -> np.ndarray:
    """Radar-frame position covariance (3, 3) of one report: J diag(sigma^2) J^T (first order)."""
    r, a, e = range_m, az_rad, el_rad
    ca, sa, ce, se = np.cos(a), np.sin(a), np.cos(e), np.sin(e)
    jac = np.array([
        [ce * ca, -r * ce * sa, -r * se * ca],
        [-ce * sa, -r * ce * ca, r * se * sa],
        [se, 0.0, r * ce],
    ])
    return jac @ np.diag([sigma_range_m**2, sigma_az_rad**2, sigma_el_rad**2]) @ jac.T


@dataclass(frozen=True)
class RadarPose:
    """Where the radar stands in the mission's ENU frame and how it is turned.

    Args:
        position_enu: (3,) metres, the radar's phase centre in the mission frame.
        rotation: radar frame (FLU) -> ENU.
    """

    position_enu: np.ndarray
    rotation: Rotation

    def __post_init__(self) -> None:
        p = np.asarray(self.position_enu, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"radar position must be 3 finite numbers, got {self.position_enu!r}")
        object.__setattr__(self, "position_enu", p)

    @classmethod
    def from_attitude(cls, position_enu: np.ndarray, yaw_rad: float, pitch_rad: float,
                      roll_rad: float) -> RadarPose:
        """Pose from the boresight's compass heading, pitch and roll (radians)."""
        return cls(np.asarray(position_enu, float), body_to_enu_rotation(roll_rad, pitch_rad, yaw_rad))

    @classmethod
    def from_geodetic(cls, frame: LocalFrame, position: GeoPoint, yaw_rad: float, pitch_rad: float,
                      roll_rad: float) -> RadarPose:
        """Pose from a geodetic position, in the mission ``frame``."""
        return cls.from_attitude(frame.point_to_enu(position), yaw_rad, pitch_rad, roll_rad)

    @property
    def yaw_pitch_roll(self) -> tuple[float, float, float]:
        """(yaw = boresight heading, pitch, roll), radians."""
        roll, pitch, yaw = euler_ned_from_rotation(self.rotation)
        return yaw % (2.0 * np.pi), pitch, roll

    def to_enu(self, xyz: np.ndarray) -> np.ndarray:
        """Radar-frame points (..., 3) -> ENU points."""
        return self.rotation.apply(np.asarray(xyz, float)) + self.position_enu

    def vector_to_enu(self, v: np.ndarray) -> np.ndarray:
        """Radar-frame vectors (velocities) -> ENU vectors."""
        return self.rotation.apply(np.asarray(v, float))

    def from_enu(self, enu: np.ndarray) -> np.ndarray:
        """ENU points (..., 3) -> radar-frame points."""
        return self._to_radar.apply(np.asarray(enu, float) - self.position_enu)

    @functools.cached_property
    def _to_radar(self) -> Rotation:
        """ENU -> radar frame (the rotation's inverse, asked for at every scan)."""
        return self.rotation.inv()

    def rae_to_enu(self, range_m: np.ndarray, az_rad: np.ndarray, el_rad: np.ndarray) -> np.ndarray:
        """Range/azimuth/elevation -> ENU points."""
        return self.to_enu(rae_to_xyz(range_m, az_rad, el_rad))

    def covariance_enu(self, range_m: float, az_rad: float, el_rad: float, sigma_range_m: float,
                       sigma_az_rad: float, sigma_el_rad: float) -> np.ndarray:
        """ENU covariance (3, 3) of one report with the given measurement noise."""
        c = rae_covariance_xyz(range_m, az_rad, el_rad, sigma_range_m, sigma_az_rad, sigma_el_rad)
        m = self.rotation.as_matrix()
        return m @ c @ m.T
