"""What the link knows about the aircraft: :class:`VehicleState`, and the telemetry that fills it.

The state is one mutable object the link updates in place as MAVLink arrives, so behaviours can
hold a reference and read it every tick. Everything in it is SI and ENU (DESIGN §3); the MAVLink
units (1e7 degrees, mm, cm/s, centidegrees, NED/FRD, scalar-first quaternions) are converted
here, in :func:`update_state`, and nowhere else.
"""

from __future__ import annotations

import enum
import math
import re
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from scipy.spatial.transform import Rotation

from chaser_bt.geo import (
    GeoPoint,
    LocalFrame,
    body_to_enu_rotation,
    enu_yaw_to_heading,
    heading_to_enu_yaw,
    ned_to_enu,
    quat_wxyz_to_xyzw,
)

__all__ = ["LandedState", "VehicleState", "update_state", "mode_name", "EKF_REQUIRED_FLAGS"]

_NAN = float("nan")
_UINT16_MAX = 65535

# What ArduPilot's EKF must report before it can fly a position-controlled mode: attitude,
# horizontal velocity and an absolute horizontal position (the "EKF3 IMU0 is using GPS" state).
EKF_REQUIRED_FLAGS = mavlink2.EKF_ATTITUDE | mavlink2.EKF_VELOCITY_HORIZ | mavlink2.EKF_POS_HORIZ_ABS
# Flags that mean the position above is not to be trusted even when the required bits are set.
_EKF_BAD_FLAGS = mavlink2.EKF_CONST_POS_MODE | mavlink2.EKF_UNINITIALIZED


class LandedState(enum.IntEnum):
    """MAV_LANDED_STATE as reported in EXTENDED_SYS_STATE."""

    UNDEFINED = 0
    ON_GROUND = 1
    IN_AIR = 2
    TAKEOFF = 3
    LANDING = 4


def _nan3() -> np.ndarray:
    return np.full(3, _NAN)


@dataclass
class VehicleState:
    """The aircraft as last reported; ``nan``/``None``/empty until the first report of each part."""

    t_boot_s: float = _NAN  # vehicle time of the latest message carrying time_boot_ms
    position_enu: np.ndarray = field(default_factory=_nan3)  # m, in the link's frame
    velocity_enu: np.ndarray = field(default_factory=_nan3)  # m/s
    lat_deg: float = _NAN
    lon_deg: float = _NAN
    alt_amsl_m: float = _NAN
    alt_rel_m: float = _NAN  # above home (GLOBAL_POSITION_INT.relative_alt)
    attitude: Rotation | None = None  # FLU body -> ENU (a property, built on first read: see below)
    yaw_enu_rad: float = _NAN
    heading_deg: float = _NAN
    mode: str = ""  # ArduCopter mode name; "" before the first heartbeat
    armed: bool = False
    landed_state: LandedState = LandedState.UNDEFINED
    gps_fix_type: int = 0
    satellites: int = 0
    battery_voltage_v: float = _NAN
    battery_remaining_pct: float = _NAN
    battery_failsafe: bool = False  # the autopilot's own low-battery failsafe has fired (it may take no action)
    rc_channels: tuple[int, ...] = ()  # PWM as the flight controller sees it
    home: GeoPoint | None = None
    prearm_ok: bool = False  # SYS_STATUS health has MAV_SYS_STATUS_PREARM_CHECK
    ekf_ok: bool = False  # EKF_STATUS_REPORT has EKF_REQUIRED_FLAGS
    fence_enabled: bool = False  # SYS_STATUS: the autopilot's geofence is on (GUIDED refuses targets outside it)
    fence_breached: bool = False  # SYS_STATUS: ... and breached now
    statustexts: deque[tuple[float, int, str]] = field(default_factory=lambda: deque(maxlen=50))
    telemetry_rejected: Counter[str] = field(default_factory=Counter)  # messages dropped unbelieved, per reason
    telemetry_fault: str = ""  # why the telemetry cannot be trusted now (a flood of drops, a second sender)
    # The latest reported (roll, pitch, yaw) not yet turned into ``attitude``: ATTITUDE arrives at
    # 10 Hz and scipy's Rotation costs more than the rest of the message, so it is built when read.
    _attitude_euler: tuple[float, float, float] | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def ready_to_arm(self) -> bool:
        """ArduCopter would accept an arm now: pre-arm checks pass, 3-D fix, EKF has a position."""
        return self.prearm_ok and self.gps_fix_type >= 3 and self.ekf_ok

    @property
    def airborne(self) -> bool:
        """Armed and flying (or taking off / landing); altitude decides when landed state is unknown."""
        if not self.armed:
            return False
        if self.landed_state == LandedState.UNDEFINED:
            return self.alt_rel_m > 0.5
        return self.landed_state in (LandedState.IN_AIR, LandedState.TAKEOFF, LandedState.LANDING)


def _get_attitude(s: VehicleState) -> Rotation | None:
    if s._attitude_euler is not None:
        s._attitude, s._attitude_euler = body_to_enu_rotation(*s._attitude_euler), None
    return s._attitude


def _put_attitude(s: VehicleState, attitude: Rotation | None) -> None:
    s._attitude, s._attitude_euler = attitude, None


# The ``attitude`` field, read and written through these (the dataclass' __init__ and repr included).
VehicleState.attitude = property(_get_attitude, _put_attitude, doc="FLU body -> ENU, as last reported.")


def mode_name(custom_mode: int) -> str:
    """ArduCopter mode number -> name as pymavlink spells it (``MODE<n>`` when unknown)."""
    return mavutil.mode_mapping_acm.get(custom_mode, f"MODE{custom_mode}")


