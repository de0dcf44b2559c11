"""The MAVLink link to an ArduCopter: telemetry into :class:`VehicleState`, non-blocking commands.

One :class:`VehicleLink` flies the built-in simulator (in-process pipe or UDP/TCP), ArduPilot SITL
or a real aircraft; only the connection string changes (DESIGN §5). Its rules:

- Nothing blocks except :meth:`VehicleLink.connect` (bounded) and the script helper
  :meth:`VehicleLink.wait`. :meth:`~VehicleLink.poll` drains what arrived, updates the state,
  moves commands along (acks, retries, timeouts, readiness waits) and sends what is due.
- Every timer runs on the injected ``monotonic`` callable, so a rehearsal on the simulator's
  clock is reproducible and independent of how fast the host runs. With
  ``LinkConfig.timers_on_vehicle_time`` the heartbeat and RC-override resends also keep to the
  vehicle's own time (``time_boot_ms``), so a simulator at any speed-up sees them at their rate
  (:mod:`chaser_bt.vehicle.cadence`); silence and ack timeouts stay on ``monotonic``, which runs
  on when a quiet vehicle's time stops.
- It keeps ArduCopter fed the way ArduCopter expects: a GCS HEARTBEAT at 1 Hz (FS_GCS failsafe),
  SET_MESSAGE_INTERVAL per stream (SITL streams little unless asked), HOME_POSITION asked for with
  MAV_CMD_REQUEST_MESSAGE until it arrives, and a held RC override resent at 5 Hz (overrides
  expire after RC_OVERRIDE_TIME, 3 s).
- With ``LinkConfig.signing`` it signs what it sends (MAVLink 2 signing, timestamp from the Unix
  time at opening) and believes only correctly signed messages from its vehicle
  (:mod:`chaser_bt.vehicle.signing`): unsigned or wrongly signed ones claiming to be the vehicle
  are dropped and counted in :attr:`VehicleLink.signing`. Other systems' messages (an intruder's
  own telemetry) are not ours to authenticate; they reach listeners as before and never the state.
- With a key (or ``LinkConfig.designation_unsigned`` on the bench) it also takes the operator's
  target designations from a ground station (:mod:`chaser_bt.vehicle.designation`): it answers as
  component ``designation_compid`` of the vehicle's system, sends that component's HEARTBEAT so the
  autopilot forwards commands for it here, acks each command it believes, and hands the accepted
  ones out by :meth:`~VehicleLink.take_designations`.
- A command counts as accepted only when ArduCopter acked it *and*, where telemetry can show it,
  telemetry shows it (mode in HEARTBEAT.custom_mode, armed flag): ArduPilot acks first. Telemetry
  that shows it without an ack (the ack was lost) counts too.
- Telemetry is checked before it is believed (:mod:`chaser_bt.vehicle.telemetry_check`): what no
  aircraft reports is dropped and counted on ``state.telemetry_rejected``; a flood of drops, or two
  senders interleaving under the vehicle's ids (:mod:`chaser_bt.vehicle.source_watch`), sets
  ``state.telemetry_fault``. A vehicle whose time stops while its messages keep coming, or whose
  telemetry stays untrustworthy, is as good as quiet: :class:`VehicleQuiet` after ``quiet_timeout_s``.
- Every set-point is checked against the :class:`~chaser_bt.vehicle.envelope.CommandEnvelope`
  before it is sent; one outside raises :class:`~chaser_bt.vehicle.envelope.UnsafeCommand` and
  nothing leaves. Only the hold of :meth:`~VehicleLink.hover` (where the aircraft is) is exempt.
- Two public hooks observe it: :meth:`~VehicleLink.add_listener` sees decoded messages both ways;
  :meth:`~VehicleLink.add_wire_tap` sees the raw bytes read from the connection and the link time
  of every :meth:`~VehicleLink.poll`, with :meth:`~VehicleLink.now` and
  :attr:`~VehicleLink.opened_at_s` (the flight recorder's hook: replay feeds those bytes back at
  those times to an identical link).
"""

from __future__ import annotations

import inspect
import logging
import math
import time
from collections import Counter
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from chaser_bt.geo import GeoPoint, LocalFrame, enu_to_ned, enu_yaw_to_heading, wrap_pi
from chaser_bt.vehicle.cadence import Cadence
from chaser_bt.vehicle.commands import Command, CommandTracker, Setpoint
from chaser_bt.vehicle.connection import PipeConnection, mavutil, open_connection
from chaser_bt.vehicle.designation import (
    COMMAND_MESSAGES,
    DEFAULT_COMPID,
    DesignationInbox,
    Judgement,
    MavlinkDesignation,
    authenticity,
)
from chaser_bt.vehicle.envelope import CommandEnvelope, UnsafeCommand
from chaser_bt.vehicle.errors import CommandRejected, LinkTimeout, VehicleError, VehicleQuiet, VehicleUnreachable
from chaser_bt.vehicle.pipe import PipeEnd
from chaser_bt.vehicle.signing import SigningConfig, SigningGate, signing_timestamp
from chaser_bt.vehicle.source_watch import SequenceWatch
from chaser_bt.vehicle.state import VehicleState, statustext_str, update_state
from chaser_bt.vehicle.telemetry_check import TelemetryGate, TelemetryLimits

__all__ = ["LinkConfig", "LinkCounters", "VehicleLink", "DEFAULT_STREAM_RATES_HZ", "COPTER_MODES"]

log = logging.getLogger(__name__)
mavlink = mavutil.mavlink  # the ardupilotmega dialect, MAVLink 2 (set up in connection.py)

DEFAULT_STREAM_RATES_HZ: Mapping[str, float] = MappingProxyType({
    "GLOBAL_POSITION_INT": 10.0,
    "ATTITUDE": 10.0,
    "VFR_HUD": 4.0,
    "RC_CHANNELS": 5.0,
    "SYS_STATUS": 2.0,
    "GPS_RAW_INT": 2.0,
    "SYSTEM_TIME": 2.0,
    "EXTENDED_SYS_STATE": 2.0,
    "EKF_STATUS_REPORT": 1.0,
    "BATTERY_STATUS": 1.0,
    "HOME_POSITION": 0.5,
})
COPTER_MODES: Mapping[str, int] = MappingProxyType({name: num for num, name in mavutil.mode_mapping_acm.items()})

