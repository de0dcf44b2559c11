"""Telemetry: which message is due when (ArduPilot's streams and intervals, on sim time) and its encoding.

ArduPilot sends telemetry in *streams* (``SRn_POSITION``, ``SRn_EXTRA1`` ...), each a group of
messages at one rate, and lets a client override any single message with
``MAV_CMD_SET_MESSAGE_INTERVAL`` (GCS_MAVLINK_Parameters.cpp, GCS_Common.cpp). This module keeps
both: a stream rate per group, and an optional interval per message that wins over its group.

Default rates: ArduCopter's firmware default for every ``SRn_*`` is 0 Hz, but nobody sees that in
practice, because MAVProxy (which ``sim_vehicle.py`` starts with every SITL) immediately asks for all
streams at 4 Hz with REQUEST_DATA_STREAM. A stock client that asks for nothing should still see a
live vehicle, so the defaults here are what ArduCopter SITL with MAVProxy sends: every stream at
4 Hz, HEARTBEAT at 1 Hz. Messages that ArduPilot only sends on request or on change
(ATTITUDE_QUATERNION, HOME_POSITION, AUTOPILOT_VERSION) start disabled.

Scheduling is on simulated seconds, so rates are the same at 1x and 100x real time.

Encoding (:class:`TelemetryEncoder`) is on the simulator's hot path (a rehearsal runs at 20-100x
real time): periodic messages are pre-built pymavlink message objects whose fields are
overwritten and packed in place, and the position estimate is read once per update. Units and
frames convert here: ENU -> NED, metres -> mm/cm, degrees -> 1e7 integers and centidegrees,
FRD Euler -> scalar-first quaternion. Every time field is the simulator's clock.
"""

from __future__ import annotations

import math
import os
from typing import Callable

os.environ["MAVLINK20"] = "1"

from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from chaser_bt.geo import enu_to_ned, quat_xyzw_to_wxyz  # noqa: E402
from sitl.vehicle.autopilot import Autopilot  # noqa: E402
from sitl.vehicle.fence import fence_enabled, fence_present  # noqa: E402

__all__ = [
    "STREAM_GROUPS", "DEFAULT_STREAM_RATE_HZ", "StreamScheduler", "TelemetryEncoder",
    "CAPABILITIES", "FLIGHT_SW_VERSION", "FIRMWARE_STRING", "BUILD_ID", "FRAME_CLASSES", "banner_lines",
]

# MAV_DATA_STREAM id -> the message ids ArduCopter sends in it (only those this simulator produces).
STREAM_GROUPS: dict[int, tuple[int, ...]] = {
    mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS: (
        mavlink2.MAVLINK_MSG_ID_SYS_STATUS,
        mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT,
        mavlink2.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    ),
    mavlink2.MAV_DATA_STREAM_POSITION: (
        mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    ),
    mavlink2.MAV_DATA_STREAM_RC_CHANNELS: (mavlink2.MAVLINK_MSG_ID_RC_CHANNELS,),
    mavlink2.MAV_DATA_STREAM_EXTRA1: (mavlink2.MAVLINK_MSG_ID_ATTITUDE,),
    mavlink2.MAV_DATA_STREAM_EXTRA2: (mavlink2.MAVLINK_MSG_ID_VFR_HUD,),
    mavlink2.MAV_DATA_STREAM_EXTRA3: (
        mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME,
        mavlink2.MAVLINK_MSG_ID_EKF_STATUS_REPORT,
        mavlink2.MAVLINK_MSG_ID_BATTERY_STATUS,
    ),
}

DEFAULT_STREAM_RATE_HZ = 4.0
HEARTBEAT_INTERVAL_S = 1.0
_EPS_S = 1e-6  # sim time is a float sum of steps: a message due "now" must not slip a step

# Sent only when asked for (MAV_CMD_SET_MESSAGE_INTERVAL / REQUEST_MESSAGE) or on change.
ON_REQUEST_ONLY: tuple[int, ...] = (
    mavlink2.MAVLINK_MSG_ID_ATTITUDE_QUATERNION,
    mavlink2.MAVLINK_MSG_ID_HOME_POSITION,
    mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
)


