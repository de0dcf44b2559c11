"""The simulated ArduCopter's geofence: which fences are configured, and which are breached.

ArduCopter's AC_Fence in miniature, read from the FENCE_* parameters: a fence is *present* when
FENCE_TYPE configures the circle or an altitude limit (or the polygon, once polygon points are
stored), *enabled* when it is present, FENCE_ENABLE is 1 and FENCE_ACTION is not report-only, and
it *fails* (SYS_STATUS' GEOFENCE health bit cleared) only while a breach is recorded. What is
checked: the circle (horizontal distance from home over FENCE_RADIUS) and the maximum altitude
(height above home over FENCE_ALT_MAX), as AC_Fence does only while FENCE_ENABLE is 1. The
polygon and the minimum altitude count towards "present" but are not checked here (no polygon
geometry is kept; ArduCopter arms the minimum-altitude fence only after first climbing above it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

__all__ = [
    "FENCE_ALT_MAX",
    "FENCE_ALT_MIN",
    "FENCE_CIRCLE",
    "FENCE_GIVE_UP_DISTANCE_M",
    "FENCE_POLYGON",
    "breach_distance",
    "destination_within_fence",
    "fence_breaches",
    "fence_enabled",
    "fence_present",
]

FENCE_ALT_MAX, FENCE_CIRCLE, FENCE_POLYGON, FENCE_ALT_MIN = 1, 2, 4, 8  # FENCE_TYPE bits (AC_FENCE_TYPE_*)
FENCE_GIVE_UP_DISTANCE_M = 100.0  # AC_FENCE_GIVE_UP_DISTANCE: further out than this, LAND instead of RTL
_REPORT_ONLY = 0


def fence_present(p: Mapping[str, float], polygon_points: int = 0) -> bool:
    """AC_Fence::present(): the circle or an altitude fence configured, or a polygon with points."""
    kinds = int(p["FENCE_TYPE"])
    if kinds & (FENCE_CIRCLE | FENCE_ALT_MAX | FENCE_ALT_MIN):
        return True
    return bool(kinds & FENCE_POLYGON) and polygon_points > 0


def fence_enabled(p: Mapping[str, float], polygon_points: int = 0) -> bool:
    """AC_Fence::sys_status_enabled(): present, FENCE_ENABLE on, and an action other than report-only."""
    return (fence_present(p, polygon_points) and int(p["FENCE_ENABLE"]) != 0
            and int(p["FENCE_ACTION"]) != _REPORT_ONLY)


def fence_breaches(p: Mapping[str, float], dist_from_home_m: float, alt_above_home_m: float) -> int:
    """FENCE_TYPE bits breached now (0 while FENCE_ENABLE is off, as AC_Fence checks nothing then)."""
    if int(p["FENCE_ENABLE"]) == 0:
        return 0
    kinds = int(p["FENCE_TYPE"])
    out = 0
    if kinds & FENCE_CIRCLE and dist_from_home_m >= p["FENCE_RADIUS"]:
        out |= FENCE_CIRCLE
    if kinds & FENCE_ALT_MAX and alt_above_home_m >= p["FENCE_ALT_MAX"]:
        out |= FENCE_ALT_MAX
    return out


def destination_within_fence(p: Mapping[str, float], dist_from_home_m: float, alt_above_home_m: float) -> bool:
    """AC_Fence::check_destination_within_fence: GUIDED (ModeGuided::set_destination) refuses a
    target beyond the enabled circle or above the enabled ceiling, and keeps flying the old one."""
    if int(p["FENCE_ENABLE"]) == 0:
        return True
    kinds = int(p["FENCE_TYPE"])
    if kinds & FENCE_ALT_MAX and alt_above_home_m > p["FENCE_ALT_MAX"]:
        return False
    return not (kinds & FENCE_CIRCLE and p["FENCE_RADIUS"] > 0.0 and dist_from_home_m > p["FENCE_RADIUS"])


def breach_distance(p: Mapping[str, float], breaches: int, dist_from_home_m: float,
                    alt_above_home_m: float) -> float:
    """How far outside the breached fences the vehicle is, m (the largest of them)."""
    d = 0.0
    if breaches & FENCE_CIRCLE:
        d = max(d, dist_from_home_m - p["FENCE_RADIUS"])
    if breaches & FENCE_ALT_MAX:
        d = max(d, alt_above_home_m - p["FENCE_ALT_MAX"])
    return d if math.isfinite(d) else math.inf
