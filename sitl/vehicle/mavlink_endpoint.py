"""The simulator's MAVLink face: makes an :class:`~sitl.vehicle.autopilot.Autopilot` look like ArduCopter 4.5/4.6.

Bytes in and out per channel (one port or one TCP client each, as ArduCopter gives each client its own
link): each has its own parser, its own MAVLink 2 output (ardupilotmega dialect, sysid ``SYSID_THISMAV``,
compid AUTOPILOT1, its own sequence numbers) and its own message rates. What is
answered and how follows ArduPilot's GCS_MAVLink library (GCS_Common.cpp, GCS_Param.cpp,
ArduCopter/GCS_Mavlink.cpp), cited per handler. Everything converts here and only here: NED <->
ENU, FRD <-> FLU, 1e7-degree integers, cm and mm, scalar-first quaternions.

As in ArduPilot's GCS_MAVLink, what answers a request (COMMAND_ACK, PARAM_VALUE for a read or a list,
MESSAGE_INTERVAL, the mission protocol, a requested message, the banner on request) goes to the channel
that asked; SET_MESSAGE_INTERVAL and REQUEST_DATA_STREAM set that channel's rates only; STATUSTEXT,
HOME_POSITION on change, PARAM_VALUE after a PARAM_SET and the boot banner go to every channel.
What one channel sends for another system or component (a ground station's command to a companion
computer on another port) is forwarded the way ArduPilot's MAVLink_routing does (:mod:`sitl.vehicle.routing`).

With :meth:`MavlinkEndpoint.enable_signing` the endpoint signs everything it sends and, like
ArduCopter with a signing key stored, acts only on messages that are correctly signed or are of a
kind ArduPilot accepts unsigned (RADIO_STATUS, RADIO); the rest are dropped and counted in
:attr:`MavlinkEndpoint.signing` (:mod:`chaser_bt.vehicle.signing`). Its signing timestamp follows
the simulator's clock (boot epoch + sim time), as ArduPilot's follows GPS time.

Periodic telemetry (what is due, and its lean encoding) lives in :mod:`sitl.vehicle.telemetry`; this module
handles everything that arrives and the replies to it. All times are the simulator's. The mission, fence and
rally protocol is :mod:`sitl.vehicle.mission_protocol`, MAVFTP's parameter file :mod:`sitl.vehicle.mavftp`.

The boot banner (GCS_MAVLINK_Copter::send_banner: "ArduCopter V4.6.0 (chaserbt)", "Frame: OCTA/X") goes out
at boot and, as ArduCopter sends it, on PARAM_REQUEST_LIST and MAV_CMD_DO_SEND_BANNER (the 4.7.0-dev SITL
sends it for neither REQUEST_MESSAGE AUTOPILOT_VERSION nor REQUEST_AUTOPILOT_CAPABILITIES). HEARTBEAT's
type follows FRAME_CLASS unless the caller names one.
"""

from __future__ import annotations

import math
import os
import weakref
from dataclasses import dataclass
from typing import Callable

os.environ["MAVLINK20"] = "1"

from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from chaser_bt.geo import (  # noqa: E402
    body_to_enu_rotation,
    heading_to_enu_yaw,
    ned_to_enu,
    quat_wxyz_to_xyzw,
)
from chaser_bt.vehicle.signing import SigningConfig, SigningGate, signing_timestamp  # noqa: E402
from sitl.vehicle.autopilot import FORCE_ARM_MAGIC, Autopilot  # noqa: E402
from sitl.vehicle.mavftp import MavFtpServer  # noqa: E402
from sitl.vehicle.mission_protocol import MissionProtocol  # noqa: E402
from sitl.vehicle.routing import Router  # noqa: E402
from sitl.vehicle.telemetry import (  # noqa: E402
    FRAME_CLASSES,
    StreamScheduler,
    TelemetryEncoder,
    banner_lines,
)

__all__ = ["MavlinkEndpoint", "Channel", "EndpointStats", "COMPID"]

COMPID = mavlink2.MAV_COMP_ID_AUTOPILOT1
PARAMS_PER_UPDATE = 10  # PARAM_REQUEST_LIST is streamed, as ArduPilot paces it (GCS_Param.cpp)
STATUSTEXT_LEN = 50

