"""Where a rehearsal left the aircraft, scored from the simulator's truth: safe, or not, and since when.

Safe is what a pilot standing by would accept without touching the sticks: on the ground and
disarmed, flying itself under the autopilot (RTL, LAND, LOITER, BRAKE: its own return, descent or
hold), or holding still (under 1 m/s horizontally and 0.5 m/s vertically) in any mode. A crash
is never safe, and neither is an aircraft still moving on the mission's last command. The watch
keeps the start of the current safe stretch, so after a fault the time to safe is the time to the
stretch that lasted to the end.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sitl.vehicle.autopilot import TruthState

__all__ = ["SELF_FLYING_MODES", "SafeWatch", "safe_state"]

#: Modes in which ArduCopter flies the aircraft on its own to a hold or to the ground.
SELF_FLYING_MODES = ("RTL", "LAND", "LOITER", "BRAKE", "SMART_RTL", "POSHOLD")


def safe_state(truth: TruthState, mode: str, armed: bool) -> str:
    """``landed``, ``holding``, ``under the autopilot (MODE)`` (all safe), or ``crashed`` / ``moving``."""
    if truth.crashed:
        return "crashed"
    if truth.on_ground:
        return "landed"  # disarmed, or armed on the ground (ArduCopter disarms it after DISARM_DELAY)
    if armed and mode in SELF_FLYING_MODES:
        return f"under the autopilot ({mode})"
    v = truth.vel_enu
    if math.hypot(v[0], v[1]) < 1.0 and abs(v[2]) < 0.5:
        return "holding"
    return "moving" if armed else "falling"


def _is_safe(state: str) -> bool:
    return state not in ("crashed", "moving", "falling")


@dataclass
class SafeWatch:
    """Observe the truth over time; the state at the end and when its safe stretch began."""

    state: str = ""
    safe_since_s: float | None = None

    def observe(self, t: float, truth: TruthState, mode: str, armed: bool) -> None:
        self.state = safe_state(truth, mode, armed)
        if not _is_safe(self.state):
            self.safe_since_s = None
        elif self.safe_since_s is None:
            self.safe_since_s = t

    @property
    def safe(self) -> bool:
        return _is_safe(self.state)

    def time_to_safe(self, fault_at_s: float | None) -> float | None:
        """Seconds from ``fault_at_s`` to the safe stretch that lasted to the end (None: no fault, or not safe)."""
        if fault_at_s is None or not self.safe or self.safe_since_s is None:
            return None
        return max(0.0, self.safe_since_s - fault_at_s)