class StreamScheduler:
    """Per-message send intervals in sim seconds; :meth:`due` says which are due at time ``t``.

    A message's interval is its own override if set (``set_interval``), else its stream group's rate.
    ``None`` means "not sent". Phase is kept (next due = last due + interval) so long-run rates are
    exact even when the physics step does not divide the interval.
    """

    def __init__(self) -> None:
        self._group_of: dict[int, int] = {}
        for stream_id, ids in STREAM_GROUPS.items():
            for msg_id in ids:
                self._group_of[msg_id] = stream_id
        self._stream_rate_hz: dict[int, float] = {s: DEFAULT_STREAM_RATE_HZ for s in STREAM_GROUPS}
        self._override_s: dict[int, float | None] = {}
        self._interval_s: dict[int, float | None] = {}
        self._next_due: dict[int, float] = {}
        self._earliest = math.inf
        for msg_id in self.known_ids():
            self._refresh(msg_id, now=0.0)

    @staticmethod
    def known_ids() -> tuple[int, ...]:
        """Every message id this scheduler can send."""
        grouped = tuple(i for ids in STREAM_GROUPS.values() for i in ids)
        return (mavlink2.MAVLINK_MSG_ID_HEARTBEAT, *grouped, *ON_REQUEST_ONLY)

    def default_interval(self, msg_id: int) -> float | None:
        """The interval ``msg_id`` has without a per-message override (its stream's rate)."""
        if msg_id == mavlink2.MAVLINK_MSG_ID_HEARTBEAT:
            return HEARTBEAT_INTERVAL_S
        stream = self._group_of.get(msg_id)
        if stream is None:
            return None
        rate = self._stream_rate_hz[stream]
        return 1.0 / rate if rate > 0.0 else None

    def interval(self, msg_id: int) -> float | None:
        """Current interval of ``msg_id`` in seconds, ``None`` when it is not sent."""
        return self._interval_s.get(msg_id)

    def set_interval(self, msg_id: int, interval_s: float | None, now: float) -> None:
        """Override one message: ``interval_s`` seconds, or ``None`` to stop it."""
        self._override_s[msg_id] = interval_s
        self._refresh(msg_id, now)

    def reset_interval(self, msg_id: int, now: float) -> None:
        """Drop the override of ``msg_id``: back to its stream's rate."""
        self._override_s.pop(msg_id, None)
        self._refresh(msg_id, now)

    def set_stream_rate(self, stream_id: int, rate_hz: float, now: float) -> None:
        """REQUEST_DATA_STREAM: set one group's rate (``MAV_DATA_STREAM_ALL`` = every group)."""
        streams = list(STREAM_GROUPS) if stream_id == mavlink2.MAV_DATA_STREAM_ALL else [stream_id]
        for stream in streams:
            if stream not in STREAM_GROUPS:
                continue
            self._stream_rate_hz[stream] = max(0.0, float(rate_hz))
            for msg_id in STREAM_GROUPS[stream]:
                self._refresh(msg_id, now)

    def due(self, now: float) -> list[int]:
        """Message ids due at ``now``, in a fixed order; advances their next due time."""
        now += _EPS_S
        if now < self._earliest:
            return []
        out = []
        earliest = math.inf
        for msg_id, t_due in self._next_due.items():
            if now >= t_due:
                out.append(msg_id)
                step = self._interval_s[msg_id]
                t_due += step
                if t_due <= now:  # fell behind (interval shorter than a physics step): no bursts
                    t_due = now + step
                self._next_due[msg_id] = t_due
            earliest = min(earliest, t_due)
        self._earliest = earliest
        return out

    def _refresh(self, msg_id: int, now: float) -> None:
        if msg_id in self._override_s:
            interval = self._override_s[msg_id]
        else:
            interval = self.default_interval(msg_id)
        self._interval_s[msg_id] = interval
        if interval is None:
            self._next_due.pop(msg_id, None)
        else:
            self._next_due[msg_id] = now
        self._earliest = min(self._next_due.values(), default=math.inf)


