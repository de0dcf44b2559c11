"""The mission's geofence: a cylinder around home, or a polygon, with a ceiling (ENU metres).

ArduCopter has its own fence (FENCE_TYPE, FENCE_RADIUS, FENCE_ALT_MAX); this one is the mission's,
checked on the vehicle's estimated position every tick so the tree can label the breach and fly
RTL itself. Both can be used together: set the mission's inside the autopilot's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ["Geofence", "point_in_polygon"]


def point_in_polygon(x: float, y: float, polygon: np.ndarray) -> bool:
    """Whether (x, y) is inside ``polygon`` ((n, 2) vertices, either winding; even-odd rule).

    Points exactly on an edge may fall either way; a fence has a margin, so that does not matter.
    """
    inside = False
    n = len(polygon)
    for i in range(n):
        x1, y1 = polygon[i]
        x2, y2 = polygon[(i + 1) % n]
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


@dataclass(frozen=True)
class Geofence:
    """Where the vehicle may fly, in the mission's ENU frame (origin: home).

    Args:
        radius_m: horizontal distance from ``center_en`` allowed; 0 = no cylinder.
        max_alt_m: ceiling above the origin; 0 = none.
        polygon_en: flat list ``[e1, n1, e2, n2, ...]`` of at least three vertices; empty = none.
        center_en: centre of the cylinder, east and north (m).
    """

    radius_m: float = 0.0
    max_alt_m: float = 0.0
    polygon_en: Sequence[float] = ()
    center_en: Sequence[float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if not (self.radius_m >= 0 and self.max_alt_m >= 0):
            raise ValueError(f"geofence radius_m {self.radius_m} and max_alt_m {self.max_alt_m}: expected >= 0")
        n = len(self.polygon_en)
        if n and (n % 2 or n < 6):
            raise ValueError(f"geofence polygon_en has {n} numbers: expected east/north pairs of at least 3 vertices")
        if not all(math.isfinite(float(v)) for v in (*self.polygon_en, *self.center_en)) or len(self.center_en) != 2:
            raise ValueError("geofence vertices and centre must be finite east/north pairs")

    def breach(self, position_enu: Sequence[float]) -> str | None:
        """Why ``position_enu`` is outside the fence (None when inside, or when it is not known)."""
        e, n, u = (float(v) for v in position_enu)
        if not all(math.isfinite(v) for v in (e, n, u)):
            return None
        if self.max_alt_m > 0 and u > self.max_alt_m:
            return f"{u:.0f} m above the {self.max_alt_m:.0f} m ceiling"
        if self.radius_m > 0:
            d = math.hypot(e - self.center_en[0], n - self.center_en[1])
            if d > self.radius_m:
                return f"{d:.0f} m from the centre, fence radius {self.radius_m:.0f} m"
        if self.polygon_en and not point_in_polygon(e, n, np.reshape(np.asarray(self.polygon_en, float), (-1, 2))):
            return f"outside the fence polygon at ({e:.0f}, {n:.0f})"
        return None
