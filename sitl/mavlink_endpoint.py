"""The simulator's MAVLink face: makes an :class:`~sitl.autopilot.Autopilot` look like ArduCopter 4.5/4.6.

Bytes in (any number of channels, each with its own parser so streams never interleave), bytes out
(one MAVLink 2 stream, ardupilotmega dialect, sysid ``SYSID_THISMAV``, compid AUTOPILOT1). What is
answered and how follows ArduPilot's GCS_MAVLink library (GCS_Common.cpp, GCS_Param.cpp,
ArduCopter/GCS_Mavlink.cpp), cited per handler. Everything converts here and only here: NED <->
ENU, FRD <-> FLU, 1e7-degree integers, cm and mm, scalar-first quaternions.

Output goes to every attached port (a broadcast radio): a command's ACK reaches every client, which
MAVLink clients tolerate because COMMAND_ACK carries the requester's system and component ids.

Encoding is on the simulator's hot path (a rehearsal runs at 20-100x real time), so periodic
messages are pre-built pymavlink message objects whose fields are overwritten and packed in place;
all times are the simulator's, never the wall clock's.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from typing import Callable

os.environ["MAVLINK20"] = "1"

from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from chaser_bt.geo import (  # noqa: E402
    body_to_enu_rotation,
    enu_to_ned,
    heading_to_enu_yaw,
    ned_to_enu,
    quat_wxyz_to_xyzw,
    quat_xyzw_to_wxyz,
)
from sitl.autopilot import FORCE_ARM_MAGIC, Autopilot  # noqa: E402
from sitl.telemetry import StreamScheduler  # noqa: E402

__all__ = ["MavlinkEndpoint", "Channel", "EndpointStats", "COMPID"]

log = logging.getLogger(__name__)

COMPID = mavlink2.MAV_COMP_ID_AUTOPILOT1
# AUTOPILOT_VERSION.flight_sw_version: major << 24 | minor << 16 | patch << 8 | FIRMWARE_VERSION_TYPE
FLIGHT_SW_VERSION = (4 << 24) | (6 << 16) | (0 << 8) | mavlink2.FIRMWARE_VERSION_TYPE_OFFICIAL
CAPABILITIES = (
    mavlink2.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | mavlink2.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
)
PARAMS_PER_UPDATE = 10  # PARAM_REQUEST_LIST is streamed, as ArduPilot paces it (GCS_Param.cpp)
STATUSTEXT_LEN = 50

# Copter mode numbers whose controller holds horizontal position: HEARTBEAT's GUIDED_ENABLED flag
# (ArduCopter base_mode(): pos_control->is_active_xy()) and SYS_STATUS' XY control bit.
_POSITION_MODES = frozenset({4, 5, 6, 9, 17})  # GUIDED, LOITER, RTL, LAND, BRAKE
_ALTITUDE_MODES = _POSITION_MODES | {2}  # + ALT_HOLD

_SENSORS = (
    mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink2.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink2.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mavlink2.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mavlink2.MAV_SYS_STATUS_SENSOR_BATTERY
)
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
_SYS_PRESENT = _SENSORS | _GPS | _AHRS | _PREARM | _RATE_ATT_YAW | _Z_CTRL | _XY_CTRL | _MOTORS

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

# SET_POSITION_TARGET_* type_mask bits (POSITION_TARGET_TYPEMASK)
_POS_IGNORE = 0b111
_VEL_IGNORE = 0b111 << 3
_YAW_IGNORE = 1 << 10
_YAW_RATE_IGNORE = 1 << 11
# SET_ATTITUDE_TARGET type_mask bits (ATTITUDE_TARGET_TYPEMASK)
_ATT_RATES_IGNORE = 0b111
_ATT_YAW_RATE_IGNORE = 1 << 2
_ATT_THROTTLE_IGNORE = 1 << 6
_ATT_ATTITUDE_IGNORE = 1 << 7

_GLOBAL_AMSL = frozenset({mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_FRAME_GLOBAL_INT})
_GLOBAL_RELATIVE = frozenset(
    {
        mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        # no terrain database in the simulator: terrain-relative is home-relative (flat field)
        mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT,
        mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
    }
)
_BODY_FRAMES = frozenset({mavlink2.MAV_FRAME_BODY_NED, mavlink2.MAV_FRAME_BODY_OFFSET_NED})
_OFFSET_FRAMES = _BODY_FRAMES | {mavlink2.MAV_FRAME_LOCAL_OFFSET_NED}
_LOCAL_FRAMES = _OFFSET_FRAMES | {mavlink2.MAV_FRAME_LOCAL_NED}

_U16_MAX = 65535


def _clamp_int(x: float, lo: int, hi: int) -> int:
    """Round to the nearest int inside a MAVLink field's range (so pack() can never fail)."""
    if x != x:  # NaN
        return hi if hi == _U16_MAX else 0
    v = int(round(x))
    return lo if v < lo else hi if v > hi else v


