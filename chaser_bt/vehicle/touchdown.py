"""Was a disarm a landing or a fall? Judged from telemetry alone, as the aircraft reports itself.

"Disarmed" is not "landed": a forced disarm, a crash check or a motor failure disarms an aircraft in
the air, and it falls. Nor is EXTENDED_SYS_STATE's ``ON_GROUND`` enough: ArduCopter's land detector
declares every disarmed aircraft landed at once (Copter::update_land_detector), while the
HEARTBEAT that says "disarmed" comes up to a second later, so a falling aircraft can read "armed,
on the ground". A real landing holds still on the ground for ArduCopter's LAND_DETECTOR_TRIGGER_SEC
(1 s) before it disarms. :class:`TouchdownJudge` therefore calls a disarm a landing only when the
armed reports before it show the aircraft on the ground (``ON_GROUND``, or at home's height) and
still (vertical speed under ``settled_mps``) for ``min_touch_s`` without a break (or from the first
report it saw: an aircraft armed on the ground when the judge started), ending within ``window_s``
of the disarm; otherwise a crash, at the height last reported while armed.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

from chaser_bt.vehicle.state import LandedState, VehicleState

__all__ = ["Touchdown", "TouchdownJudge"]


class Touchdown(enum.Enum):
    """The judge's verdict on the latest disarm."""

    FLYING = "flying"  # armed, or never seen armed: nothing to judge yet
    LANDED = "landed"
    CRASHED = "crashed"


@dataclass
class TouchdownJudge:
    """Judge each armed -> disarmed change seen through :meth:`observe` (see the module docstring).

    Args:
        window_s: how old, in mission seconds, the last armed report may be and still explain the
            disarm (longer than the HEARTBEAT's 1 s period).
        min_touch_s: how long the armed reports must show the aircraft on the ground and still.
        ground_alt_m: below this height above home an armed aircraft counts as on the ground when
            the autopilot does not say ON_GROUND.
        settled_mps: the vertical speed a landed aircraft stays under.
    """

    window_s: float = 3.0
    ground_alt_m: float = 1.0
    settled_mps: float = 1.0
    min_touch_s: float = 1.0
    verdict: Touchdown = Touchdown.FLYING
    detail: str = ""
    _last_armed: tuple[float, bool, float] | None = field(default=None, repr=False)  # (t, touched, alt)
    _touch_since: float | None = field(default=None, repr=False)  # start of the unbroken on-the-ground stretch
    _was_armed: bool = field(default=False, repr=False)

    def observe(self, t: float, state: VehicleState) -> Touchdown:
        """Take the state at mission time ``t``; the verdict on the latest disarm (FLYING while armed)."""
        if state.armed:
            if not self._was_armed:
                self.verdict, self.detail, self._touch_since, self._last_armed = Touchdown.FLYING, "", None, None
            self._was_armed = True
            touched = self._touched(state)
            if not touched:
                self._touch_since = None
            elif self._touch_since is None:  # on the ground at the first look: it was before we looked
                self._touch_since = -math.inf if self._last_armed is None else t
            self._last_armed = (t, touched, state.alt_rel_m)
            return self.verdict
        if self._was_armed:
            self._was_armed = False
            self._judge(t)
        return self.verdict

    def _touched(self, state: VehicleState) -> bool:
        vz = float(state.velocity_enu[2])
        if not (math.isfinite(vz) and abs(vz) < self.settled_mps):
            return False
        if state.landed_state == LandedState.ON_GROUND:
            return True
        if state.landed_state in (LandedState.IN_AIR, LandedState.TAKEOFF):
            return False
        return state.alt_rel_m < self.ground_alt_m

    def _judge(self, t: float) -> None:
        t_armed, touched, alt = self._last_armed if self._last_armed is not None else (-math.inf, False, math.nan)
        held = self._touch_since is not None and t_armed - self._touch_since >= self.min_touch_s
        if touched and held and t - t_armed <= self.window_s:
            self.verdict, self.detail = Touchdown.LANDED, "landed and disarmed"
            return
        where = f"{alt:.1f} m above home" if math.isfinite(alt) else "an unknown height"
        self.verdict = Touchdown.CRASHED
        self.detail = f"disarmed in the air at {where} (no touchdown seen before the disarm)"
