"""Where to fly towards a radar cue (paper section 2.2.1, state 3: "fly out to cue location").

The chaser does not fly *to* the cue: it flies to a point ``standoff_m`` short of it along the
line from the cue to the chaser, at a safe altitude, facing the cue, so that the camera (fixed,
looking forward and slightly down) has the intruder in view when it arrives and vision can take
over (state 5). Already closer than the standoff, it backs off to it along the same line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ["CueApproach", "approach_point"]


@dataclass(frozen=True)
class CueApproach:
    """A GUIDED goal: ENU position (m) and the ENU yaw (rad, counter-clockwise from east) facing the cue."""

    goal_enu: np.ndarray
    yaw_enu_rad: float
    distance_m: float  # horizontal distance from the chaser to the goal


def approach_point(own_enu: Sequence[float], cue_enu: Sequence[float], *, standoff_m: float, min_alt_m: float,
                   height_above_m: float) -> CueApproach:
    """The approach goal for a chaser at ``own_enu`` and a cue at ``cue_enu``.

    Args:
        standoff_m: horizontal distance to stop short of the cue (>= 0).
        min_alt_m: never lower than this above the origin (home).
        height_above_m: the goal's height above the cue (the follow geometry's relative height).
    """
    own = np.asarray(own_enu, dtype=float)
    cue = np.asarray(cue_enu, dtype=float)
    if standoff_m < 0:
        raise ValueError(f"standoff_m {standoff_m}: expected >= 0")
    away = own[:2] - cue[:2]
    dist = float(np.hypot(*away))
    if dist > 1e-6:
        xy = cue[:2] + away * (standoff_m / dist)
    else:  # right above the cue: no direction to keep, stay put horizontally
        xy = own[:2].copy()
    goal = np.array([xy[0], xy[1], max(min_alt_m, cue[2] + height_above_m)])
    look = cue[:2] - goal[:2]
    yaw = math.atan2(look[1], look[0]) if float(np.hypot(*look)) > 1e-6 else math.atan2(-away[1], -away[0])
    return CueApproach(goal, yaw, float(np.hypot(*(goal[:2] - own[:2]))))
