"""The scenario's faults and the operator's ground-station commands, injected into ArduCopter SITL as a tester would.

The built-in simulator scripts its faults inside its own autopilot (:mod:`sitl.vehicle.autopilot`).
ArduCopter's code cannot be reached that way, so each fault is struck from outside, the way
ArduPilot's own autotest strikes it, from a **second ground station**: a TCP client on ArduCopter's
SERIAL1 (SITL's default ``--serial1 tcp:2``, port ``5762 + 10 I``), source system
:data:`SECOND_GCS_SYSID` (254), never the mission's. ArduCopter obeys COMMAND_LONG and PARAM_SET
from any system id unless MAV_OPTIONS enforces MAV_GCS_SYSID (off by default); it sends no
heartbeat, so ArduCopter's GCS failsafe still watches the mission's link alone.

=================  ==========================================================================
kind               what is sent, at ``at_s`` (and undone at ``at_s + duration_s`` if given)
=================  ==========================================================================
``disarm``         COMMAND_LONG MAV_CMD_COMPONENT_ARM_DISARM, param1 0, param2 21196 (forced)
``gps_loss``       PARAM_SET ``SIM_GPS1_ENABLE`` 0 (the simulated receiver goes silent); back to 1
``battery_drop``   PARAM_SET ``SIM_BATT_VOLTAGE`` lowered by one cell's worth (the pack's voltage over
                   its cell count, 4.2 V a cell: 12.6 V, SITL's default 3S, drops to 8.4 V, below
                   ArduCopter's default BATT_LOW_VOLT 10.5 V); back to the value read at connect
``rc_loss``        PARAM_SET ``SIM_RC_FAIL`` 1 (SITL's receiver gives no pulses) and the safety
                   pilot's RC datagrams stop (:meth:`FaultInjector.rc_silent`); back to 0.
                   Stopping the datagrams alone fires nothing: SITL's UDP receiver
                   (AP_RCProtocol_UDP) repeats the last frame it got at 50 Hz for ever
``link_loss``      not a command: the mission's TCP link to SERIAL0 runs through :class:`LinkRelay`,
                   which drops every byte both ways while the fault is in force
ground station     COMMAND_LONG MAV_CMD_DO_SET_MODE, param1 1 (custom mode), param2 the ArduCopter
                   mode number (:data:`sitl.vehicle.setup.GCS_MODES`)
=================  ==========================================================================

Times are the world's clock (:attr:`ArduPilotSimulator.time_s`: seconds since ArduCopter was ready
to arm), not ArduCopter's boot clock. Each injection is logged with ArduCopter's reply
(COMMAND_ACK, or the PARAM_VALUE it broadcasts after a set) in :attr:`FaultInjector.injections`; a
refused or unanswered one is logged as a warning (its ``reply`` is the refusal, or None), and a
fault that cannot be struck at all (SERIAL1 refuses the connection, the battery's voltage was never
read) raises :class:`FaultNotInjected`, so a run never passes for a fault that did not happen.
"""

from __future__ import annotations

import logging
import math
import os
import socket
from dataclasses import dataclass, field
from typing import Callable, Iterable

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from sitl.vehicle.setup import GCS_MODES, Fault, GroundStationEvent  # noqa: E402

__all__ = ["FaultInjector", "FaultNotInjected", "Injection", "LinkRelay", "SECOND_GCS_SYSID", "SERIAL1_OFFSET"]

log = logging.getLogger(__name__)

SECOND_GCS_SYSID = 254  # the operator's second ground station; the mission is MAV_GCS_SYSID (255)
_SECOND_GCS_COMPID = mavlink2.MAV_COMP_ID_MISSIONPLANNER
SERIAL1_OFFSET = 2  # SITL's default --serial1 tcp:2: SERIAL0's port + 2
_VOLTS_PER_CELL = 4.2  # a full LiPo cell, as SIM_BATT_VOLTAGE's default 12.6 V is a full 3S pack
_FORCE_DISARM = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2: disarm even in the air
_REPLY_WAIT_S = 2.0  # world seconds to wait for ArduCopter's reply before warning
_CONNECT_WAIT_S = 5.0  # world seconds SERIAL1 may refuse before the faults are given up on
_RECV_CHUNK = 65536
_MAX_PENDING = 1 << 20  # bytes a relay holds for a peer that does not read; older ones are dropped


class FaultNotInjected(RuntimeError):
    """A scripted fault could not be struck on ArduCopter (the message says which and why)."""