# AUTOPILOT_VERSION.flight_sw_version: major << 24 | minor << 16 | patch << 8 | FIRMWARE_VERSION_TYPE
FLIGHT_SW_VERSION = (4 << 24) | (6 << 16) | (0 << 8) | mavlink2.FIRMWARE_VERSION_TYPE_OFFICIAL
FIRMWARE_STRING = "ArduCopter V4.6.0"
# flight_custom_version: ArduPilot puts the first 8 characters of its git hash here and in the
# banner's "(...)"; this build is chaser-bt's simulator, and says so in the same 8 characters.
BUILD_ID = "chaserbt"
# The bits ArduCopter sets (GCS_MAVLINK::capabilities(); the 4.7.0-dev SITL reports 64495) less
# those for what the simulator lacks: TERRAIN, FLIGHT_TERMINATION, COMPASS_CALIBRATION. FTP: the
# parameter file only (sitl.vehicle.mavftp), which is what ground stations use it for.
CAPABILITIES = (
    mavlink2.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | mavlink2.MAV_PROTOCOL_CAPABILITY_FTP
    | mavlink2.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
    | mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
    | mavlink2.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
)

# FRAME_CLASS -> HEARTBEAT type and the banner's frame name (AP_MotorsMatrix get_frame_string /
# Copter get_frame_mav_type); FRAME_TYPE -> the banner's layout name (get_type_string).
FRAME_CLASSES: dict[int, tuple[int, str]] = {
    1: (mavlink2.MAV_TYPE_QUADROTOR, "QUAD"),
    2: (mavlink2.MAV_TYPE_HEXAROTOR, "HEXA"),
    3: (mavlink2.MAV_TYPE_OCTOROTOR, "OCTA"),
    4: (mavlink2.MAV_TYPE_OCTOROTOR, "OCTAQUAD"),
    5: (mavlink2.MAV_TYPE_HEXAROTOR, "Y6"),
    12: (mavlink2.MAV_TYPE_DODECAROTOR, "DODECA_HEXA"),
    14: (mavlink2.MAV_TYPE_DECAROTOR, "DECA"),
}
FRAME_TYPES: dict[int, str] = {0: "PLUS", 1: "X", 2: "V", 3: "H", 4: "V_TAIL", 5: "A_TAIL", 10: "Y6B",
                               11: "Y6F", 12: "BF_X", 13: "DJI_X", 14: "CW_X", 18: "BF_X_REV"}


def banner_lines(frame_class: int, frame_type: int) -> list[str]:
    """The STATUSTEXTs of GCS_MAVLINK_Copter::send_banner: firmware and build, then the frame.

    ArduPilot sends a line with the board's unique id between them when the board has one; the
    simulated board has none, so that line is left out, as ArduPilot leaves it out then.
    """
    name = FRAME_CLASSES.get(frame_class, (0, "UNKNOWN"))[1]
    layout = FRAME_TYPES.get(frame_type, "UNKNOWN")
    return [f"{FIRMWARE_STRING} ({BUILD_ID})", f"Frame: {name}/{layout}"]

# Copter mode numbers whose controller holds horizontal position: HEARTBEAT's GUIDED_ENABLED flag
# (ArduCopter base_mode(): pos_control->is_active_xy()) and SYS_STATUS' XY control bit.
_POSITION_MODES = frozenset({4, 5, 6, 9, 17})  # GUIDED, LOITER, RTL, LAND, BRAKE
_ALTITUDE_MODES = _POSITION_MODES | {2}  # + ALT_HOLD

_SENSORS = (
    mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink2.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink2.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mavlink2.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mavlink2.MAV_SYS_STATUS_SENSOR_RC_RECEIVER  # the SITL's RC input: healthy until a radio failsafe
)
_BATTERY = mavlink2.MAV_SYS_STATUS_SENSOR_BATTERY
_GEOFENCE = mavlink2.MAV_SYS_STATUS_GEOFENCE
_PROXIMITY = mavlink2.MAV_SYS_STATUS_SENSOR_PROXIMITY
_GPS = mavlink2.MAV_SYS_STATUS_SENSOR_GPS
_AHRS = mavlink2.MAV_SYS_STATUS_AHRS
_PREARM = mavlink2.MAV_SYS_STATUS_PREARM_CHECK
_RATE_ATT_YAW = (
    mavlink2.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mavlink2.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mavlink2.MAV_SYS_STATUS_SENSOR_YAW_POSITION
)
_Z_CTRL = mavlink2.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
_XY_CTRL = mavlink2.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
_MOTORS = mavlink2.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
_SYS_PRESENT = _SENSORS | _BATTERY | _GPS | _AHRS | _PREARM | _RATE_ATT_YAW | _Z_CTRL | _XY_CTRL | _MOTORS