def _i16(x: float) -> int:
    return _clamp_int(x, -32768, 32767)


def _i32(x: float) -> int:
    return _clamp_int(x, -(2**31), 2**31 - 1)


def _u16(x: float) -> int:
    return _clamp_int(x, 0, _U16_MAX)


def _cdeg(angle_deg: float) -> int:
    """An angle in degrees as MAVLink centidegrees in [0, 36000)."""
    return int(round(angle_deg * 100.0)) % 36000


@dataclass
class EndpointStats:
    """Counters for diagnostics: what arrived, what was dropped and why."""

    messages_in: int = 0
    bad_packets: int = 0  # garbage bytes runs and packets with a bad CRC or header
    not_for_us: int = 0  # targeted at another system or component
    commands: int = 0
    packets_out: int = 0


class Channel:
    """One incoming byte stream (one port or one client) with its own MAVLink parser."""

    def __init__(self) -> None:
        self.parser = mavlink2.MAVLink(None)
        self.parser.robust_parsing = True  # bad bytes become BAD_DATA messages, never exceptions


class MavlinkEndpoint:
    """ArduCopter's MAVLink behaviour over an :class:`~sitl.autopilot.Autopilot`.

    Args:
        autopilot: the simulated flight controller (SI units, ENU).
        start_unix_s: wall-clock epoch of boot, for SYSTEM_TIME (from the scenario, so runs reproduce).
        mav_type: HEARTBEAT type (an octocopter by default, the paper's S1000 class).
    """

    def __init__(self, autopilot: Autopilot, *, start_unix_s: float, mav_type: int = mavlink2.MAV_TYPE_OCTOROTOR) -> None:
        self._ap = autopilot
        self._start_unix_s = float(start_unix_s)
        self._mav_type = mav_type
        self.sysid = int(autopilot.params.get("SYSID_THISMAV"))
        self._mav = mavlink2.MAVLink(None, srcSystem=self.sysid, srcComponent=COMPID)
        self._out = bytearray()
        self.stats = EndpointStats()
        self.streams = StreamScheduler()
        self._requested: list[int] = []  # REQUEST_MESSAGE one-shots, sent after the ACK (deferred)
        self._param_queue: list[int] = []  # indices still to stream after PARAM_REQUEST_LIST
        self._last_home = None
        self._t_ms = 0
        self._estimate = None  # position estimate, fetched at most once per update
        self._build_messages()
        self._senders: dict[int, Callable[[], None]] = {
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
        self._handlers: dict[str, Callable] = {
            "HEARTBEAT": self._on_heartbeat,
            "COMMAND_LONG": self._on_command_long,
            "COMMAND_INT": self._on_command_int,
            "SET_MODE": self._on_set_mode,
            "SET_POSITION_TARGET_GLOBAL_INT": self._on_set_position_target_global_int,
            "SET_POSITION_TARGET_LOCAL_NED": self._on_set_position_target_local_ned,
            "SET_ATTITUDE_TARGET": self._on_set_attitude_target,
            "RC_CHANNELS_OVERRIDE": self._on_rc_channels_override,
            "PARAM_REQUEST_LIST": self._on_param_request_list,
            "PARAM_REQUEST_READ": self._on_param_request_read,
            "PARAM_SET": self._on_param_set,
            "REQUEST_DATA_STREAM": self._on_request_data_stream,
        }
        self._commands: dict[int, Callable[[tuple[float, ...]], int]] = {
            mavlink2.MAV_CMD_COMPONENT_ARM_DISARM: self._cmd_arm_disarm,
            mavlink2.MAV_CMD_DO_SET_MODE: self._cmd_do_set_mode,
            mavlink2.MAV_CMD_NAV_TAKEOFF: self._cmd_takeoff,
            mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH: self._cmd_rtl,
            mavlink2.MAV_CMD_NAV_LAND: self._cmd_land,
            mavlink2.MAV_CMD_DO_CHANGE_SPEED: self._cmd_change_speed,
            mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL: self._cmd_set_message_interval,
            mavlink2.MAV_CMD_GET_MESSAGE_INTERVAL: self._cmd_get_message_interval,
            mavlink2.MAV_CMD_REQUEST_MESSAGE: self._cmd_request_message,
            mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: self._cmd_request_autopilot_capabilities,
        }

    # ------------------------------------------------------------------ public
    @staticmethod
    def open_channel() -> Channel:
        """A parser for one more incoming byte stream."""
        return Channel()

    @property
    def gcs_sysid(self) -> int:
        """The only system whose heartbeats and RC overrides count (MAV_GCS_SYSID, ArduPilot 4.6)."""
        return int(self._ap.params.get("MAV_GCS_SYSID"))

    def receive(self, data: bytes, channel: Channel) -> None:
        """Parse ``data`` from ``channel`` and act on every complete message; garbage is counted, skipped."""
        if not data:
            return
        msgs = channel.parser.parse_buffer(data)
        if not msgs:
            return
        for msg in msgs:
            kind = msg.get_type()
            if kind == "BAD_DATA":
                self.stats.bad_packets += 1
                continue
            self.stats.messages_in += 1
            handler = self._handlers.get(kind)
            if handler is not None:
                handler(msg)

    def update(self) -> None:
        """Queue what is due after a physics step: STATUSTEXTs, HOME_POSITION on change, one-shots,
        streamed parameters and periodic telemetry."""
        ap = self._ap
        self._t_ms = int(round(ap.time_s * 1000.0))
        self._estimate = None
        for severity, text in ap.pop_statustexts():
            self._send_statustext(severity, text)
        home = ap.home
        if home != self._last_home:
            self._last_home = home
            if home is not None:
                self._send_home_position()  # ArduPilot sends MSG_HOME whenever home is (re)set
        if self._requested:
            requested, self._requested = self._requested, []
            for msg_id in requested:
                self._senders[msg_id]()
        if self._param_queue:
            self._stream_params()
        senders = self._senders
        for msg_id in self.streams.due(ap.time_s):
            senders[msg_id]()

    def take_output(self) -> bytes:
        """Every byte queued since the last call (``b""`` when none)."""
        if not self._out:
            return b""
        data = bytes(self._out)
        self._out.clear()
        return data

    # ------------------------------------------------------------------ encoding
    def _emit(self, msg) -> None:
        mav = self._mav
        self._out += msg.pack(mav)
        mav.seq = (mav.seq + 1) & 0xFF
        self.stats.packets_out += 1

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

    def _send_sys_status(self) -> None:
        ap = self._ap
        m = self._m_sys_status
        mode = ap.mode_number
        enabled = _SENSORS | _GPS | _AHRS | _PREARM | _RATE_ATT_YAW
        if mode in _ALTITUDE_MODES:
            enabled |= _Z_CTRL
        if mode in _POSITION_MODES:
            enabled |= _XY_CTRL
        if ap.armed:
            enabled |= _MOTORS
        health = _SENSORS | _RATE_ATT_YAW | _Z_CTRL | _MOTORS
        if ap.gps_ok:
            health |= _GPS
        if ap.ekf_ok:
            health |= _AHRS | _XY_CTRL
        if ap.prearm_ok:
            health |= _PREARM  # how ArduPilot tells a GCS it is ready to arm
        batt = ap.battery()
        m.onboard_control_sensors_present = _SYS_PRESENT
        m.onboard_control_sensors_enabled = enabled
        m.onboard_control_sensors_health = health
        m.load = 200  # 20 % main-loop load, a typical SITL figure
        m.voltage_battery = _u16(batt.voltage_v * 1000.0)
        m.current_battery = _i16(batt.current_a * 100.0)
        m.battery_remaining = _clamp_int(batt.remaining_pct, 0, 100)
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
                CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0
            )
        )

    def _send_statustext(self, severity: int, text: str) -> None:
        self._emit(mavlink2.MAVLink_statustext_message(int(severity), text[:STATUSTEXT_LEN].encode("ascii", "replace")))

    def _send_ack(self, command: int, result: int, msg) -> None:
        self._emit(
            mavlink2.MAVLink_command_ack_message(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
        )

    def _send_param(self, name: str, index: int) -> None:
        params = self._ap.params
        self._emit(
            mavlink2.MAVLink_param_value_message(
                name.encode("ascii"), float(params.get(name)), params.mav_type(name), params.count(), index & 0xFFFF
            )  # an unindexed reply's -1 is 65535 in the uint16 field, as from ArduPilot's C
        )

    def _stream_params(self) -> None:
        names = self._ap.params.names()
        batch, self._param_queue = self._param_queue[:PARAMS_PER_UPDATE], self._param_queue[PARAMS_PER_UPDATE:]
        for index in batch:
            self._send_param(names[index], index)

    # ------------------------------------------------------------------ incoming messages
    def _for_us(self, target_system: int, target_component: int) -> bool:
        """MAVLink routing as ArduPilot does it: broadcast (0) or our ids, else not ours."""
        if target_system not in (0, self.sysid) or target_component not in (0, COMPID):
            self.stats.not_for_us += 1
            return False
        return True

    def _on_heartbeat(self, msg) -> None:
        # GCS_MAVLINK::handle_heartbeat: any heartbeat from MAV_GCS_SYSID resets the GCS failsafe timer.
        if msg.get_srcSystem() == self.gcs_sysid:
            self._ap.gcs_heartbeat()

    def _on_command_long(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        self._run_command(msg.command, params, msg)

    def _on_command_int(self, msg) -> None:
        # COMMAND_INT carries params 5 and 6 as integers (1e7 degrees for positions); the commands
        # handled here use neither, so they map onto the COMMAND_LONG handlers unchanged.
        if not self._for_us(msg.target_system, msg.target_component):
            return
        params = (msg.param1, msg.param2, msg.param3, msg.param4, float(msg.x), float(msg.y), msg.z)
        self._run_command(msg.command, params, msg)

    def _run_command(self, command: int, params: tuple[float, ...], msg) -> None:
        """Every command gets exactly one COMMAND_ACK; unknown ones MAV_RESULT_UNSUPPORTED."""
        self.stats.commands += 1
        handler = self._commands.get(command)
        if handler is None:
            result = mavlink2.MAV_RESULT_UNSUPPORTED
        elif not all(math.isfinite(v) for v in params):
            result = mavlink2.MAV_RESULT_DENIED  # NaN/inf parameters: "supported but invalid"
        else:
            result = handler(params)
        self._send_ack(command, result, msg)

    def _refusal(self, outcome, refused: int = mavlink2.MAV_RESULT_FAILED) -> int:
        """ACCEPTED, or ``refused``. Either way the autopilot's STATUSTEXTs (the refusal reason among
        them) go out before the ACK, as ArduPilot sends "PreArm: ..." while checking."""
        texts = self._ap.pop_statustexts()
        for severity, text in texts:
            self._send_statustext(severity, text)
        if outcome.accepted:
            return mavlink2.MAV_RESULT_ACCEPTED
        if outcome.text and all(text != outcome.text for _, text in texts):
            self._send_statustext(mavlink2.MAV_SEVERITY_CRITICAL, outcome.text)
        return refused

    def _cmd_arm_disarm(self, p: tuple[float, ...]) -> int:
        force = int(round(p[1])) == FORCE_ARM_MAGIC
        if p[0] == 1.0:
            return self._refusal(self._ap.request_arm(True, force=force))
        if p[0] == 0.0:
            return self._refusal(self._ap.request_arm(False, force=force))
        return mavlink2.MAV_RESULT_UNSUPPORTED

    def _cmd_do_set_mode(self, p: tuple[float, ...]) -> int:
        return self._set_mode(int(p[0]), int(p[1]))

    def _set_mode(self, base_mode: int, custom_mode: int) -> int:
        """GCS_MAVLINK::_set_mode_common: only custom modes are understood, anything else is DENIED."""
        if not base_mode & mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return mavlink2.MAV_RESULT_DENIED
        return self._refusal(self._ap.request_mode(custom_mode))

    def _cmd_takeoff(self, p: tuple[float, ...]) -> int:
        return self._refusal(self._ap.request_takeoff(float(p[6])))

    def _cmd_rtl(self, p: tuple[float, ...]) -> int:
        return self._refusal(self._ap.request_mode(6))

    def _cmd_land(self, p: tuple[float, ...]) -> int:
        return self._refusal(self._ap.request_mode(9))

    def _cmd_change_speed(self, p: tuple[float, ...]) -> int:
        # param1 speed type (0 airspeed, 1 ground speed, 2 climb, 3 descent), param2 m/s (> 0).
        speed_type, speed = int(p[0]), float(p[1])
        if speed_type not in (0, 1):
            return mavlink2.MAV_RESULT_UNSUPPORTED  # the simulator has one horizontal speed setting
        if not speed > 0.0:
            return mavlink2.MAV_RESULT_FAILED
        return self._refusal(self._ap.set_speed(speed))

    def _cmd_set_message_interval(self, p: tuple[float, ...]) -> int:
        msg_id, interval_us = int(p[0]), int(p[1])
        if msg_id not in self._senders:
            self._send_statustext(mavlink2.MAV_SEVERITY_INFO, f"No ap_message for mavlink id ({msg_id})")
            return mavlink2.MAV_RESULT_DENIED
        now = self._ap.time_s
        if interval_us == -1:
            self.streams.set_interval(msg_id, None, now)
        elif interval_us == 0:
            self.streams.reset_interval(msg_id, now)
        elif 0 < interval_us <= 2**31 - 1:  # MESSAGE_INTERVAL.interval_us is an int32
            self.streams.set_interval(msg_id, interval_us * 1e-6, now)
        else:
            return mavlink2.MAV_RESULT_FAILED
        return mavlink2.MAV_RESULT_ACCEPTED

    def _cmd_get_message_interval(self, p: tuple[float, ...]) -> int:
        msg_id = int(p[0])
        if msg_id not in self._senders:
            return mavlink2.MAV_RESULT_FAILED
        interval = self.streams.interval(msg_id)
        interval_us = -1 if interval is None else int(round(interval * 1e6))
        self._emit(mavlink2.MAVLink_message_interval_message(msg_id, interval_us))
        return mavlink2.MAV_RESULT_ACCEPTED

    def _cmd_request_message(self, p: tuple[float, ...]) -> int:
        # GCS_MAVLINK::handle_command_request_message: known ids are ACCEPTED and sent (deferred,
        # so after the ACK); HOME_POSITION simply is not sent while home is unset.
        msg_id = int(p[0])
        if msg_id not in self._senders:
            return mavlink2.MAV_RESULT_FAILED
        self._requested.append(msg_id)
        return mavlink2.MAV_RESULT_ACCEPTED

    def _cmd_request_autopilot_capabilities(self, p: tuple[float, ...]) -> int:
        self._requested.append(mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        return mavlink2.MAV_RESULT_ACCEPTED

    def _on_set_mode(self, msg) -> None:
        # Legacy SET_MODE: ArduPilot answers it with a COMMAND_ACK whose command is the message id (11).
        if msg.target_system != self.sysid:
            self.stats.not_for_us += 1
            return
        self._send_ack(mavlink2.MAVLINK_MSG_ID_SET_MODE, self._set_mode(msg.base_mode, msg.custom_mode), msg)

    def _on_request_data_stream(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        if msg.start_stop not in (0, 1):
            return
        rate = float(msg.req_message_rate) if msg.start_stop == 1 else 0.0
        self.streams.set_stream_rate(msg.req_stream_id, rate, self._ap.time_s)

    # --- GUIDED set-points (no ACK in ArduPilot); ArduCopter GCS_Mavlink.cpp handle_message_set_* ---
    def _hold(self) -> None:
        """ArduCopter's answer to an unusable set-point: mode_guided.init() = hold where it is."""
        self._ap.set_position_target(self._ap.position_estimate().pos_enu)

    def _yaw_targets(self, mask: int, yaw: float, yaw_rate: float, body: bool) -> tuple[float | None, float | None]:
        """(ENU yaw, ENU yaw rate) from a NED heading and a clockwise rate, ``None`` where masked."""
        yaw_enu = None
        if not mask & _YAW_IGNORE:
            heading = yaw + math.radians(self._ap.heading_deg) if body else yaw
            yaw_enu = heading_to_enu_yaw(heading)
        rate_enu = None if mask & _YAW_RATE_IGNORE else -float(yaw_rate)
        return yaw_enu, rate_enu

    def _apply_setpoint(self, mask: int, pos_enu, vel_enu, yaw_enu, yaw_rate_enu) -> None:
        pos_given, vel_given = not mask & _POS_IGNORE, not mask & _VEL_IGNORE
        ap = self._ap
        used = [*(pos_enu if pos_given else ()), *(vel_enu if vel_given else ())]
        used += [v for v in (yaw_enu, yaw_rate_enu) if v is not None]
        if not all(math.isfinite(v) for v in used):
            self._hold()  # never hand NaN/inf to the controller
            return
        if pos_given:
            # position (with or without velocity feed-forward, which this autopilot has no input for)
            ap.set_position_target(pos_enu, yaw_enu)
        elif vel_given:
            ap.set_velocity_target(vel_enu, yaw_enu, yaw_rate_enu)
        else:
            self._hold()  # acceleration-only targets are not simulated

    def _on_set_position_target_global_int(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        mask = msg.type_mask
        ap = self._ap
        pos_enu = None
        if not mask & _POS_IGNORE:
            frame = msg.coordinate_frame
            if frame in _GLOBAL_AMSL:
                alt_amsl = msg.alt
            elif frame in _GLOBAL_RELATIVE:
                home = ap.home if ap.home is not None else ap.frame.origin
                alt_amsl = home.alt_m + msg.alt
            else:
                self._hold()
                return
            lat, lon = msg.lat_int * 1e-7, msg.lon_int * 1e-7
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                self._hold()
                return
            pos_enu = ap.frame.to_enu(lat, lon, alt_amsl)
        vel_enu = ned_to_enu((msg.vx, msg.vy, msg.vz))
        yaw_enu, rate_enu = self._yaw_targets(mask, msg.yaw, msg.yaw_rate, body=False)
        self._apply_setpoint(mask, pos_enu, vel_enu, yaw_enu, rate_enu)

    def _on_set_position_target_local_ned(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        frame = msg.coordinate_frame
        if frame not in _LOCAL_FRAMES:
            self._hold()
            return
        mask = msg.type_mask
        body = frame in _BODY_FRAMES
        heading = math.radians(self._ap.heading_deg)
        c, s = math.cos(heading), math.sin(heading)

        def to_ne(x: float, y: float) -> tuple[float, float]:
            # ArduCopter rotate_body_frame_to_NE: body x forward, y right -> north, east
            return (x * c - y * s, x * s + y * c) if body else (x, y)

        n, e = to_ne(msg.x, msg.y)
        pos_enu = ned_to_enu((n, e, msg.z))
        if frame in _OFFSET_FRAMES:
            pos_enu = pos_enu + self._ap.position_estimate().pos_enu
        vn, ve = to_ne(msg.vx, msg.vy)
        vel_enu = ned_to_enu((vn, ve, msg.vz))
        yaw_enu, rate_enu = self._yaw_targets(mask, msg.yaw, msg.yaw_rate, body=body)
        self._apply_setpoint(mask, pos_enu, vel_enu, yaw_enu, rate_enu)

    def _on_set_attitude_target(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        mask = msg.type_mask
        rates = mask & _ATT_RATES_IGNORE
        # ArduCopter: thrust must be given, body rates all given or all ignored; and no NaN/inf
        if mask & _ATT_THROTTLE_IGNORE or rates not in (0, _ATT_RATES_IGNORE):
            self._hold()
            return
        if not (math.isfinite(msg.thrust) and math.isfinite(msg.body_yaw_rate)):
            self._hold()
            return
        if mask & _ATT_ATTITUDE_IGNORE:
            roll, pitch, yaw = self._ap.attitude()[:3]
        else:
            q = msg.q
            if not abs(math.sqrt(sum(v * v for v in q)) - 1.0) <= 1e-3:
                self._hold()  # ArduCopter rejects a quaternion that is not unit length
                return
            yaw, pitch, roll = Rotation.from_quat(quat_wxyz_to_xyzw(q)).as_euler("ZYX")  # FRD -> NED
        q_enu_flu = body_to_enu_rotation(roll, pitch, yaw).as_quat()
        yaw_rate = -float(msg.body_yaw_rate) if rates == 0 else None  # FRD z (down) -> FLU z (up)
        self._ap.set_attitude_target(q_enu_flu, yaw_rate, float(msg.thrust))

    def _on_rc_channels_override(self, msg) -> None:
        # GCS_MAVLINK::handle_rc_channels_override: only our GCS's sysid is obeyed; it also counts as
        # a GCS heartbeat for the failsafe.
        if msg.get_srcSystem() != self.gcs_sysid:
            self.stats.not_for_us += 1
            return
        if not self._for_us(msg.target_system, msg.target_component):
            return
        channels = tuple(getattr(msg, f"chan{i}_raw") for i in range(1, 19))
        self._ap.rc_override(channels)
        self._ap.gcs_heartbeat()

    # --- parameter protocol (GCS_Param.cpp) ---
    def _on_param_request_list(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        self._param_queue = list(range(self._ap.params.count()))

    def _on_param_request_read(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        params = self._ap.params
        index = msg.param_index
        if index >= 0:
            if index < params.count():  # unknown index or name: ArduPilot answers nothing
                self._send_param(params.names()[index], index)
        elif msg.param_id in params:
            self._send_param(msg.param_id, -1)  # the reply echoes the request's index (-1 by name)

    def _on_param_set(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        name, value = msg.param_id, float(msg.param_value)
        params = self._ap.params
        if name not in params or not math.isfinite(value):
            return  # ArduPilot ignores unknown names and NaN/inf silently
        if not params.set(name, value):
            self._send_statustext(mavlink2.MAV_SEVERITY_WARNING, f"Param write denied ({name})")
        # GCS::send_parameter_value: the stored value goes to every GCS, with index -1
        self._send_param(name, -1)
