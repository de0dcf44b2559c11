"""Frames and rotations: WGS84 <-> local ENU, NED <-> ENU, aircraft body <-> world.

One local frame is used everywhere inside chaser-bt: ENU (x east, y north, z up), metres, with
its origin at a geodetic reference (DESIGN §3). MAVLink speaks NED and 1e7-degree integers;
those are converted at the vehicle boundary with the helpers here and nowhere else.

Geodesy is pymap3d's; rotations are scipy's (scalar-last quaternions). Altitudes are whatever
the caller's reference uses (MAVLink's AMSL in practice): a local frame only needs the origin
and the points to share one vertical datum, since the geoid offset is constant over a few km.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import pymap3d
from scipy.spatial.transform import Rotation

__all__ = [
    "GeoPoint",
    "LocalFrame",
    "NearbyGeodetic",
    "ned_to_enu",
    "enu_to_ned",
    "body_to_enu_rotation",
    "euler_ned_from_rotation",
    "heading_to_enu_yaw",
    "enu_yaw_to_heading",
    "quat_wxyz_to_xyzw",
    "quat_xyzw_to_wxyz",
    "wrap_pi",
]

# ENU <-> NED swaps x and y and flips z; FLU (x forward, y left, z up) <-> FRD flips y and z.
_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_FLU_FRD = np.diag([1.0, -1.0, -1.0])
_R_NED_ENU = Rotation.from_matrix(_NED_ENU)
_R_FLU_FRD = Rotation.from_matrix(_FLU_FRD)
# pymap3d's default ellipsoid, built once: by default pymap3d builds it anew on every conversion.
_WGS84 = pymap3d.Ellipsoid.from_name("wgs84")


@dataclass(frozen=True)
class GeoPoint:
    """A geodetic position: latitude and longitude in degrees, altitude in metres."""

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    def __post_init__(self) -> None:
        if not -90.0 <= self.lat_deg <= 90.0:
            raise ValueError(f"latitude {self.lat_deg} deg is outside [-90, 90]")
        if not -180.0 <= self.lon_deg <= 180.0:
            raise ValueError(f"longitude {self.lon_deg} deg is outside [-180, 180]")


@dataclass(frozen=True)
class LocalFrame:
    """The ENU frame tangent to the WGS84 ellipsoid at ``origin``."""

    origin: GeoPoint

    def to_enu(self, lat_deg: float, lon_deg: float, alt_m: float) -> np.ndarray:
        """Geodetic point -> ENU metres, shape (3,)."""
        o = self.origin
        e, n, u = pymap3d.geodetic2enu(lat_deg, lon_deg, alt_m, o.lat_deg, o.lon_deg, o.alt_m, ell=_WGS84)
        return np.array([e, n, u], dtype=float)

    def to_geodetic(self, enu: np.ndarray | tuple[float, float, float]) -> GeoPoint:
        """ENU metres -> geodetic point."""
        o = self.origin
        lat, lon, alt = pymap3d.enu2geodetic(
            float(enu[0]), float(enu[1]), float(enu[2]), o.lat_deg, o.lon_deg, o.alt_m, ell=_WGS84
        )
        return GeoPoint(float(lat), float(lon), float(alt))

    def point_to_enu(self, p: GeoPoint) -> np.ndarray:
        """:meth:`to_enu` for a :class:`GeoPoint`."""
        return self.to_enu(p.lat_deg, p.lon_deg, p.alt_m)


class NearbyGeodetic:
    """:meth:`LocalFrame.to_geodetic` for a stream of nearby points, at a fraction of the cost.

    A simulator converts every telemetry position (GPS and EKF, 8 a simulated second), and
    pymap3d's iterative ECEF -> geodetic costs 0.2 ms each: a quarter of the physics-only
    simulator's time. Here pymap3d converts exactly at an anchor point and 1 m along each ENU
    axis from it; a point near the anchor goes through that Jacobian, and a point farther away
    becomes the new anchor. "Near" is ``radius_m`` shrunk by ``sqrt(1 + tan|lat|)``, since the
    meridians converge (the longitude's curvature grows with tan(lat)): the first-order error stays
    below ``radius_m**2 / 6.3e6`` m (0.4 mm at 50 m) at any latitude, far under the 1e-7 degree
    (1.1 cm) of MAVLink's integer positions. Within 1 degree of a pole every point is converted exactly.
    """

    def __init__(self, frame: LocalFrame, radius_m: float = 50.0) -> None:
        self.frame = frame
        self.radius_m = radius_m
        self._anchor: tuple[float, float, float] | None = None
        self._reach = radius_m  # radius_m shrunk for the anchor's latitude
        self._geo0 = (0.0, 0.0, 0.0)
        self._jacobian = ((0.0,) * 3,) * 3  # rows: d(lat, lon, alt) / d(e, n, u)

    def __call__(self, enu: np.ndarray | tuple[float, float, float]) -> GeoPoint:
        e, n, u = float(enu[0]), float(enu[1]), float(enu[2])
        a = self._anchor
        if a is None or abs(e - a[0]) + abs(n - a[1]) + abs(u - a[2]) > self._reach:
            return self._anchor_at(e, n, u)
        de, dn, du = e - a[0], n - a[1], u - a[2]
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self._jacobian
        lat0, lon0, alt0 = self._geo0
        lon = lon0 + j10 * de + j11 * dn + j12 * du
        return GeoPoint(lat0 + j00 * de + j01 * dn + j02 * du, (lon + 180.0) % 360.0 - 180.0,
                        alt0 + j20 * de + j21 * dn + j22 * du)

    def _anchor_at(self, e: float, n: float, u: float) -> GeoPoint:
        exact = self.frame.to_geodetic((e, n, u))
        if abs(exact.lat_deg) > 89.0:
            self._anchor = None
            return exact
        steps = [self.frame.to_geodetic((e + 1.0, n, u)), self.frame.to_geodetic((e, n + 1.0, u)),
                 self.frame.to_geodetic((e, n, u + 1.0))]
        self._jacobian = (
            tuple(s.lat_deg - exact.lat_deg for s in steps),
            tuple((s.lon_deg - exact.lon_deg + 180.0) % 360.0 - 180.0 for s in steps),  # across 180
            tuple(s.alt_m - exact.alt_m for s in steps),
        )
        self._anchor, self._geo0 = (e, n, u), (exact.lat_deg, exact.lon_deg, exact.alt_m)
        self._reach = self.radius_m / math.sqrt(1.0 + abs(math.tan(math.radians(exact.lat_deg))))
        return exact


def ned_to_enu(v: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """A NED vector (north, east, down) as ENU (east, north, up)."""
    return np.array([v[1], v[0], -v[2]], dtype=float)


def enu_to_ned(v: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """An ENU vector (east, north, up) as NED (north, east, down)."""
    return np.array([v[1], v[0], -v[2]], dtype=float)


@functools.lru_cache(maxsize=16)
def body_to_enu_rotation(roll: float, pitch: float, yaw: float) -> Rotation:
    """Attitude as MAVLink reports it (FRD body -> NED, radians) as a FLU body -> ENU rotation.

    ``R_enu_flu = R_enu_ned * R_ned_frd * R_frd_flu``; the returned rotation maps vectors in the
    FLU body frame to ENU. The last few are kept: a tick asks for the same attitude many times (the
    scorer, the camera, the telemetry), and building one costs more than the rest of its use.
    """
    r_ned_frd = Rotation.from_euler("ZYX", [yaw, pitch, roll])
    return _R_NED_ENU * r_ned_frd * _R_FLU_FRD


def euler_ned_from_rotation(r_enu_flu: Rotation) -> tuple[float, float, float]:
    """Inverse of :func:`body_to_enu_rotation`: (roll, pitch, yaw) of FRD body in NED, radians."""
    r_ned_frd = _R_NED_ENU.inv() * r_enu_flu * _R_FLU_FRD.inv()
    yaw, pitch, roll = r_ned_frd.as_euler("ZYX")
    return float(roll), float(pitch), float(yaw)


def heading_to_enu_yaw(heading_rad: float) -> float:
    """Compass heading (clockwise from north) -> ENU yaw (counter-clockwise from east)."""
    return wrap_pi(math.pi / 2.0 - heading_rad)


def enu_yaw_to_heading(yaw_rad: float) -> float:
    """ENU yaw (counter-clockwise from east) -> compass heading in [0, 2*pi)."""
    return (math.pi / 2.0 - yaw_rad) % (2.0 * math.pi)


def quat_wxyz_to_xyzw(q: tuple[float, float, float, float] | np.ndarray) -> np.ndarray:
    """MAVLink's scalar-first quaternion -> scipy's scalar-last."""
    return np.array([q[1], q[2], q[3], q[0]], dtype=float)


def quat_xyzw_to_wxyz(q: tuple[float, float, float, float] | np.ndarray) -> np.ndarray:
    """scipy's scalar-last quaternion -> MAVLink's scalar-first."""
    return np.array([q[3], q[0], q[1], q[2]], dtype=float)


def wrap_pi(angle: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi
