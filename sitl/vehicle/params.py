"""The simulated ArduCopter's parameters: ArduCopter names, units and defaults (4.5/4.6).

Only parameters the simulator obeys are listed, and a few that ground stations read to know the
vehicle (FRAME_CLASS and FRAME_TYPE name the frame in the banner and HEARTBEAT; FENCE_ALT_MIN and
FENCE_MARGIN are stored, not enforced: sitl.vehicle.fence); an unknown name is rejected, as a real
autopilot answers nothing for it. Units are ArduPilot's (centimetres, cm/s, centidegrees,
milliseconds where ArduCopter uses them), so a script that tunes a real copter tunes this one.
Defaults are ArduCopter's except where noted: FS_GCS_ENABLE is 1 (RTL) here, the battery
parameters describe the simulated 6S pack with its low-voltage failsafe set to RTL, and FRAME_CLASS
is 3 (octocopter, the simulated S1000 class; ArduPilot's SITL parameter file sets 1, a quad).
Each MAVLink type is the one a real ArduCopter's PARAM_VALUE carries (checked against the
4.7.0-dev SITL in ``../shared/ardupilot``: INT8 for enums and flags, INT16/INT32 for integers,
REAL32 for floats).

The store keeps a fixed order (PARAM_VALUE's param_index/param_count) and a MAVLink type per
parameter. ``SYSID_MYGCS`` is accepted as the pre-4.6 name of ``MAV_GCS_SYSID``, and ``MAV_SYSID``
(ArduCopter 4.7's name) for ``SYSID_THISMAV``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["ParamSpec", "PARAM_SPECS", "PARAM_ALIASES", "ParamStore",
           "MAV_PARAM_TYPE_INT8", "MAV_PARAM_TYPE_INT16", "MAV_PARAM_TYPE_INT32",
           "MAV_PARAM_TYPE_REAL32"]

MAV_PARAM_TYPE_INT8 = 2
MAV_PARAM_TYPE_INT16 = 4
MAV_PARAM_TYPE_INT32 = 6
MAV_PARAM_TYPE_REAL32 = 9

_INT_TYPES = (MAV_PARAM_TYPE_INT8, MAV_PARAM_TYPE_INT16, MAV_PARAM_TYPE_INT32)
_INT_LIMITS = {
    MAV_PARAM_TYPE_INT8: (-128, 127),
    MAV_PARAM_TYPE_INT16: (-32768, 32767),
    MAV_PARAM_TYPE_INT32: (-(2**31), 2**31 - 1),
}


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: name, default, MAVLink type, unit (for people) and meaning."""

    name: str
    default: float
    mav_type: int
    unit: str
    doc: str


_I8, _I16, _I32 = MAV_PARAM_TYPE_INT8, MAV_PARAM_TYPE_INT16, MAV_PARAM_TYPE_INT32
_F = MAV_PARAM_TYPE_REAL32