# EKF_STATUS_REPORT: attitude and vertical state come from IMU and baro at boot; the horizontal
# (GPS-aided) solution only once the EKF has its absolute position (ekf_ok).
_EKF_ALWAYS = mavlink2.EKF_ATTITUDE | mavlink2.EKF_VELOCITY_VERT | mavlink2.EKF_POS_VERT_ABS
_EKF_HORIZONTAL = (
    mavlink2.EKF_VELOCITY_HORIZ
    | mavlink2.EKF_POS_HORIZ_REL
    | mavlink2.EKF_POS_HORIZ_ABS
    | mavlink2.EKF_PRED_POS_HORIZ_REL
    | mavlink2.EKF_PRED_POS_HORIZ_ABS
)

_U16_MAX = 65535


def _clamp_int(x: float, lo: int, hi: int) -> int:
    """Round to the nearest int inside a MAVLink field's range (so pack() can never fail)."""
    if not math.isfinite(x):
        if x != x:  # NaN: "unknown" is UINT16_MAX in unsigned 16-bit fields, else 0
            return hi if hi == _U16_MAX else 0
        return hi if x > 0 else lo
    v = int(round(x))
    return lo if v < lo else hi if v > hi else v


def _i16(x: float) -> int:
    return _clamp_int(x, -32768, 32767)


def _i32(x: float) -> int:
    return _clamp_int(x, -(2**31), 2**31 - 1)


def _u16(x: float) -> int:
    return _clamp_int(x, 0, _U16_MAX)


def _cdeg(angle_deg: float) -> int:
    """An angle in degrees as MAVLink centidegrees in [0, 36000); UINT16_MAX when unknown."""
    if not math.isfinite(angle_deg):
        return _U16_MAX
    return int(round(angle_deg * 100.0)) % 36000