# SET_POSITION_TARGET_* type_mask bits (POSITION_TARGET_TYPEMASK)
_POS_IGNORE = 0b111
_VEL_IGNORE = 0b111 << 3
_YAW_IGNORE = 1 << 10
_YAW_RATE_IGNORE = 1 << 11
# SET_ATTITUDE_TARGET type_mask bits (ATTITUDE_TARGET_TYPEMASK)
_ATT_RATES_IGNORE = 0b111
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


@dataclass
class EndpointStats:
    """Counters for diagnostics: what arrived, what was dropped and why."""

    messages_in: int = 0  # acted on (with signing on: signed, or allowed unsigned)
    forwarded: int = 0  # resent on another channel (sitl.vehicle.routing), counted per channel
    bad_packets: int = 0  # garbage bytes runs and packets with a bad CRC or header
    not_for_us: int = 0  # targeted at another system or component (or a loop of our own)
    commands: int = 0
    packets_out: int = 0


class Channel:
    """One link (one port or one client): its parser, its output with its own sequence numbers, its
    message rates, and what it asked for that is still to be sent."""

    def __init__(self, sysid: int = 1) -> None:
        self.parser = mavlink2.MAVLink(None)
        self.parser.robust_parsing = True  # bad bytes become BAD_DATA messages, never exceptions
        self.mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=COMPID)
        self.out = bytearray()
        self.streams = StreamScheduler()
        self.requested: list[int] = []  # REQUEST_MESSAGE one-shots, sent after the ACK (deferred)
        self.param_queue: list[int] = []  # indices still to stream after PARAM_REQUEST_LIST
        self.banner_due = False  # asked for (PARAM_REQUEST_LIST, DO_SEND_BANNER): sent after the ACK