# Modes in which the pilot's sticks (or our RC override) fly the copter. Entering any other mode
# releases a held override, so a pilot who switches to LOITER, or a failsafe RTL, is not fought.
_STICK_MODES = frozenset({"STABILIZE", "ACRO", "ALT_HOLD", "POSHOLD", "SPORT", "DRIFT", "FLOWHOLD"})
_HOVER_BY_STICKS = frozenset({"STABILIZE", "ALT_HOLD"})
# Modes ArduCopter enters only with a position estimate (mode.h requires_GPS()).
_POSITION_MODES = frozenset({"AUTO", "GUIDED", "LOITER", "RTL", "CIRCLE", "POSHOLD", "BRAKE", "SMART_RTL",
                             "FOLLOW", "ZIGZAG", "AUTO_RTL"})
_FORCE_DISARM_MAGIC = 21196  # ArduPilot: MAV_CMD_COMPONENT_ARM_DISARM param2 to bypass checks
_RC_CENTRE = 1500
_RC_LEAVE = 65535  # UINT16_MAX: leave this channel alone
_RC_RELEASE = 0  # hand this channel back to the pilot's radio
_STREAM_CHECK_S = 5.0  # how often missing streams are asked for again
_HOME_REQUEST_S = 2.0  # how often HOME_POSITION is asked for until it arrives
_MAX_MESSAGES_PER_POLL = 5000  # a flooding peer cannot keep poll() from returning
# Commands whose acks nobody waits for: stream set-up sent by the link itself.
_SELF_SERVICE_CMDS = frozenset({mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAV_CMD_REQUEST_MESSAGE})
_POSITION_ONLY = (
    mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
)
_VELOCITY_ONLY = (
    mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
)


@dataclass(frozen=True)
class LinkConfig:
    """How the link identifies itself, what it asks for, and how patient it is (seconds, Hz)."""

    gcs_sysid: int = 255  # ArduPilot obeys RC overrides only from MAV_GCS_SYSID (255 by default)
    gcs_compid: int = 190  # MAV_COMP_ID_MISSIONPLANNER, what ground stations use
    target_sysid: int | None = None  # None: the first autopilot heard
    heartbeat_period_s: float = 1.0
    ack_timeout_s: float = 1.5
    retries: int = 3
    quiet_timeout_s: float = 5.0
    connect_timeout_s: float = 10.0
    ready_timeout_s: float = 120.0  # arm waits this long for ArduCopter to become ready (~40 s after boot)
    confirm_timeout_s: float = 3.0  # an acked command has this long to show in telemetry (1 Hz heartbeat)
    rc_resend_hz: float = 5.0  # held RC overrides are resent this often (they expire after 3 s)
    stream_rates_hz: Mapping[str, float] = field(default_factory=lambda: DEFAULT_STREAM_RATES_HZ)
    origin: GeoPoint | None = None  # ENU origin; None: the vehicle's home
    signing: SigningConfig | None = None  # MAVLink 2 signing key and link id; None: unsigned link
    envelope: CommandEnvelope = field(default_factory=CommandEnvelope)  # where set-points may send the aircraft
    telemetry_limits: TelemetryLimits = field(default_factory=TelemetryLimits)  # what telemetry is believed
    # Heartbeats and RC-override resends also keep to the vehicle's time (its time_boot_ms), so a
    # simulator at speed-up sees them at their rate in its own time (chaser_bt.vehicle.cadence).
    timers_on_vehicle_time: bool = False
    # The operator's designations from a ground station over MAVLink (chaser_bt.vehicle.designation):
    # the component the link answers them as (None: not listened for), and whether unsigned ones are
    # believed (bench use only). Without a signing key and without that, nothing is listened for.
    designation_compid: int | None = DEFAULT_COMPID
    designation_unsigned: bool = False

    def __post_init__(self) -> None:
        for name in ("gcs_sysid", "gcs_compid"):
            if not 1 <= getattr(self, name) <= 255:
                raise ValueError(f"LinkConfig.{name} = {getattr(self, name)}: expected 1..255")
        if self.designation_compid is not None and not 1 <= self.designation_compid <= 255:
            raise ValueError(f"LinkConfig.designation_compid = {self.designation_compid}: expected 1..255 or None")
        if self.target_sysid is not None and not 1 <= self.target_sysid <= 255:
            raise ValueError(f"LinkConfig.target_sysid = {self.target_sysid}: expected 1..255 or None")
        for name in ("heartbeat_period_s", "ack_timeout_s", "quiet_timeout_s", "connect_timeout_s",
                     "ready_timeout_s", "confirm_timeout_s", "rc_resend_hz"):
            if not getattr(self, name) > 0:
                raise ValueError(f"LinkConfig.{name} = {getattr(self, name)}: expected > 0")
        if self.retries < 0:
            raise ValueError(f"LinkConfig.retries = {self.retries}: expected >= 0")
        for name, rate in self.stream_rates_hz.items():
            if not hasattr(mavlink, f"MAVLINK_MSG_ID_{name}"):
                raise ValueError(f"LinkConfig.stream_rates_hz: {name!r} is not a MAVLink message name")
            if not rate >= 0:
                raise ValueError(f"LinkConfig.stream_rates_hz[{name!r}] = {rate}: expected >= 0 (0 = off)")


@dataclass
class LinkCounters:
    """Diagnostics: what arrived, what was dropped, what had to be repeated."""

    received: Counter[str] = field(default_factory=Counter)  # valid messages by type, any sender
    bad_packets: int = 0  # garbled bytes / bad CRC (pymavlink BAD_DATA)
    other_systems: int = 0  # messages from systems other than our vehicle (ignored)
    unmatched_acks: int = 0  # COMMAND_ACKs for nothing we were waiting on
    commands_retried: int = 0  # command retransmissions after an ack timeout
    read_errors: int = 0  # socket errors while reading (connection reset, ...)