class TelemetryEncoder:
    """Encodes the vehicle's telemetry messages from :class:`~sitl.vehicle.autopilot.Autopilot` state.

    Args:
        autopilot: the state to report.
        emit: packs and queues one message (the endpoint's, which owns the sequence number).
        start_unix_s: wall-clock epoch of boot, for SYSTEM_TIME.
        mav_type: HEARTBEAT type.
    """

    def __init__(
        self, autopilot: Autopilot, emit: Callable[[object], None], *, start_unix_s: float, mav_type: int
    ) -> None:
        self._ap = autopilot
        self._emit = emit
        self._start_unix_s = float(start_unix_s)
        self._mav_type = mav_type
        self._t_ms = 0
        self._estimate = None  # position estimate, fetched at most once per update
        self._build_messages()
        # msg id -> encodes that message from the autopilot's state now
        self.senders: dict[int, Callable[[], None]] = {
            mavlink2.MAVLINK_MSG_ID_HEARTBEAT: self._send_heartbeat,
            mavlink2.MAVLINK_MSG_ID_SYS_STATUS: self._send_sys_status,
            mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT: self._send_gps_raw_int,
            mavlink2.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: self._send_extended_sys_state,
            mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self._send_global_position_int,
            mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED: self._send_local_position_ned,
            mavlink2.MAVLINK_MSG_ID_RC_CHANNELS: self._send_rc_channels,
            mavlink2.MAVLINK_MSG_ID_ATTITUDE: self._send_attitude,
            mavlink2.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: self._send_attitude_quaternion,
            mavlink2.MAVLINK_MSG_ID_VFR_HUD: self._send_vfr_hud,
            mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME: self._send_system_time,
            mavlink2.MAVLINK_MSG_ID_EKF_STATUS_REPORT: self._send_ekf_status_report,
            mavlink2.MAVLINK_MSG_ID_BATTERY_STATUS: self._send_battery_status,
            mavlink2.MAVLINK_MSG_ID_HOME_POSITION: self._send_home_position,
            mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION: self._send_autopilot_version,
        }

    def begin(self) -> None:
        """Start of an update: take the time, forget the cached position estimate."""
        self._t_ms = int(round(self._ap.time_s * 1000.0))
        self._estimate = None

    def _build_messages(self) -> None:
        """The pre-built periodic messages whose fields are overwritten before each pack."""
        m = mavlink2
        self._m_heartbeat = m.MAVLink_heartbeat_message(self._mav_type, m.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 0, 3)
        self._m_sys_status = m.MAVLink_sys_status_message(*([0] * 13))
        self._m_gps = m.MAVLink_gps_raw_int_message(*([0] * 10))
        self._m_ext_state = m.MAVLink_extended_sys_state_message(m.MAV_VTOL_STATE_UNDEFINED, 0)
        self._m_gpi = m.MAVLink_global_position_int_message(*([0] * 9))
        self._m_lpn = m.MAVLink_local_position_ned_message(*([0] * 7))
        self._m_rc = m.MAVLink_rc_channels_message(*([0] * 20), 255)
        self._m_att = m.MAVLink_attitude_message(*([0] * 7))
        self._m_attq = m.MAVLink_attitude_quaternion_message(0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self._m_vfr = m.MAVLink_vfr_hud_message(*([0] * 6))
        self._m_time = m.MAVLink_system_time_message(0, 0)
        self._m_ekf = m.MAVLink_ekf_status_report_message(0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self._m_batt = m.MAVLink_battery_status_message(
            0, m.MAV_BATTERY_FUNCTION_ALL, m.MAV_BATTERY_TYPE_LIPO, 32767, [_U16_MAX] * 10, -1, -1, -1, -1
        )

    def _position(self):
        if self._estimate is None:
            self._estimate = self._ap.position_estimate()
        return self._estimate

    def _send_heartbeat(self) -> None:
        ap = self._ap
        m = self._m_heartbeat
        # ArduCopter base_mode(): STABILIZE | MANUAL_INPUT always, GUIDED when the position
        # controller is active, SAFETY_ARMED when armed, CUSTOM_MODE_ENABLED always.
        base = (
            mavlink2.MAV_MODE_FLAG_STABILIZE_ENABLED
            | mavlink2.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
            | mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        )
        mode = ap.mode_number
        if mode in _POSITION_MODES:
            base |= mavlink2.MAV_MODE_FLAG_GUIDED_ENABLED
        if ap.armed:
            base |= mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
        m.base_mode = base
        m.custom_mode = mode
        m.system_status = self._system_status()
        self._emit(m)

    def _system_status(self) -> int:
        """ArduCopter vehicle_system_status(): CRITICAL on any failsafe, STANDBY landed, else ACTIVE."""
        ap = self._ap
        if ap.fs_gcs or ap.fs_battery or ap.fs_ekf:
            return mavlink2.MAV_STATE_CRITICAL
        if ap.landed_state == mavlink2.MAV_LANDED_STATE_ON_GROUND:
            return mavlink2.MAV_STATE_STANDBY
        return mavlink2.MAV_STATE_ACTIVE

    def sensor_bits(self) -> tuple[int, int, int]:
        """SYS_STATUS (present, enabled, health), as GCS::update_sensor_status_flags and
        GCS_Copter::update_vehicle_sensor_status_flags set them for what the simulator models.

        Motor outputs are enabled armed or not (no safety switch, as in ArduPilot's SITL); the
        position and altitude controllers are enabled and healthy in the modes that run them; the
        pre-arm bit is enabled while ARMING_CHECK is non-zero; the battery is unhealthy once its
        failsafe has fired; the geofence follows :mod:`sitl.vehicle.fence`; PROXIMITY is healthy
        (no rangefinder connected, as ArduCopter reports it). LOGGING, TERRAIN and PROPULSION,
        which the real SITL also reports, are absent: the simulator keeps no onboard log, no
        terrain database and no ESC telemetry.
        """
        ap = self._ap
        p = ap.p
        mode = ap.mode_number
        present = _SYS_PRESENT
        enabled = _SENSORS | _BATTERY | _GPS | _AHRS | _RATE_ATT_YAW | _MOTORS
        health = _SENSORS | _RATE_ATT_YAW | _MOTORS | _PROXIMITY
        if mode in _ALTITUDE_MODES:
            enabled |= _Z_CTRL
            health |= _Z_CTRL
        if mode in _POSITION_MODES:
            enabled |= _XY_CTRL
            health |= _XY_CTRL
        if p["ARMING_CHECK"] != 0:
            enabled |= _PREARM
        if ap.gps_ok:
            health |= _GPS
        if ap.ekf_ok:
            health |= _AHRS
        if ap.prearm_ok:
            health |= _PREARM  # how ArduPilot tells a GCS it is ready to arm
        if not ap.fs_battery:
            health |= _BATTERY
        if ap.fs_radio:
            health &= ~mavlink2.MAV_SYS_STATUS_SENSOR_RC_RECEIVER  # no valid RC input
        polygon = ap.missions.polygon_points()
        if fence_present(p, polygon):
            present |= _GEOFENCE
            if fence_enabled(p, polygon):
                enabled |= _GEOFENCE
            if not ap.fence_breaches:
                health |= _GEOFENCE
        else:
            health |= _GEOFENCE  # AC_Fence::sys_status_failed(): never failed when not present
        return present, enabled, health

    def _send_sys_status(self) -> None:
        ap = self._ap
        m = self._m_sys_status
        batt = ap.battery()
        (m.onboard_control_sensors_present, m.onboard_control_sensors_enabled,
         m.onboard_control_sensors_health) = self.sensor_bits()
        m.load = 200  # 20 % main-loop load, a typical SITL figure
        m.voltage_battery = _u16(batt.voltage_v * 1000.0)
        m.current_battery = _i16(batt.current_a * 100.0)
        m.battery_remaining = _clamp_int(batt.remaining_pct, 0, 100)
        # AP_BattMonitor::get_mavlink_charge_state: the failsafe level, LOW once the low failsafe fired
        m.charge_state = mavlink2.MAV_BATTERY_CHARGE_STATE_LOW if self._ap.fs_battery else mavlink2.MAV_BATTERY_CHARGE_STATE_OK
        self._emit(m)

    def _send_gps_raw_int(self) -> None:
        gps = self._ap.gps()
        m = self._m_gps
        vn, ve = float(gps.vel_ned[0]), float(gps.vel_ned[1])
        m.time_usec = self._t_ms * 1000
        m.fix_type = int(gps.fix_type)
        m.lat = _i32(gps.lat_deg * 1e7)
        m.lon = _i32(gps.lon_deg * 1e7)
        m.alt = _i32(gps.alt_amsl_m * 1000.0)
        m.eph = _u16(gps.eph_m * 100.0)
        m.epv = _u16(gps.epv_m * 100.0)
        m.vel = _u16(math.hypot(vn, ve) * 100.0)
        m.cog = _cdeg(math.degrees(gps.cog_rad))
        m.satellites_visible = int(gps.satellites)
        m.h_acc = _clamp_int(gps.eph_m * 1000.0, 0, 2**32 - 1)
        m.v_acc = _clamp_int(gps.epv_m * 1000.0, 0, 2**32 - 1)
        self._emit(m)

    def _send_extended_sys_state(self) -> None:
        m = self._m_ext_state
        m.landed_state = int(self._ap.landed_state)
        self._emit(m)

    def _send_global_position_int(self) -> None:
        est = self._position()
        vel = est.vel_enu
        m = self._m_gpi
        m.time_boot_ms = self._t_ms
        m.lat = _i32(est.lat_deg * 1e7)
        m.lon = _i32(est.lon_deg * 1e7)
        m.alt = _i32(est.alt_amsl_m * 1000.0)
        m.relative_alt = _i32(est.alt_rel_m * 1000.0)
        m.vx = _i16(vel[1] * 100.0)  # north
        m.vy = _i16(vel[0] * 100.0)  # east
        m.vz = _i16(-vel[2] * 100.0)  # down
        m.hdg = _cdeg(self._ap.heading_deg)
        self._emit(m)

    def _send_local_position_ned(self) -> None:
        est = self._position()
        pos, vel = est.pos_enu, est.vel_enu
        m = self._m_lpn
        m.time_boot_ms = self._t_ms
        m.x, m.y, m.z = float(pos[1]), float(pos[0]), -float(pos[2])
        m.vx, m.vy, m.vz = float(vel[1]), float(vel[0]), -float(vel[2])
        self._emit(m)

    def _send_rc_channels(self) -> None:
        ch = self._ap.rc_channels()
        m = self._m_rc
        m.time_boot_ms = self._t_ms
        m.chancount = len(ch)
        values = [_u16(c) for c in ch[:18]] + [_U16_MAX] * (18 - min(len(ch), 18))
        (
            m.chan1_raw, m.chan2_raw, m.chan3_raw, m.chan4_raw, m.chan5_raw, m.chan6_raw,
            m.chan7_raw, m.chan8_raw, m.chan9_raw, m.chan10_raw, m.chan11_raw, m.chan12_raw,
            m.chan13_raw, m.chan14_raw, m.chan15_raw, m.chan16_raw, m.chan17_raw, m.chan18_raw,
        ) = values  # fmt: skip
        self._emit(m)

    def _send_attitude(self) -> None:
        m = self._m_att
        m.time_boot_ms = self._t_ms
        m.roll, m.pitch, m.yaw, m.rollspeed, m.pitchspeed, m.yawspeed = self._ap.attitude()
        self._emit(m)

    def _send_attitude_quaternion(self) -> None:
        roll, pitch, yaw, p, q, r = self._ap.attitude()
        w, x, y, z = quat_xyzw_to_wxyz(Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat())
        m = self._m_attq
        m.time_boot_ms = self._t_ms
        m.q1, m.q2, m.q3, m.q4 = float(w), float(x), float(y), float(z)
        m.rollspeed, m.pitchspeed, m.yawspeed = p, q, r
        self._emit(m)

    def _send_vfr_hud(self) -> None:
        ap = self._ap
        est = self._position()
        m = self._m_vfr
        m.airspeed = float(ap.airspeed_mps)
        m.groundspeed = float(ap.groundspeed_mps)
        m.heading = _clamp_int(ap.heading_deg, 0, 359) if ap.heading_deg < 359.5 else 0
        m.throttle = _clamp_int(ap.throttle_pct, 0, 100)
        m.alt = float(est.alt_amsl_m)  # ArduPilot vfr_hud_alt(): AMSL unless a dev option says otherwise
        m.climb = float(est.vel_enu[2])
        self._emit(m)

    def _send_system_time(self) -> None:
        m = self._m_time
        m.time_boot_ms = self._t_ms
        m.time_unix_usec = int(round(self._start_unix_s * 1e6)) + self._t_ms * 1000
        self._emit(m)

    def _send_ekf_status_report(self) -> None:
        ok = self._ap.ekf_ok
        m = self._m_ekf
        m.flags = _EKF_ALWAYS | (_EKF_HORIZONTAL if ok else 0)
        # normalised innovation test ratios: < 0.5 is good, > 1 is failing (ArduPilot's GCS colours)
        m.velocity_variance = 0.05 if ok else 1.0
        m.pos_horiz_variance = 0.05 if ok else 1.0
        m.pos_vert_variance = 0.05
        m.compass_variance = 0.05
        self._emit(m)

    def _send_battery_status(self) -> None:
        batt = self._ap.battery()
        m = self._m_batt
        m.voltages[0] = _u16(batt.voltage_v * 1000.0)
        m.current_battery = _i16(batt.current_a * 100.0)
        m.current_consumed = _i32(batt.consumed_mah)
        m.battery_remaining = _clamp_int(batt.remaining_pct, 0, 100)
        # AP_BattMonitor::get_mavlink_charge_state: the failsafe level, LOW once the low failsafe fired
        m.charge_state = mavlink2.MAV_BATTERY_CHARGE_STATE_LOW if self._ap.fs_battery else mavlink2.MAV_BATTERY_CHARGE_STATE_OK
        self._emit(m)

    def _send_home_position(self) -> None:
        home = self._ap.home
        if home is None:
            return  # ArduPilot sends nothing until home is set
        n, e, d = enu_to_ned(self._ap.frame.point_to_enu(home))
        self._emit(
            mavlink2.MAVLink_home_position_message(
                _i32(home.lat_deg * 1e7),
                _i32(home.lon_deg * 1e7),
                _i32(home.alt_m * 1000.0),
                float(n),
                float(e),
                float(d),
                [1.0, 0.0, 0.0, 0.0],
                0.0,
                0.0,
                0.0,
                self._t_ms * 1000,
            )
        )

    def _send_autopilot_version(self) -> None:
        self._emit(
            mavlink2.MAVLink_autopilot_version_message(
                CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, list(BUILD_ID.encode("ascii")), [0] * 8, [0] * 8,
                0, 0, 0
            )
        )