PARAM_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("SYSID_THISMAV", 1, _I16, "", "MAVLink system id of this vehicle"),
    ParamSpec("MAV_GCS_SYSID", 255, _I16, "", "system id of the GCS obeyed for overrides and failsafe"),
    ParamSpec("FRAME_CLASS", 3, _I8, "", "frame class: 1 quad, 2 hexa, 3 octa, 4 octa-quad, 5 Y6, ..."),
    ParamSpec("FRAME_TYPE", 1, _I8, "", "motor layout: 0 plus, 1 X, 2 V, 3 H, ..."),
    ParamSpec("ANGLE_MAX", 3000, _I16, "cdeg", "maximum lean angle in all modes"),
    ParamSpec("PILOT_SPEED_UP", 250, _I16, "cm/s", "maximum pilot climb rate"),
    ParamSpec("PILOT_SPEED_DN", 0, _I16, "cm/s", "maximum pilot descent rate (0 = PILOT_SPEED_UP)"),
    ParamSpec("PILOT_ACCEL_Z", 250, _I16, "cm/s/s", "vertical acceleration used with pilot climb rates"),
    ParamSpec("PILOT_Y_RATE", 202.5, _F, "deg/s", "yaw rate at full yaw stick"),
    ParamSpec("THR_DZ", 100, _I16, "PWM", "throttle deadzone around mid-stick in altitude-holding modes"),
    ParamSpec("RC1_DZ", 20, _I16, "PWM", "roll stick deadzone"),
    ParamSpec("RC2_DZ", 20, _I16, "PWM", "pitch stick deadzone"),
    ParamSpec("RC3_DZ", 30, _I16, "PWM", "throttle stick deadzone"),
    ParamSpec("RC4_DZ", 20, _I16, "PWM", "yaw stick deadzone"),
    ParamSpec("RC_OVERRIDE_TIME", 3.0, _F, "s", "RC override timeout (-1 = never, 0 = overrides off)"),
    ParamSpec("WPNAV_SPEED", 1000, _F, "cm/s", "horizontal speed of autonomous navigation"),
    ParamSpec("WPNAV_SPEED_UP", 250, _F, "cm/s", "climb rate of autonomous navigation"),
    ParamSpec("WPNAV_SPEED_DN", 150, _F, "cm/s", "descent rate of autonomous navigation"),
    ParamSpec("WPNAV_ACCEL", 250, _F, "cm/s/s", "horizontal acceleration of autonomous navigation"),
    ParamSpec("WPNAV_ACCEL_Z", 100, _F, "cm/s/s", "vertical acceleration of autonomous navigation"),
    ParamSpec("WPNAV_RADIUS", 200, _F, "cm", "distance at which a waypoint counts as reached"),
    ParamSpec("WPNAV_JERK", 1.0, _F, "m/s/s/s", "jerk of the waypoint S-curves (RTL's legs)"),
    ParamSpec("PSC_JERK_XY", 5.0, _F, "m/s/s/s", "jerk limit of the horizontal position controller's target shaping"),
    ParamSpec("PSC_JERK_Z", 5.0, _F, "m/s/s/s", "jerk limit of the vertical position controller's target shaping"),
    ParamSpec("LOIT_SPEED", 1250, _F, "cm/s", "maximum horizontal speed in LOITER"),
    ParamSpec("LOIT_ACC_MAX", 500, _F, "cm/s/s", "maximum horizontal acceleration in LOITER"),
    ParamSpec("LOIT_BRK_ACCEL", 250, _F, "cm/s/s", "LOITER braking acceleration when the sticks centre"),
    ParamSpec("RTL_ALT", 1500, _I32, "cm", "altitude above home for the return (0 = current altitude)"),
    ParamSpec("RTL_ALT_FINAL", 0, _I16, "cm", "altitude RTL descends to at home (0 = land)"),
    ParamSpec("RTL_CLIMB_MIN", 0, _I16, "cm", "minimum climb before returning"),
    ParamSpec("RTL_CONE_SLOPE", 3.0, _F, "", "return altitude at most slope * distance from home (< 0.5 = no cone)"),
    ParamSpec("RTL_SPEED", 0, _I16, "cm/s", "return speed (0 = WPNAV_SPEED)"),
    ParamSpec("RTL_LOIT_TIME", 5000, _I32, "ms", "time hovering above home before the final descent"),
    ParamSpec("LAND_SPEED", 50, _I16, "cm/s", "descent rate of the final stage of landing"),
    ParamSpec("LAND_SPEED_HIGH", 0, _I16, "cm/s", "descent rate above LAND_ALT_LOW (0 = WPNAV_SPEED_DN)"),
    ParamSpec("LAND_ALT_LOW", 1000, _I16, "cm", "altitude below which landing slows to LAND_SPEED"),
    ParamSpec("DISARM_DELAY", 10, _I8, "s", "disarm after this long landed and idle (0 = never)"),
    ParamSpec("MOT_SPOOL_TIME", 0.5, _F, "s", "time the rotors take to spool up from ground idle (and down)"),
    ParamSpec("TKOFF_SLEW_TIME", 2.0, _F, "s", "take-off throttle ramp, 0 to full, until lift-off is detected"),
    ParamSpec("TKOFF_THR_MAX", 0.9, _F, "", "throttle at which the take-off ramp counts as lifted off"),
    ParamSpec("ARMING_CHECK", 1, _I32, "", "pre-arm checks (0 = only the mandatory ones, otherwise all)"),
    ParamSpec("FS_GCS_ENABLE", 1, _I8, "", "GCS failsafe: 0 off, 1/2/3/6 RTL, 4/5 LAND, 7 BRAKE"),
    ParamSpec("FS_GCS_TIMEOUT", 5.0, _F, "s", "GCS heartbeat silence that triggers the GCS failsafe"),
    ParamSpec("FS_THR_ENABLE", 1, _I8, "", "radio failsafe: 0 off, 1/2/4/6 RTL, 3/5 LAND, 7 BRAKE"),
    ParamSpec("FS_OPTIONS", 16, _I32, "", "failsafe options (bit 2: radio failsafe continues GUIDED; bit 4: GCS "
                                          "failsafe continues a mode the pilot flies)"),
    ParamSpec("RC_FS_TIMEOUT", 1.0, _F, "s", "RC input silence that triggers the radio failsafe"),
    ParamSpec("FS_EKF_ACTION", 1, _I8, "", "EKF failsafe: 1 LAND, 2 ALT_HOLD, 3 LAND in every mode"),
    ParamSpec("GUID_OPTIONS", 0, _I32, "", "GUIDED options (bit 3: attitude-target thrust is thrust)"),
    ParamSpec("GUID_TIMEOUT", 3.0, _F, "s", "GUIDED velocity/attitude target timeout"),
    ParamSpec("BATT_CAPACITY", 10000, _I32, "mAh", "battery capacity for remaining-percent"),
    ParamSpec("BATT_LOW_VOLT", 21.0, _F, "V", "low-battery failsafe voltage (0 = off)"),
    ParamSpec("BATT_LOW_MAH", 0, _F, "mAh", "low-battery failsafe remaining capacity (0 = off)"),
    ParamSpec("BATT_LOW_TIMER", 10, _I8, "s", "time below BATT_LOW_VOLT before the failsafe"),
    ParamSpec("BATT_FS_LOW_ACT", 2, _I8, "", "low-battery action: 0 warn, 1 LAND, 2/3 RTL, 4 LAND"),
    ParamSpec("FENCE_ENABLE", 0, _I8, "", "geofence on (1) or off (0)"),
    ParamSpec("FENCE_TYPE", 7, _I8, "", "fences configured: bit 0 max altitude, 1 circle, 2 polygon, 3 min altitude"),
    ParamSpec("FENCE_ACTION", 1, _I8, "", "on a breach: 0 report, 1 RTL or LAND, 2 LAND, 3/5 RTL, 4 BRAKE"),
    ParamSpec("FENCE_RADIUS", 300, _F, "m", "circular fence radius around home"),
    ParamSpec("FENCE_ALT_MAX", 100, _F, "m", "maximum altitude above home"),
    ParamSpec("FENCE_ALT_MIN", -10, _F, "m", "minimum altitude above home"),
    ParamSpec("FENCE_MARGIN", 2, _F, "m", "distance kept from the fence by avoidance"),
)