class MavlinkEndpoint:
    """ArduCopter's MAVLink behaviour over an :class:`~sitl.vehicle.autopilot.Autopilot`.

    Args:
        autopilot: the simulated flight controller (SI units, ENU).
        start_unix_s: wall-clock epoch of boot, for SYSTEM_TIME (from the scenario, so runs reproduce).
        mav_type: HEARTBEAT type; by default the one FRAME_CLASS names (octocopter by default, the
            paper's S1000 class).
    """

    def __init__(self, autopilot: Autopilot, *, start_unix_s: float, mav_type: int | None = None) -> None:
        self._ap = autopilot
        self._start_unix_s = start_unix_s
        self.signing: SigningGate | None = None  # set by enable_signing()
        self._signing_epoch_s = start_unix_s
        self._channels: list[weakref.ref[Channel]] = []  # open ones, in the order opened
        self._target: Channel | None = None  # the channel being answered; None = every channel
        self.sysid = int(autopilot.params.get("SYSID_THISMAV"))
        self.stats = EndpointStats()
        self.router: Router[Channel] = Router(self.sysid, COMPID)
        self._last_home = None
        self._mode_changes_sent = autopilot.mode_changes
        self._boot_banner_due = True  # sent at boot, to every channel
        if mav_type is None:
            frame_class = int(autopilot.params.get("FRAME_CLASS"))
            mav_type = FRAME_CLASSES.get(frame_class, (mavlink2.MAV_TYPE_OCTOROTOR, ""))[0]
        self.ftp = MavFtpServer(autopilot.params)
        self.missions = MissionProtocol(autopilot.missions, lambda: self._ap.home, self._emit, self._send_statustext)
        self.telemetry = TelemetryEncoder(self._ap, self._emit, start_unix_s=start_unix_s, mav_type=mav_type)
        self._senders = self.telemetry.senders
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
            "FILE_TRANSFER_PROTOCOL": self._on_file_transfer_protocol,
            **{kind: self._on_mission for kind in (
                "MISSION_REQUEST_LIST", "MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_COUNT",
                "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_CLEAR_ALL", "MISSION_ACK")},
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
            mavlink2.MAV_CMD_DO_SEND_BANNER: self._cmd_send_banner,
        }

    # ------------------------------------------------------------------ public
    def open_channel(self) -> Channel:
        """A parser for one more incoming byte stream (checking signatures once signing is on)."""
        channel = Channel(self.sysid)
        if self.signing is not None:
            self.signing.attach(channel.parser)
            self.signing.attach(channel.mav)
        self._channels.append(weakref.ref(channel))
        return channel

    def channels(self) -> list[Channel]:
        """The open channels, in the order opened (closed ones are forgotten)."""
        live = [c for c in (r() for r in self._channels) if c is not None]
        if len(live) != len(self._channels):
            self._channels = [weakref.ref(c) for c in live]
        return live

    def enable_signing(self, config: SigningConfig, *, epoch_unix_s: float | None = None) -> SigningGate:
        """Sign from now on and obey only correctly signed messages (and RADIO_STATUS/RADIO unsigned).

        Args:
            config: the key and the vehicle's link id.
            epoch_unix_s: the Unix time of boot for the signing clock (default ``start_unix_s``,
                reproducible). The real-time server passes the wall clock's: a real ArduCopter's
                clock is GPS time, and ground stations start their timestamps at the wall clock, so
                a vehicle clock far behind theirs looks like a replayed recording to them.

        Returns the gate, whose ``counters`` count what was accepted and rejected, and why.
        """
        self._signing_epoch_s = self._start_unix_s if epoch_unix_s is None else float(epoch_unix_s)
        gate = SigningGate(config, signing_timestamp(self._signing_clock()))
        for channel in self.channels():
            gate.attach(channel.parser)
            gate.attach(channel.mav)
        self.signing = gate
        return gate

    def _signing_clock(self) -> float:
        return self._signing_epoch_s + self._ap.time_s

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
            if self.signing is not None and not self.signing.admit(msg):
                continue  # unsigned or wrongly signed: counted by the gate, never acted on or forwarded
            local, forward_to = self.router.check_and_forward(msg, channel, self.channels())
            if forward_to:
                packet = bytes(msg.get_msgbuf())  # as it came, signature and all (_mavlink_resend_uart)
                for other in forward_to:
                    other.out += packet
                self.stats.forwarded += len(forward_to)
            if not local:
                self.stats.not_for_us += 1
                continue
            self.stats.messages_in += 1
            handler = self._handlers.get(kind)
            if handler is not None:
                self._target = channel
                try:
                    handler(msg)
                finally:
                    self._target = None

    def update(self) -> None:
        """Queue what is due after a physics step: STATUSTEXTs, HOME_POSITION on change, one-shots,
        streamed parameters and periodic telemetry."""
        ap = self._ap
        if self.signing is not None:
            self.signing.advance(self._signing_clock())
        self.telemetry.begin()
        if self._boot_banner_due:
            self._boot_banner_due = False
            self._send_banner()
        for severity, text in ap.pop_statustexts():
            self._send_statustext(severity, text)
        home = ap.home
        if home is not self._last_home and home != self._last_home:  # identity first: a dataclass comparison every step adds up
            self._last_home = home
            if home is not None:
                self._senders[mavlink2.MAVLINK_MSG_ID_HOME_POSITION]()  # sent whenever home is (re)set
        if ap.mode_changes != self._mode_changes_sent:
            # Copter::set_mode sends a HEARTBEAT at once, so a GCS sees the new mode without
            # waiting for the 1 Hz stream
            self._mode_changes_sent = ap.mode_changes
            self._senders[mavlink2.MAVLINK_MSG_ID_HEARTBEAT]()
        senders = self._senders
        now = ap.time_s
        for channel in self.channels():
            self._target = channel
            try:
                if channel.banner_due:
                    channel.banner_due = False
                    self._send_banner()
                if channel.requested:
                    requested, channel.requested = channel.requested, []
                    for msg_id in requested:
                        senders[msg_id]()
                if channel.param_queue:
                    self._stream_params(channel)
                for msg_id in channel.streams.due(now):
                    senders[msg_id]()
            finally:
                self._target = None

    def take_output(self, channel: Channel) -> bytes:
        """Every byte queued for ``channel`` since the last call (``b""`` when none)."""
        if not channel.out:
            return b""
        data = bytes(channel.out)
        channel.out.clear()
        return data

    # ------------------------------------------------------------------ encoding
    def _emit(self, msg) -> None:
        """Queue ``msg`` for the channel being answered, or for every channel outside an answer."""
        target = self._target
        for channel in (target,) if target is not None else self.channels():
            mav = channel.mav
            channel.out += msg.pack(mav)
            mav.seq = (mav.seq + 1) & 0xFF
            self.stats.packets_out += 1

    def _broadcast(self, msg) -> None:
        """Queue ``msg`` for every channel (GCS::send_text, GCS::send_parameter_value)."""
        target, self._target = self._target, None
        try:
            self._emit(msg)
        finally:
            self._target = target

    def _send_statustext(self, severity: int, text: str) -> None:
        self._broadcast(
            mavlink2.MAVLink_statustext_message(int(severity), text[:STATUSTEXT_LEN].encode("ascii", "replace")))

    def _send_banner(self) -> None:
        """GCS_MAVLINK::send_banner on this link (the channel being answered; every channel at boot)."""
        p = self._ap.params
        for line in banner_lines(int(p.get("FRAME_CLASS")), int(p.get("FRAME_TYPE"))):
            self._emit(mavlink2.MAVLink_statustext_message(mavlink2.MAV_SEVERITY_INFO, line.encode("ascii")))

    def _send_ack(self, command: int, result: int, msg) -> None:
        self._emit(
            mavlink2.MAVLink_command_ack_message(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
        )

    def _send_param(self, name: str, index: int, *, broadcast: bool = False) -> None:
        params = self._ap.params
        (self._broadcast if broadcast else self._emit)(
            mavlink2.MAVLink_param_value_message(
                name.encode("ascii"), float(params.get(name)), params.mav_type(name), params.count(), index & 0xFFFF
            )  # an unindexed reply's -1 is 65535 in the uint16 field, as from ArduPilot's C
        )

    def _stream_params(self, channel: Channel) -> None:
        names = self._ap.params.names()
        queue = channel.param_queue
        batch, channel.param_queue = queue[:PARAMS_PER_UPDATE], queue[PARAMS_PER_UPDATE:]
        for index in batch:
            self._send_param(names[index], index)

    # ------------------------------------------------------------------ incoming messages
    def _channel(self) -> Channel:
        """The channel whose message is being handled."""
        assert self._target is not None, "only while handling a received message"
        return self._target

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
        streams = self._channel().streams
        if interval_us == -1:
            streams.set_interval(msg_id, None, now)
        elif interval_us == 0:
            streams.reset_interval(msg_id, now)
        elif 0 < interval_us <= 2**31 - 1:  # MESSAGE_INTERVAL.interval_us is an int32
            streams.set_interval(msg_id, interval_us * 1e-6, now)
        else:
            return mavlink2.MAV_RESULT_FAILED
        return mavlink2.MAV_RESULT_ACCEPTED

    def _cmd_get_message_interval(self, p: tuple[float, ...]) -> int:
        msg_id = int(p[0])
        if msg_id not in self._senders:
            return mavlink2.MAV_RESULT_FAILED
        interval = self._channel().streams.interval(msg_id)
        interval_us = -1 if interval is None else int(round(interval * 1e6))
        self._emit(mavlink2.MAVLink_message_interval_message(msg_id, interval_us))
        return mavlink2.MAV_RESULT_ACCEPTED

    def _cmd_request_message(self, p: tuple[float, ...]) -> int:
        # GCS_MAVLINK::handle_command_request_message: known ids are ACCEPTED and sent (deferred,
        # so after the ACK); HOME_POSITION simply is not sent while home is unset.
        msg_id = int(p[0])
        if msg_id not in self._senders:
            return mavlink2.MAV_RESULT_FAILED
        self._channel().requested.append(msg_id)
        return mavlink2.MAV_RESULT_ACCEPTED

    def _cmd_request_autopilot_capabilities(self, p: tuple[float, ...]) -> int:
        self._channel().requested.append(mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        return mavlink2.MAV_RESULT_ACCEPTED

    def _cmd_send_banner(self, p: tuple[float, ...]) -> int:
        self._channel().banner_due = True  # after the ACK, as the real SITL sends it
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
        self._channel().streams.set_stream_rate(msg.req_stream_id, rate, self._ap.time_s)

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
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and math.isfinite(alt_amsl)):
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

    def _on_file_transfer_protocol(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        self.ftp.handle(msg.payload, lambda payload: self._emit(
            mavlink2.MAVLink_file_transfer_protocol_message(0, *src, list(payload))))

    def _on_mission(self, msg) -> None:
        if self._for_us(msg.target_system, msg.target_component):
            self.missions.handle(msg)

    # --- parameter protocol (GCS_Param.cpp) ---
    def _on_param_request_list(self, msg) -> None:
        if not self._for_us(msg.target_system, msg.target_component):
            return
        channel = self._channel()
        channel.param_queue = list(range(self._ap.params.count()))
        channel.banner_due = True  # GCS_Param.cpp: "requesting parameters is a convenient way to get extra information"

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
        self._send_param(name, -1, broadcast=True)