class VehicleLink:
    """A ground station's side of the MAVLink link to one ArduCopter."""

    def __init__(
        self, conn: mavutil.mavfile, config: LinkConfig = LinkConfig(), *, monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        """Wrap an open pymavlink ``mavfile``; nothing is sent until the first :meth:`poll`."""
        self.conn = conn
        self.config = config
        self._now = monotonic
        conn.source_system, conn.source_component = config.gcs_sysid, config.gcs_compid
        conn.mav.srcSystem, conn.mav.srcComponent = config.gcs_sysid, config.gcs_compid
        self.state = VehicleState()
        self.frame: LocalFrame | None = LocalFrame(config.origin) if config.origin is not None else None
        self.params: dict[str, float] = {}
        self.counters = LinkCounters()
        self.last_setpoint: Setpoint | None = None
        self.target_sysid: int | None = config.target_sysid
        self.target_compid: int | None = None
        self._telemetry = TelemetryGate(config.telemetry_limits)
        self._sequence = SequenceWatch()
        self._t_boot_seen = (math.nan, 0.0)  # (the vehicle's latest time, link time it last moved)
        self._timed_rx_at = -math.inf  # link time of the latest message carrying the vehicle's time
        self._fault_since: float | None = None  # link time state.telemetry_fault was set
        self._heartbeats = 0  # the vehicle's, believed
        self._commands = CommandTracker(
            ack_timeout_s=config.ack_timeout_s, retries=config.retries, confirm_timeout_s=config.confirm_timeout_s,
            heartbeats=lambda: self._heartbeats,
        )
        t = monotonic()
        self._opened_at = t
        self._last_rx_t = t
        self._last_rx_type = ""
        self._heartbeat = Cadence(config.heartbeat_period_s, t)
        self._streams_checked_at: float | None = None
        self._stream_rx: dict[str, float] = {}
        self._next_home_request = t
        self._rc_hold: tuple[int, int, int, int] | None = None
        self._rc_resend = Cadence(1.0 / config.rc_resend_hz, t)
        self._on_receive: list[Callable[[Any], None]] = []
        self._on_send: list[Callable[[Any], None]] = []
        self._wire_taps: list[tuple[Callable[[bytes], None], Callable[[float], None]]] = []
        conn.mav.set_send_callback(self._notify_sent)
        self.signing: SigningGate | None = None
        if config.signing is not None:
            # The Unix time makes the first timestamp newer than any this key signed before.
            self.signing = SigningGate(config.signing, signing_timestamp(time.time()))
            self.signing.attach(conn.mav)
        # Designations over MAVLink, answered as our own component of the vehicle's system (it also
        # sends that component's heartbeat, so ArduPilot learns to forward them to this port).
        self.designations: DesignationInbox | None = None
        if config.designation_compid is not None and (self.signing is not None or config.designation_unsigned):
            self.designations = DesignationInbox(config.designation_compid, allow_unsigned=config.designation_unsigned)
        self._companion: Any = None  # the encoder speaking as that component, once the vehicle is known

    # ----------------------------------------------------------------------------- opening
    @classmethod
    def connect(
        cls, url: str, config: LinkConfig = LinkConfig(), *, monotonic: Callable[[], float] = time.monotonic,
    ) -> VehicleLink:
        """Open ``url`` and block until the first autopilot HEARTBEAT (then streams are requested).

        Raises:
            VehicleUnreachable: nothing answered within ``config.connect_timeout_s``.
            ValueError: ``url`` is not a connection string (see :mod:`chaser_bt.vehicle.connection`).
        """
        timeout = config.connect_timeout_s
        conn = open_connection(url, source_system=config.gcs_sysid, source_component=config.gcs_compid,
                               timeout_s=timeout, monotonic=monotonic)
        try:
            link = cls(conn, config, monotonic=monotonic)
            # The iteration bound keeps this finite even with a clock that does not advance.
            for _ in range(math.ceil(timeout / 0.05) * 20):
                link._poll(check_quiet=False)
                if link.target_sysid is not None and link.target_compid is not None:
                    log.info("connected to vehicle %d on %s", link.target_sysid, url)
                    return link
                if monotonic() - link._opened_at >= timeout:
                    break
                conn.select(0.05)
        except BaseException:
            conn.close()
            raise
        conn.close()
        heard = ", ".join(f"{k} x{n}" for k, n in link.counters.received.most_common(5)) or "nothing"
        raise VehicleUnreachable(f"{url}: no autopilot HEARTBEAT within {timeout:g} s (heard: {heard})")

    @classmethod
    def over_pipe(cls, end: PipeEnd, config: LinkConfig = LinkConfig(), *, monotonic: Callable[[], float]) -> VehicleLink:
        """A link over an in-memory pipe end (rehearsals); never blocks."""
        conn = PipeConnection(end, source_system=config.gcs_sysid, source_component=config.gcs_compid)
        return cls(conn, config, monotonic=monotonic)

    def close(self) -> None:
        """Hand the sticks back if we held them, then close the connection."""
        if self._rc_hold is not None:
            self.release_rc()
        self.conn.close()

    # ----------------------------------------------------------------------------- polling
    def poll(self) -> int:
        """Drain input, update state, advance commands, send what is due; never blocks.

        Returns the number of valid messages handled.

        Raises:
            VehicleQuiet: nothing from the vehicle for ``quiet_timeout_s`` (raised on every poll
                until it speaks again; heartbeats and retries are still sent first).
        """
        if not self._wire_taps:
            return self._poll(check_quiet=True)
        started = self._now()
        try:
            return self._poll(check_quiet=True)
        finally:
            for _, on_poll in list(self._wire_taps):
                on_poll(started)

    def take_designations(self) -> list[MavlinkDesignation]:
        """The operator's designations from a ground station believed since the last call, oldest
        first (:mod:`chaser_bt.vehicle.designation`); always empty while :attr:`designations` is off."""
        return [] if self.designations is None else self.designations.take()

    def now(self) -> float:
        """The link's own clock (the injected ``monotonic``), on which every timer of the link runs."""
        return self._now()

    def last_heard_s(self, mtype: str) -> float | None:
        """Link time (:meth:`now`) of the latest ``mtype`` message from our vehicle; None: never heard."""
        return self._stream_rx.get(mtype)

    @property
    def opened_at_s(self) -> float:
        """:meth:`now` when the link was opened: its timers and ``time_boot_ms`` count from here."""
        return self._opened_at

    def _poll(self, *, check_quiet: bool) -> int:
        now = self._now()
        handled = 0
        for _ in range(_MAX_MESSAGES_PER_POLL):
            try:
                msg = self.conn.recv_msg()
            except OSError as e:  # a reset TCP connection; silence will be reported as quiet
                self.counters.read_errors += 1
                log.debug("read error on %s: %s", self.conn.address, e)
                break
            if msg is None:
                break
            handled += self._handle(msg, now)
        self._commands.tick(now)
        self.counters.commands_retried = self._commands.retried
        self._send_due(now)
        if check_quiet:
            self._check_quiet(now)
        return handled

    def wait(
        self, cmd_or_predicate: Command | Callable[..., bool], timeout_s: float, *,
        pump: Callable[[], None] | None = None,
    ) -> Command | bool:
        """Block until a command is done or a condition holds (scripts and tests, never behaviours).

        Loops ``pump()`` + :meth:`poll`; ``pump`` defaults to waiting briefly for input (pass the
        simulator's ``step`` to run in lock-step). A predicate takes the :class:`VehicleState`,
        or nothing. Returns the accepted command, or True.

        Raises:
            CommandRejected: the command finished FAILED or TIMED_OUT.
            LinkTimeout: not done within ``timeout_s`` on the link's clock.
        """
        if isinstance(cmd_or_predicate, Command):
            cmd = cmd_or_predicate
            done: Callable[[], bool] = lambda: cmd.done  # noqa: E731
            what = cmd.name
        else:
            predicate = cmd_or_predicate
            takes_state = bool(inspect.signature(predicate).parameters)
            done = (lambda: bool(predicate(self.state))) if takes_state else (lambda: bool(predicate()))
            what = getattr(predicate, "__name__", "condition")
        pump = pump if pump is not None else (lambda: self.conn.select(0.01))
        deadline = self._now() + timeout_s
        while True:
            self.poll()
            if done():
                break
            if self._now() >= deadline:
                raise LinkTimeout(f"{what}: not done within {timeout_s:g} s")
            pump()
        if isinstance(cmd_or_predicate, Command):
            if not cmd_or_predicate.ok:
                c = cmd_or_predicate
                raise CommandRejected(f"{c.name} {c.status.value}: {c.reason}")
            return cmd_or_predicate
        return True

    @property
    def in_flight(self) -> list[Command]:
        """Commands not finished yet, oldest first."""
        return self._commands.in_flight

    # ----------------------------------------------------------------------------- commands
    def arm(self) -> Command:
        """Arm; waits (WAITING) up to ``ready_timeout_s`` for :attr:`VehicleState.ready_to_arm`.

        Take off promptly once armed: ArduCopter disarms itself after DISARM_DELAY (10 s) on the ground.
        """
        if self.state.armed:
            return self._commands.accept_now(Command("arm"))
        return self._submit("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,), blocker=self._not_ready_to_arm,
                            wait_s=self.config.ready_timeout_s, confirm=lambda: self.state.armed)

    def disarm(self, force: bool = False) -> Command:
        """Disarm (``force`` also in flight: the motors stop)."""
        if self.target_sysid is not None and self.state.mode and not self.state.armed:
            return self._commands.accept_now(Command("disarm"))
        return self._submit("disarm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                            (0, _FORCE_DISARM_MAGIC if force else 0), confirm=lambda: not self.state.armed)

    def set_mode(self, name: str) -> Command:
        """Switch flight mode; accepted once acked and shown in HEARTBEAT.custom_mode.

        Before the vehicle is armed, a mode that needs a position estimate (GUIDED, LOITER, RTL...)
        waits (WAITING, up to ``ready_timeout_s``) for a 3-D fix and the EKF's position, as
        :meth:`arm` does; in the air it is sent at once. Switching to ALT_HOLD first holds throttle at 1500 by RC override (unless sticks are held
        already): ALT_HOLD reads the throttle stick as a climb rate, and a low stick sinks.

        Raises:
            ValueError: ``name`` is not an ArduCopter mode.
        """
        if name not in COPTER_MODES:
            raise ValueError(f"unknown ArduCopter mode {name!r}; known: {', '.join(COPTER_MODES)}")
        cmd_name = f"set_mode({name})"
        if self.state.mode == name:
            return self._commands.accept_now(Command(cmd_name))
        if name == "ALT_HOLD" and self._rc_hold is None:
            self.rc_override(throttle=_RC_CENTRE)
        params = (mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, COPTER_MODES[name])
        if name in _POSITION_MODES and not self.state.armed:
            # On the ground after boot ArduCopter refuses these until the EKF has a position:
            # wait for it as arm() does, instead of failing the first request.
            return self._submit(cmd_name, mavlink.MAV_CMD_DO_SET_MODE, params, blocker=self._no_position(name),
                                wait_s=self.config.ready_timeout_s, confirm=lambda: self.state.mode == name)
        return self._submit(cmd_name, mavlink.MAV_CMD_DO_SET_MODE, params, confirm=lambda: self.state.mode == name)

    def takeoff(self, alt_rel_m: float) -> Command:
        """GUIDED take-off to ``alt_rel_m`` above home (ArduCopter: armed, GUIDED, landed)."""
        if not alt_rel_m > 0:
            raise ValueError(f"takeoff altitude {alt_rel_m} m: expected > 0 (above home)")
        self.envelope.check_altitude(alt_rel_m)
        return self._submit(f"takeoff({alt_rel_m:g} m)", mavlink.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, 0, 0, alt_rel_m))

    def rtl(self) -> Command:
        """Return to launch (MAV_CMD_NAV_RETURN_TO_LAUNCH); accepted once HEARTBEAT shows RTL."""
        return self._mode_command("rtl", mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, "RTL")

    def land(self) -> Command:
        """Land here (MAV_CMD_NAV_LAND); accepted once HEARTBEAT shows LAND."""
        return self._mode_command("land", mavlink.MAV_CMD_NAV_LAND, "LAND")

    def set_speed(self, speed_mps: float) -> Command:
        """Horizontal speed for GUIDED legs (MAV_CMD_DO_CHANGE_SPEED, ground speed; throttle unchanged)."""
        if not speed_mps > 0:
            raise ValueError(f"speed {speed_mps} m/s: expected > 0")
        self.envelope.check_speed(speed_mps)
        return self._submit(f"set_speed({speed_mps:g} m/s)", mavlink.MAV_CMD_DO_CHANGE_SPEED, (1, speed_mps, -1))

    def set_param(self, name: str, value: float) -> Command:
        """Set a parameter; accepted when PARAM_VALUE echoes the value (as float32)."""
        _check_param_name(name)
        want = np.float32(value)

        def send(attempt: int) -> None:
            self.conn.mav.param_set_send(self.target_sysid, self.target_compid, name.encode(), float(value),
                                         mavlink.MAV_PARAM_TYPE_REAL32)

        return self._commands.submit(
            Command(f"set_param({name})"), ("param_set", name), send, self._now(),
            blocker=self._vehicle_unknown, wait_s=self._answer_budget_s(), matches=lambda v: np.float32(v) == want,
        )

    @property
    def envelope(self) -> CommandEnvelope:
        """The command envelope in force: the configured one, cut down to the vehicle's fence once its
        FENCE_* parameters have been read (:func:`chaser_bt.mission.preflight.read_fence`)."""
        return self.config.envelope.within_fence(self.params)

    def request_param(self, name: str) -> Command:
        """Read a parameter into :attr:`params`; accepted when its PARAM_VALUE arrives."""
        _check_param_name(name)
        key = ("param_get", name)
        pending = self._commands.find(key)
        if pending is not None:
            return pending

        def send(attempt: int) -> None:
            self.conn.mav.param_request_read_send(self.target_sysid, self.target_compid, name.encode(), -1)

        return self._commands.submit(Command(f"request_param({name})"), key, send, self._now(),
                                     blocker=self._vehicle_unknown, wait_s=self._answer_budget_s())

    # ----------------------------------------------------------------------------- set-points
    def goto_enu(self, pos_enu: Sequence[float] | np.ndarray, yaw_enu_rad: float | None = None) -> None:
        """GUIDED: fly to ``pos_enu`` in :attr:`frame` and hold there (no ack; holds until replaced).

        Raises:
            UnsafeCommand: the target is outside the command envelope (nothing was sent).
        """
        self._check_target_enu(pos_enu)
        self._goto_enu(pos_enu, yaw_enu_rad)

    def _goto_enu(self, pos_enu: Sequence[float] | np.ndarray, yaw_enu_rad: float | None) -> None:
        if self.frame is None:
            raise VehicleError("no ENU frame yet: the vehicle's HOME_POSITION has not arrived (or set LinkConfig.origin)")
        p = self.frame.to_geodetic(pos_enu)
        if self.state.home is not None:
            self._send_position(p.lat_deg, p.lon_deg, p.alt_m - self.state.home.alt_m, yaw_enu_rad, relative=True)
        else:
            self._send_position(p.lat_deg, p.lon_deg, p.alt_m, yaw_enu_rad, relative=False)

    def goto_global(self, point: GeoPoint, alt_rel_m: float, yaw_enu_rad: float | None = None) -> None:
        """GUIDED: fly to ``point``'s latitude/longitude at ``alt_rel_m`` above home, and hold (checked
        against the command envelope like :meth:`goto_enu`)."""
        if self.frame is None:
            self.envelope.check_altitude(alt_rel_m)
        else:
            east, north, _ = self.frame.point_to_enu(point) - self._home_enu()
            self.envelope.check_position(float(east), float(north), alt_rel_m)
        self._send_position(point.lat_deg, point.lon_deg, alt_rel_m, yaw_enu_rad, relative=True)

    def velocity_enu(self, vel_enu: Sequence[float] | np.ndarray, yaw_rate: float | None = None,
                     yaw_enu_rad: float | None = None) -> None:
        """GUIDED: fly at ``vel_enu`` m/s and turn at ``yaw_rate`` rad/s counter-clockwise, or to the
        heading ``yaw_enu_rad`` (the autopilot's own yaw controller turns there; not both); resend < 3 s
        or it stops."""
        if yaw_rate is not None and yaw_enu_rad is not None:
            raise ValueError("velocity_enu: give a yaw rate or a heading, not both")
        self.envelope.check_velocity(vel_enu, yaw_rate)
        self._require_vehicle()
        vn, ve, vd = enu_to_ned(vel_enu)
        mask = _VELOCITY_ONLY | (mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE if yaw_rate is None else 0)
        if yaw_enu_rad is not None:
            mask &= ~mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
        yaw_ned = 0.0 if yaw_enu_rad is None else wrap_pi(enu_yaw_to_heading(yaw_enu_rad))
        rate_ned = 0.0 if yaw_rate is None else -yaw_rate  # NED yaw rate turns clockwise seen from above
        self.conn.mav.set_position_target_local_ned_send(
            self._time_boot_ms(), self.target_sysid, self.target_compid, mavlink.MAV_FRAME_LOCAL_NED, mask,
            0, 0, 0, vn, ve, vd, 0, 0, 0, yaw_ned, rate_ned,
        )
        rate = math.nan if yaw_rate is None else float(yaw_rate)
        self.last_setpoint = Setpoint("velocity", self._now(), (float(vel_enu[0]), float(vel_enu[1]), float(vel_enu[2]), rate))

    def rc_override(self, roll: int = _RC_LEAVE, pitch: int = _RC_LEAVE, throttle: int = _RC_LEAVE,
                    yaw: int = _RC_LEAVE) -> None:
        """Override sticks 1-4 (PWM; 65535 = leave alone, 0 = give back to the radio); held and resent
        at ``rc_resend_hz`` until :meth:`release_rc` or a switch to a mode the autopilot flies itself."""
        channels = (roll, pitch, throttle, yaw)
        for ch, v in zip(("roll", "pitch", "throttle", "yaw"), channels):
            if v not in (_RC_LEAVE, _RC_RELEASE) and not 800 <= v <= 2200:
                raise ValueError(f"rc_override {ch} = {v}: expected PWM 800..2200, 65535 (leave alone) or 0 (release)")
        self._require_vehicle()
        self._rc_hold = tuple(int(v) for v in channels)  # type: ignore[assignment]
        now = self._now()
        self._send_rc(self._rc_hold)
        self._rc_resend.restart(now, self._vehicle_t())
        self.last_setpoint = Setpoint("rc_override", now, tuple(float(v) for v in channels))

    def release_rc(self) -> None:
        """Stop overriding: every channel back to the pilot's radio (all fields 0)."""
        self._rc_hold = None
        if self.target_sysid is None:
            return
        self._send_rc((_RC_RELEASE,) * 4, rest=_RC_RELEASE)
        self.last_setpoint = Setpoint("rc_release", self._now())

    def hover(self, yaw_enu_rad: float | None = None) -> bool:
        """The safe "stop moving" for the current mode (DESIGN §3: a behaviour's exit command); in
        GUIDED, turning on the spot to ``yaw_enu_rad`` when given (the nose, and a fixed camera, towards
        where the target was last reported), else keeping the heading.

        GUIDED: hold the current position (zero velocity if it is not known yet); STABILIZE/ALT_HOLD:
        centred sticks; LOITER, BRAKE, RTL, LAND and the rest already fly themselves: nothing.
        Disarmed: nothing either; a centred-throttle override left on a vehicle on the ground would
        wait for whoever arms it next. With a telemetry fault none of that can be believed: zero
        velocity, which a GUIDED aircraft holds and any other mode ignores. Returns whether a command
        was sent.
        """
        s = self.state
        if s.telemetry_fault:  # what it says (armed, mode, where) cannot be believed: stop it where it really is
            self.velocity_enu((0.0, 0.0, 0.0))
            return True
        if not s.armed:
            return False
        if s.mode == "GUIDED":
            yaw = yaw_enu_rad if yaw_enu_rad is not None else (s.yaw_enu_rad if math.isfinite(s.yaw_enu_rad) else None)
            if self.frame is not None and np.all(np.isfinite(s.position_enu)):
                self._goto_enu(s.position_enu, yaw)
            else:
                self.velocity_enu((0.0, 0.0, 0.0), yaw_enu_rad=yaw_enu_rad)
            return True
        if s.mode in _HOVER_BY_STICKS:
            self.rc_override(_RC_CENTRE, _RC_CENTRE, _RC_CENTRE, _RC_CENTRE)
            return True
        return False

    def add_listener(
        self, *, on_receive: Callable[[Any], None] | None = None, on_send: Callable[[Any], None] | None = None,
    ) -> None:
        """Observe every MAVLink message from the vehicle and every one sent to it (recorders, tests).

        Listeners get the decoded pymavlink message; they run inside :meth:`poll` and the senders,
        so they must be quick and must not raise.
        """
        if on_receive is not None:
            self._on_receive.append(on_receive)
        if on_send is not None:
            self._on_send.append(on_send)

    def add_wire_tap(self, on_read: Callable[[bytes], None], on_poll: Callable[[float], None]) -> Callable[[], None]:
        """Observe the raw link: ``on_read(data)`` gets every chunk of bytes read from the connection
        (by :meth:`poll`, :meth:`wait` or :meth:`connect`), ``on_poll(t)`` runs after each :meth:`poll`
        with the link time (:meth:`now`) at which that poll began, even when it raised.

        Feeding the same bytes at the same times to a link with the same configuration reproduces
        this one exactly (the flight recorder and replay rely on it). Both run inside the link, so
        they must be quick and must not raise. Returns a function that removes the tap.
        """
        if not self._wire_taps:
            self._tap_connection()
        tap = (on_read, on_poll)
        self._wire_taps.append(tap)

        def remove() -> None:
            if tap in self._wire_taps:
                self._wire_taps.remove(tap)

        return remove

    # ----------------------------------------------------------------------------- internals
    def _tap_connection(self) -> None:
        """Route the connection's reads through the wire taps (once; pymavlink reads with ``recv``)."""
        conn_recv = self.conn.recv

        def recv(*args: Any, **kwargs: Any) -> Any:
            data = conn_recv(*args, **kwargs)
            if data:
                for on_read, _ in list(self._wire_taps):
                    on_read(bytes(data))
            return data

        self.conn.recv = recv

    def _notify_sent(self, msg: Any) -> None:
        for listener in self._on_send:
            listener(msg)

    def _handle(self, msg: Any, now: float) -> int:
        mtype = msg.get_type()
        if self.signing is not None and mtype != "BAD_DATA" and self._claims_vehicle(msg, mtype):
            if not self.signing.admit(msg):
                return 0  # unsigned or wrongly signed "vehicle": counted by the gate, never believed
        for listener in self._on_receive:
            listener(msg)
        if mtype == "BAD_DATA":
            self.counters.bad_packets += 1
            return 0
        self.counters.received[mtype] += 1
        if mtype in COMMAND_MESSAGES and self._designation(msg):
            return 1
        src, comp = msg.get_srcSystem(), msg.get_srcComponent()
        if self.target_compid is None:
            if not (mtype == "HEARTBEAT" and _is_autopilot(msg) and self.target_sysid in (None, src)):
                self.counters.other_systems += 1
                return 1
            self.target_sysid, self.target_compid = src, comp
            log.info("vehicle is system %d component %d", src, comp)
        if src != self.target_sysid:
            self.counters.other_systems += 1
            return 1
        if mtype == "STATUSTEXT":  # any component of the vehicle may explain itself
            self._on_statustext(msg, now)
            return 1
        if comp != self.target_compid:
            return 1
        self._sequence.observe(msg.get_seq())
        admitted = self._telemetry.admit(msg, self.state, now)
        self._set_telemetry_fault(self._telemetry.fault or self._sequence.fault, now)
        if not admitted:
            return 0  # counted on state.telemetry_rejected; not heard, not believed
        if getattr(msg, "time_boot_ms", None) is not None:
            self._timed_rx_at = now
        self._last_rx_t, self._last_rx_type = now, mtype
        self._stream_rx[mtype] = now
        if mtype == "COMMAND_ACK":
            self._on_ack(msg, now)
        elif mtype == "PARAM_VALUE":
            name = _param_id(msg)
            self.params[name] = float(msg.param_value)
            self._commands.on_param_value(name, float(msg.param_value), now)
        else:
            previous_mode = self.state.mode
            update_state(self.state, msg, self.frame)
            self._heartbeats += mtype == "HEARTBEAT"
            if self.state.t_boot_s != self._t_boot_seen[0]:
                self._t_boot_seen = (self.state.t_boot_s, now)
            if mtype == "HEARTBEAT" and self.state.mode != previous_mode:
                self._on_mode_change(previous_mode)
            elif mtype == "HOME_POSITION" and self.frame is None:
                self.frame = LocalFrame(self.state.home)
                log.info("ENU frame origin = home %s", self.state.home)
        return 1

    def _designation(self, msg: Any) -> bool:
        """Judge a command for our designation component and answer it; False: not one for us."""
        if self.designations is None or self.target_sysid is None:
            return False
        judgement = self.designations.receive(msg, sysid=self.target_sysid, auth=authenticity(msg, self.signing))
        if judgement is None:
            return False
        if judgement.ack is not None:
            self._send_designation_ack(msg, judgement)
        return True

    def _send_designation_ack(self, msg: Any, judgement: Judgement) -> None:
        """COMMAND_ACK from our designation component to whoever sent ``msg`` (GCS_Common.cpp's fields)."""
        self._companion_mav().command_ack_send(msg.command, judgement.ack, 0, judgement.bad_param,
                                               msg.get_srcSystem(), msg.get_srcComponent())

    def _companion_mav(self) -> Any:
        """The encoder that speaks as our designation component of the vehicle's system (signed as the link)."""
        if self._companion is None:
            mav = mavlink.MAVLink(self.conn, srcSystem=self.target_sysid, srcComponent=self.config.designation_compid)
            if self.signing is not None:
                self.signing.attach(mav)
            mav.set_send_callback(self._notify_sent)
            self._companion = mav
        return self._companion

    def _claims_vehicle(self, msg: Any, mtype: str) -> bool:
        """From our vehicle's system, or an autopilot heartbeat that could make itself our vehicle."""
        src = msg.get_srcSystem()
        if self.target_sysid is not None and src == self.target_sysid:
            return True
        return self.target_compid is None and mtype == "HEARTBEAT" and _is_autopilot(msg)

    def _on_statustext(self, msg: Any, now: float) -> None:
        update_state(self.state, msg, self.frame)
        text = statustext_str(msg)
        level = logging.WARNING if msg.severity <= mavlink.MAV_SEVERITY_ERROR else logging.INFO
        log.log(level, "vehicle: %s", text)
        self._commands.on_statustext(int(msg.severity), text, now)

    def _on_ack(self, msg: Any, now: float) -> None:
        if msg.target_system not in (0, self.config.gcs_sysid) or msg.command in _SELF_SERVICE_CMDS:
            return
        if not self._commands.on_ack(msg.command, msg.result, now):
            self.counters.unmatched_acks += 1

    def _on_mode_change(self, previous: str) -> None:
        log.info("mode %s -> %s", previous or "?", self.state.mode)
        if self._rc_hold is not None and self.state.mode not in _STICK_MODES:
            log.info("%s flies itself: releasing the RC override", self.state.mode)
            self.release_rc()

    def _send_due(self, now: float) -> None:
        vehicle_t = self._vehicle_t()
        if self._heartbeat.fire(now, vehicle_t):
            self.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                         mavlink.MAV_STATE_ACTIVE)
            if self.designations is not None and self.target_compid is not None:
                self._companion_mav().heartbeat_send(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID,
                                                     0, 0, mavlink.MAV_STATE_ACTIVE)
        if self.target_compid is None:
            return
        if self._streams_checked_at is None or _due(now, self._streams_checked_at + _STREAM_CHECK_S):
            self._request_streams(now)
        if self.state.home is None and _due(now, self._next_home_request):
            self._send_command_long(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_HOME_POSITION)
            self._next_home_request = now + _HOME_REQUEST_S
        if self._rc_hold is not None and self._rc_resend.fire(now, vehicle_t):
            self._send_rc(self._rc_hold)

    def _request_streams(self, now: float) -> None:
        """Ask for every configured stream the first time, then again for those not arriving."""
        first = self._streams_checked_at is None
        for name, rate in self.config.stream_rates_hz.items():
            if rate > 0 and not first:
                last = self._stream_rx.get(name)
                if last is not None and now - last <= max(3.0 / rate, _STREAM_CHECK_S):
                    continue
                log.debug("stream %s missing, asking again", name)
            elif rate <= 0 and not first:
                continue
            interval_us = 1e6 / rate if rate > 0 else -1
            self._send_command_long(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                                    getattr(mavlink, f"MAVLINK_MSG_ID_{name}"), interval_us)
        self._streams_checked_at = now

    def _set_telemetry_fault(self, fault: str, now: float) -> None:
        if fault and self._fault_since is None:
            self._fault_since = now
        elif not fault:
            self._fault_since = None
        self.state.telemetry_fault = fault

    def _check_quiet(self, now: float) -> None:
        silent, timeout = now - self._last_rx_t, self.config.quiet_timeout_s
        if silent <= timeout:
            t_boot, moved_at = self._t_boot_seen
            if now - self._timed_rx_at <= 1.0 and now - moved_at > timeout:
                raise VehicleQuiet(f"vehicle {self.target_sysid}'s time frozen at {t_boot:.1f} s for "
                                   f"{now - moved_at:.1f} s while its messages keep coming")
            if self._fault_since is not None and now - self._fault_since > timeout:
                raise VehicleQuiet(f"vehicle {self.target_sysid}: {self.state.telemetry_fault}, for "
                                   f"{now - self._fault_since:.1f} s")
            return
        if not self._last_rx_type:
            raise VehicleQuiet(f"no MAVLink from an autopilot in the {silent:.1f} s since the link opened "
                               f"(quiet_timeout_s = {self.config.quiet_timeout_s:g})")
        raise VehicleQuiet(f"vehicle {self.target_sysid} quiet for {silent:.1f} s: last heard {self._last_rx_type} "
                           f"at vehicle time {self.state.t_boot_s:.1f} s (quiet_timeout_s = "
                           f"{self.config.quiet_timeout_s:g})")

    def _submit(self, name: str, command_id: int, params: Sequence[float], *,
                blocker: Callable[[], str | None] | None = None, wait_s: float | None = None,
                confirm: Callable[[], bool] | None = None) -> Command:
        p = (tuple(float(x) for x in params) + (0.0,) * 7)[:7]

        def send(attempt: int) -> None:
            self.conn.mav.command_long_send(self.target_sysid, self.target_compid, command_id, min(attempt, 255), *p)

        return self._commands.submit(
            Command(name), ("cmd", command_id), send, self._now(), blocker=blocker or self._vehicle_unknown,
            wait_s=self._answer_budget_s() if wait_s is None else wait_s, confirm=confirm,
        )

    def _mode_command(self, name: str, command_id: int, mode: str) -> Command:
        if self.state.mode == mode:
            return self._commands.accept_now(Command(name))
        return self._submit(name, command_id, (), confirm=lambda: self.state.mode == mode)

    def _send_command_long(self, command_id: int, *params: float) -> None:
        p = (tuple(float(x) for x in params) + (0.0,) * 7)[:7]
        self.conn.mav.command_long_send(self.target_sysid, self.target_compid, command_id, 0, *p)

    def _home_enu(self) -> np.ndarray:
        """Home in :attr:`frame` (the frame's origin until HOME_POSITION arrives)."""
        if self.frame is None or self.state.home is None:
            return np.zeros(3)
        return self.frame.point_to_enu(self.state.home)

    def _check_target_enu(self, pos_enu: Sequence[float] | np.ndarray) -> None:
        target = np.asarray(pos_enu, dtype=float)
        if target.shape != (3,) or not np.all(np.isfinite(target)):
            raise UnsafeCommand(f"position target not finite: {list(np.ravel(target))}")
        east, north, up = target - self._home_enu()
        self.envelope.check_position(float(east), float(north), float(up))

    def _send_position(self, lat_deg: float, lon_deg: float, alt_m: float, yaw_enu_rad: float | None, *,
                       relative: bool) -> None:
        self._require_vehicle()
        frame = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT if relative else mavlink.MAV_FRAME_GLOBAL_INT
        mask = _POSITION_ONLY | (mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE if yaw_enu_rad is None else 0)
        yaw_ned = 0.0 if yaw_enu_rad is None else wrap_pi(enu_yaw_to_heading(yaw_enu_rad))
        self.conn.mav.set_position_target_global_int_send(
            self._time_boot_ms(), self.target_sysid, self.target_compid, frame, mask,
            round(lat_deg * 1e7), round(lon_deg * 1e7), alt_m, 0, 0, 0, 0, 0, 0, yaw_ned, 0,
        )
        yaw = math.nan if yaw_enu_rad is None else float(yaw_enu_rad)
        self.last_setpoint = Setpoint("position", self._now(), (lat_deg, lon_deg, alt_m, yaw))

    def _send_rc(self, sticks: Sequence[int], rest: int = _RC_LEAVE) -> None:
        # Channels 5-8: 65535 leaves them alone (0 would release); 9-18: 0 means "ignore".
        self.conn.mav.rc_channels_override_send(self.target_sysid, self.target_compid, *sticks, *(rest,) * 4)

    def _not_ready_to_arm(self) -> str | None:
        if self.target_compid is None:
            return "no heartbeat from the vehicle yet"
        s = self.state
        missing = []
        if not s.prearm_ok:
            missing.append("pre-arm checks failing (SYS_STATUS)")
        if s.gps_fix_type < 3:
            missing.append(f"GPS fix type {s.gps_fix_type}, need 3 (3-D)")
        if not s.ekf_ok:
            missing.append("EKF has no absolute position (EKF_STATUS_REPORT)")
        return "not ready to arm: " + ", ".join(missing) if missing else None

    def _no_position(self, mode: str) -> Callable[[], str | None]:
        def blocker() -> str | None:
            s = self.state
            if self.target_compid is None:
                return "no heartbeat from the vehicle yet"
            if s.armed or (s.ekf_ok and s.gps_fix_type >= 3):
                return None
            return f"{mode} needs a position estimate: GPS fix type {s.gps_fix_type}, EKF position {'ok' if s.ekf_ok else 'not ready'}"
        return blocker

    def _vehicle_unknown(self) -> str | None:
        return "no heartbeat from the vehicle yet" if self.target_compid is None else None

    def _require_vehicle(self) -> None:
        if self.target_compid is None:
            raise VehicleError("no heartbeat from the vehicle yet: nowhere to send a set-point")

    def _answer_budget_s(self) -> float:
        return self.config.ack_timeout_s * (self.config.retries + 1)

    def _vehicle_t(self) -> float:
        """The vehicle's time for the cadences when they keep to it (``nan``: the link's clock only)."""
        return self.state.t_boot_s if self.config.timers_on_vehicle_time else math.nan

    def _time_boot_ms(self) -> int:
        return int((self._now() - self._opened_at) * 1000) & 0xFFFFFFFF


def _due(now: float, when: float) -> bool:
    """``now`` has reached ``when`` (a microsecond of slack absorbs float error in the clock)."""
    return now >= when - 1e-6


def _is_autopilot(msg: Any) -> bool:
    """A HEARTBEAT from a flight controller (not a GCS, gimbal, camera, or companion computer)."""
    return (msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID
            and msg.type not in (mavlink.MAV_TYPE_GCS, mavlink.MAV_TYPE_GIMBAL, mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
                                 mavlink.MAV_TYPE_ADSB, mavlink.MAV_TYPE_CAMERA))


def _param_id(msg: Any) -> str:
    pid = msg.param_id
    if isinstance(pid, (bytes, bytearray)):
        pid = pid.decode("ascii", "replace")
    return pid.rstrip("\x00")


def _check_param_name(name: str) -> None:
    if not name or len(name) > 16 or not name.isascii():
        raise ValueError(f"parameter name {name!r}: expected 1..16 ASCII characters")