PARAM_ALIASES: dict[str, str] = {"SYSID_MYGCS": "MAV_GCS_SYSID", "MAV_SYSID": "SYSID_THISMAV"}


class ParamStore:
    """Ordered parameter values with their MAVLink types; unknown names are rejected.

    ``values`` is the live name -> value dict (read directly on the controller's hot path).
    """

    def __init__(self, overrides: dict[str, float] | None = None) -> None:
        self._specs = {s.name: s for s in PARAM_SPECS}
        self._order = [s.name for s in PARAM_SPECS]
        self._index = {n: i for i, n in enumerate(self._order)}
        self.values: dict[str, float] = {s.name: float(s.default) for s in PARAM_SPECS}
        for name, value in (overrides or {}).items():
            if not self.set(name, value):
                raise KeyError(f"unknown parameter or bad value: {name}={value!r}")

    def canonical(self, name: str) -> str | None:
        """The parameter's current name (resolving aliases), or None when unknown."""
        name = PARAM_ALIASES.get(name, name)
        return name if name in self._specs else None

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and self.canonical(name) is not None

    def names(self) -> list[str]:
        """Parameter names in PARAM_VALUE index order."""
        return list(self._order)

    def count(self) -> int:
        """Number of parameters (PARAM_VALUE.param_count)."""
        return len(self._order)

    def index(self, name: str) -> int:
        """PARAM_VALUE.param_index of ``name``; KeyError when unknown."""
        c = self.canonical(name)
        if c is None:
            raise KeyError(name)
        return self._index[c]

    def mav_type(self, name: str) -> int:
        """MAV_PARAM_TYPE of ``name``; KeyError when unknown."""
        c = self.canonical(name)
        if c is None:
            raise KeyError(name)
        return self._specs[c].mav_type

    def spec(self, name: str) -> ParamSpec:
        """The declaration of ``name``; KeyError when unknown."""
        c = self.canonical(name)
        if c is None:
            raise KeyError(name)
        return self._specs[c]

    def get(self, name: str) -> float:
        """Value of ``name``; KeyError when unknown."""
        c = self.canonical(name)
        if c is None:
            raise KeyError(name)
        return self.values[c]

    def set(self, name: str, value: float) -> bool:
        """Set ``name``; False (and nothing changed) for an unknown name or a non-finite value.

        Integer-typed parameters are rounded and clipped to their type's range, as a value
        packed into PARAM_SET's float is by ArduPilot.
        """
        c = self.canonical(name)
        try:
            v = float(value)
        except (TypeError, ValueError):
            return False
        if c is None or not math.isfinite(v):
            return False
        t = self._specs[c].mav_type
        if t in _INT_TYPES:
            lo, hi = _INT_LIMITS[t]
            v = float(min(max(round(v), lo), hi))
        self.values[c] = v
        return True