def _heartbeat(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    s.mode = mode_name(m.custom_mode)
    s.armed = bool(m.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)


def _global_position(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    s.lat_deg = m.lat * 1e-7
    s.lon_deg = m.lon * 1e-7
    s.alt_amsl_m = m.alt * 1e-3
    s.alt_rel_m = m.relative_alt * 1e-3
    s.velocity_enu = ned_to_enu((m.vx * 0.01, m.vy * 0.01, m.vz * 0.01))
    if frame is not None:
        s.position_enu = frame.to_enu(s.lat_deg, s.lon_deg, s.alt_amsl_m)


def _set_attitude(s: VehicleState, roll: float, pitch: float, yaw: float) -> None:
    s._attitude_euler = (roll, pitch, yaw)
    s.yaw_enu_rad = heading_to_enu_yaw(yaw)
    s.heading_deg = math.degrees(enu_yaw_to_heading(s.yaw_enu_rad))


def _attitude(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    _set_attitude(s, m.roll, m.pitch, m.yaw)


def _attitude_quaternion(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    # MAVLink's quaternion is scalar-first and rotates FRD body into NED.
    r_ned_frd = Rotation.from_quat(quat_wxyz_to_xyzw((m.q1, m.q2, m.q3, m.q4)))
    yaw, pitch, roll = r_ned_frd.as_euler("ZYX")
    _set_attitude(s, float(roll), float(pitch), float(yaw))


def _gps_raw(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    s.gps_fix_type = int(m.fix_type)
    s.satellites = 0 if m.satellites_visible == 255 else int(m.satellites_visible)


def _sys_status(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    s.prearm_ok = bool(m.onboard_control_sensors_health & mavlink2.MAV_SYS_STATUS_PREARM_CHECK)
    fence = mavlink2.MAV_SYS_STATUS_GEOFENCE
    s.fence_enabled = bool(m.onboard_control_sensors_enabled & fence)
    s.fence_breached = s.fence_enabled and not m.onboard_control_sensors_health & fence
    s.battery_voltage_v = _NAN if m.voltage_battery == _UINT16_MAX else m.voltage_battery * 1e-3
    s.battery_remaining_pct = _NAN if m.battery_remaining < 0 else float(m.battery_remaining)


def _battery_status(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    if m.id != 0:
        return
    if m.battery_remaining >= 0:
        s.battery_remaining_pct = float(m.battery_remaining)
    # ArduPilot reports its battery failsafe level here (AP_BattMonitor::get_mavlink_charge_state)
    s.battery_failsafe = int(getattr(m, "charge_state", 0)) >= mavlink2.MAV_BATTERY_CHARGE_STATE_LOW


def _extended_sys_state(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    try:
        s.landed_state = LandedState(m.landed_state)
    except ValueError:
        s.landed_state = LandedState.UNDEFINED


def _ekf_status(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    s.ekf_ok = (m.flags & EKF_REQUIRED_FLAGS) == EKF_REQUIRED_FLAGS and not m.flags & _EKF_BAD_FLAGS


def _home_position(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    s.home = GeoPoint(m.latitude * 1e-7, m.longitude * 1e-7, m.altitude * 1e-3)


def _rc_channels(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    n = min(int(m.chancount), 18)
    s.rc_channels = tuple(int(getattr(m, f"chan{i}_raw")) for i in range(1, n + 1))


def _statustext(s: VehicleState, m: Any, frame: LocalFrame | None) -> None:
    text = statustext_str(m)
    s.statustexts.append((s.t_boot_s, int(m.severity), text))
    if _BATTERY_FAILSAFE_TEXT.match(text):  # AP_BattMonitor's "Battery 1 is low 10.40V used 0 mAh"
        s.battery_failsafe = True


def statustext_str(m: Any) -> str:
    """STATUSTEXT's text as a clean string (pymavlink may hand bytes, padded with NULs)."""
    text = m.text.decode("utf-8", "replace") if isinstance(m.text, (bytes, bytearray)) else m.text
    return text.rstrip("\x00").strip()


_BATTERY_FAILSAFE_TEXT = re.compile(r"Battery \d+ is (low|critical)\b", re.IGNORECASE)

_Handler = Callable[[VehicleState, Any, "LocalFrame | None"], None]
_HANDLERS: dict[str, _Handler] = {
    "HEARTBEAT": _heartbeat,
    "GLOBAL_POSITION_INT": _global_position,
    "ATTITUDE": _attitude,
    "ATTITUDE_QUATERNION": _attitude_quaternion,
    "GPS_RAW_INT": _gps_raw,
    "SYS_STATUS": _sys_status,
    "BATTERY_STATUS": _battery_status,
    "EXTENDED_SYS_STATE": _extended_sys_state,
    "EKF_STATUS_REPORT": _ekf_status,
    "HOME_POSITION": _home_position,
    "RC_CHANNELS": _rc_channels,
    "STATUSTEXT": _statustext,
}


def update_state(state: VehicleState, msg: Any, frame: LocalFrame | None) -> bool:
    """Apply one autopilot message to ``state``; ``frame`` places GLOBAL_POSITION_INT in ENU.

    Returns whether the message type carries state (others are left to the caller).
    """
    t_ms = getattr(msg, "time_boot_ms", None)
    if t_ms is not None:
        state.t_boot_s = t_ms * 1e-3
    handler = _HANDLERS.get(msg.get_type())
    if handler is None:
        return t_ms is not None
    handler(state, msg, frame)
    return True