@dataclass
class Injection:
    """One thing the second ground station did, and what ArduCopter answered.

    Attributes:
        at_s: world time it was due.
        what: e.g. ``"gps_loss: SIM_GPS1_ENABLE 0"``.
        reply: ArduCopter's answer (``"COMMAND_ACK ACCEPTED"``, ``"PARAM_VALUE 0"``) or None (none yet).
    """

    at_s: float
    what: str
    reply: str | None = None


@dataclass
class _Action:
    at_s: float
    what: str
    build: Callable[[], tuple[object, str]]  # (the MAVLink message, what it does), built when due
    expect: tuple[str, object]  # what answers it: ("ack", command id) or ("param", name)
    record: Injection | None = field(default=None)
    value: float | None = None  # a parameter's new value, once sent: only a PARAM_VALUE with it answers


def _param_id(name: str) -> bytes:
    return name.encode("ascii")


class FaultInjector:
    """A second ground station on ArduCopter's SERIAL1 that strikes the scenario's faults on time.

    Args:
        faults: the scenario's faults (``link_loss`` is left to :class:`LinkRelay`).
        ground_station: the operator's scripted mode changes.
        address: SERIAL1's TCP address.
        target_sysid: ArduCopter's SYSID_THISMAV.

    Call :meth:`step` with the world's time after every world step; :meth:`rc_silent` says whether
    the safety pilot's transmitter is to stay silent. It also listens, as the operator would:
    :attr:`texts` holds ArduCopter's STATUSTEXTs as heard on SERIAL1 (while a ``link_loss`` cuts the
    mission's link, this is where "GCS Failsafe" is seen).
    """

    def __init__(self, faults: Iterable[Fault], ground_station: Iterable[GroundStationEvent],
                 address: tuple[str, int], *, target_sysid: int = 1) -> None:
        self.address = address
        self.target_sysid = target_sysid
        faults = tuple(faults)
        self._rc_windows = tuple(f for f in faults if f.kind == "rc_loss")
        self._mav = mavlink2.MAVLink(None, srcSystem=SECOND_GCS_SYSID, srcComponent=_SECOND_GCS_COMPID)
        self._mav.robust_parsing = True
        self._sock: socket.socket | None = None
        self._first_try_s: float | None = None
        self.params: dict[str, float] = {}  # values ArduCopter reported on this link
        self.texts: list[tuple[float, str]] = []  # (world time, STATUSTEXT) as this ground station heard them
        self._now = 0.0
        self.injections: list[Injection] = []
        self._waiting: list[_Action] = []
        self._actions = sorted(self._plan(faults, ground_station), key=lambda a: a.at_s)

    @property
    def pending(self) -> int:
        """Injections still to come."""
        return len(self._actions)

    def rc_silent(self, t_s: float) -> bool:
        """Whether an ``rc_loss`` fault is in force at world time ``t_s`` (the transmitter sends nothing)."""
        return any(f.active(t_s) for f in self._rc_windows)

    # -- the plan -------------------------------------------------------------------------------------
    def _plan(self, faults: tuple[Fault, ...], events: Iterable[GroundStationEvent]) -> list[_Action]:
        actions: list[_Action] = []
        for f in faults:
            end = None if f.duration_s is None else f.at_s + f.duration_s
            if f.kind == "disarm":
                actions.append(self._command(f.at_s, "disarm: forced disarm",
                                             mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0, _FORCE_DISARM))
            elif f.kind == "gps_loss":
                actions.append(self._param(f.at_s, "gps_loss", "SIM_GPS1_ENABLE", lambda: 0.0))
                if end is not None:
                    actions.append(self._param(end, "gps_loss ends", "SIM_GPS1_ENABLE", lambda: 1.0))
            elif f.kind == "battery_drop":
                actions.append(self._param(f.at_s, "battery_drop", "SIM_BATT_VOLTAGE", self._failed_cell_v))
                if end is not None:
                    actions.append(self._param(end, "battery_drop ends", "SIM_BATT_VOLTAGE", self._full_v))
            elif f.kind == "rc_loss":
                actions.append(self._param(f.at_s, "rc_loss", "SIM_RC_FAIL", lambda: 1.0))
                if end is not None:
                    actions.append(self._param(end, "rc_loss ends", "SIM_RC_FAIL", lambda: 0.0))
            elif f.kind != "link_loss":
                raise ValueError(f"fault kind {f.kind!r} cannot be injected into ArduCopter")
        for ev in events:
            number = GCS_MODES[ev.mode]
            actions.append(self._command(ev.at_s, f"ground station: {ev.mode}", mavlink2.MAV_CMD_DO_SET_MODE,
                                         mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, number))
        return actions

    def _command(self, at_s: float, what: str, command: int, p1: float, p2: float) -> _Action:
        def build() -> tuple[object, str]:
            return self._mav.command_long_encode(self.target_sysid, 1, command, 0, p1, p2, 0, 0, 0, 0, 0), what
        return _Action(at_s, what, build, ("ack", command))

    def _param(self, at_s: float, kind: str, name: str, value: Callable[[], float]) -> _Action:
        def build() -> tuple[object, str]:
            v = action.value = value()  # read when due: the battery's voltage comes from ArduCopter at connect
            msg = self._mav.param_set_encode(self.target_sysid, 1, _param_id(name), v, mavlink2.MAV_PARAM_TYPE_REAL32)
            return msg, f"{kind}: {name} {v:g}"
        action = _Action(at_s, f"{kind}: {name}", build, ("param", name))
        return action

    def _full_v(self) -> float:
        v = self.params.get("SIM_BATT_VOLTAGE")
        if v is None:
            raise FaultNotInjected("battery_drop: ArduCopter never reported SIM_BATT_VOLTAGE on the second link")
        return v

    def _failed_cell_v(self) -> float:
        full = self._full_v()
        cells = max(1, round(full / _VOLTS_PER_CELL))
        low = full - full / cells
        threshold = self.params.get("BATT_LOW_VOLT", math.nan)
        if not low < threshold:
            log.warning("battery_drop: %.2f V is not below BATT_LOW_VOLT %s: no low-battery failsafe will follow",
                        low, threshold)
        return low

    # -- the link -------------------------------------------------------------------------------------
    def _connect(self, t_s: float) -> bool:
        if self._sock is not None:
            return True
        if self._first_try_s is None:
            self._first_try_s = t_s
        try:
            sock = socket.create_connection(self.address, timeout=1.0)
        except OSError as exc:
            if t_s - self._first_try_s > _CONNECT_WAIT_S:
                raise FaultNotInjected(f"the second ground station could not connect to ArduCopter's SERIAL1 at "
                                       f"{self.address[0]}:{self.address[1]}: {exc}") from exc
            return False
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock = sock
        log.info("second ground station (system %d) on ArduCopter's SERIAL1 %s:%d", SECOND_GCS_SYSID, *self.address)
        # Read the battery's voltages now (battery_drop needs them). Any message also makes SERIAL1 an
        # active channel: ArduCopter sends its STATUSTEXTs only to channels it has heard from.
        for name in ("SIM_BATT_VOLTAGE", "BATT_LOW_VOLT"):
            self._send(self._mav.param_request_read_encode(self.target_sysid, 1, _param_id(name), -1))
        return True

    def _send(self, msg) -> None:  # noqa: ANN001 (a pymavlink message)
        assert self._sock is not None
        data = msg.pack(self._mav)
        try:
            self._sock.sendall(data)  # a few dozen bytes into an empty socket: never partial in practice
        except BlockingIOError as exc:
            raise FaultNotInjected(f"SERIAL1 would not take {msg.get_type()}") from exc

    def _drain(self) -> None:
        assert self._sock is not None
        while True:
            try:
                data = self._sock.recv(_RECV_CHUNK)
            except BlockingIOError:  # EAGAIN / EWOULDBLOCK: nothing more now
                return
            if not data:
                return
            for msg in self._mav.parse_buffer(data) or ():
                self._on_message(msg)

    def _on_message(self, msg) -> None:  # noqa: ANN001
        kind = msg.get_type()
        if kind == "STATUSTEXT":
            self.texts.append((round(self._now, 2), msg.text))
        elif kind == "PARAM_VALUE":
            name = msg.param_id.rstrip("\x00") if isinstance(msg.param_id, str) else msg.param_id.decode().rstrip("\x00")
            self.params[name] = float(msg.param_value)
            self._answered(("param", name), f"PARAM_VALUE {msg.param_value:g}", float(msg.param_value))
        elif kind == "COMMAND_ACK" and msg.target_system in (0, SECOND_GCS_SYSID):
            result = mavlink2.enums["MAV_RESULT"][msg.result].name.removeprefix("MAV_RESULT_") \
                if msg.result in mavlink2.enums["MAV_RESULT"] else str(msg.result)
            self._answered(("ack", msg.command), f"COMMAND_ACK {result}")
            if msg.result != mavlink2.MAV_RESULT_ACCEPTED:
                log.warning("ArduCopter refused the second ground station's command %d: %s", msg.command, result)

    def _answered(self, key: tuple[str, object], reply: str, value: float | None = None) -> None:
        for action in self._waiting:
            if action.value is not None and (value is None or abs(value - action.value) > 1e-4 * max(1.0, abs(value))):
                continue  # a parameter read back with another value: not this set's answer
            if action.expect == key and action.record is not None and action.record.reply is None:
                action.record.reply = reply
                log.info("t=%.2f s %s -> %s", action.at_s, action.what, reply)
                self._waiting.remove(action)
                return

    # -- stepping -------------------------------------------------------------------------------------
    def step(self, t_s: float) -> None:
        """Read ArduCopter's replies and send what is due at world time ``t_s``.

        Raises:
            FaultNotInjected: SERIAL1 never took the connection, or a fault's value could not be known.
        """
        self._now = t_s
        if not self._connect(t_s):
            return
        self._drain()
        while self._actions and self._actions[0].at_s <= t_s:
            action = self._actions.pop(0)
            msg, action.what = action.build()
            action.record = Injection(action.at_s, action.what)
            self.injections.append(action.record)
            self._send(msg)
            self._waiting.append(action)
            log.info("t=%.2f s second ground station: %s", t_s, action.what)
        for action in list(self._waiting):
            if t_s - action.at_s > _REPLY_WAIT_S:
                log.warning("t=%.2f s ArduCopter did not answer %r within %.0f s", t_s, action.what, _REPLY_WAIT_S)
                self._waiting.remove(action)

    def close(self) -> None:
        """Hang up the second ground station."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None


class LinkRelay:
    """The mission's radio: a relay between the mission's TCP link and ArduCopter's SERIAL0, in this process.

    The mission connects to :attr:`url` instead of SERIAL0; :meth:`pump` moves the bytes waiting on
    either side to the other, or drops them while ``up`` is False (a ``link_loss``: as the built-in
    simulator's radio, nothing gets through either way, and what was sent meanwhile is lost).
    Pumped before ArduCopter's physics frames (the mission's commands of the last tick reach it
    before its next step) and after them (its telemetry reaches the mission's next poll), it adds
    no delay to a lock-step rehearsal.
    """

    def __init__(self, upstream: tuple[str, int]) -> None:
        self.upstream = upstream
        self._listen = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listen.bind(("127.0.0.1", 0))
        self._listen.listen(1)
        self._listen.setblocking(False)
        self._up: socket.socket | None = None
        self._down: socket.socket | None = None
        self._out: dict[str, bytearray] = {"up": bytearray(), "down": bytearray()}
        self.dropped_bytes = 0

    @property
    def url(self) -> str:
        """The connection string the mission opens instead of SERIAL0's."""
        return f"tcp:127.0.0.1:{self._listen.getsockname()[1]}"

    def pump(self, up: bool) -> None:
        """Move (``up``) or drop (not ``up``) every byte waiting on either side."""
        if self._down is None:
            try:
                self._down, _ = self._listen.accept()
                self._down.setblocking(False)
                self._down.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            except BlockingIOError:
                pass
        if self._up is None:
            try:  # SERIAL0 listens from before ArduCopter's first physics frame
                self._up = socket.create_connection(self.upstream, timeout=1.0)
                self._up.setblocking(False)
                self._up.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            except OSError:
                self._up = None
        self._move(self._down, self._up, "up", up)
        self._move(self._up, self._down, "down", up)

    def _move(self, src: socket.socket | None, dst: socket.socket | None, key: str, up: bool) -> None:
        out = self._out[key]
        if src is not None:
            while True:
                try:
                    data = src.recv(_RECV_CHUNK)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:
                    data = b""
                if not data:
                    break
                if up:
                    out += data
                else:
                    self.dropped_bytes += len(data)
        if not up:
            self.dropped_bytes += len(out)
            out.clear()
            return
        if dst is None or not out:
            return
        try:
            sent = dst.send(out)
        except (BlockingIOError, InterruptedError):
            sent = 0
        except OSError:
            sent = len(out)  # the peer went away: nobody to deliver to
        del out[:sent]
        if len(out) > _MAX_PENDING:  # a reader that stopped reading (the mission has ended): a full radio drops
            self.dropped_bytes += len(out) - _MAX_PENDING
            del out[: len(out) - _MAX_PENDING]

    def close(self) -> None:
        """Close both sides and the listening socket."""
        for sock in (self._down, self._up, self._listen):
            if sock is not None:
                sock.close()
        self._down = self._up = None
