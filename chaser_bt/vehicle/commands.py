"""Command handles and their life cycle: wait for a precondition, send, retry, ack, confirm.

MAVLink's command protocol (https://mavlink.io/en/services/command.html) is request/ack with
retries left to the sender; ArduPilot answers every COMMAND_LONG with a COMMAND_ACK, may send
MAV_RESULT_IN_PROGRESS before the final result, and explains a refusal in a STATUSTEXT that can
arrive just before or just after the ack. A :class:`Command` is the caller's handle; the
:class:`CommandTracker` moves it along, only when the link polls, so nothing here blocks or
reads a clock (``now`` is passed in).
"""

from __future__ import annotations

import enum
import logging
from collections import deque
from dataclasses import dataclass, field
from typing import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

__all__ = ["CommandStatus", "Command", "CommandTracker", "Setpoint", "result_name"]

log = logging.getLogger(__name__)

# A refusal's explanation is a STATUSTEXT at WARNING or worse ("PreArm: Need 3D Fix" is CRITICAL).
_REASON_SEVERITY = mavlink2.MAV_SEVERITY_WARNING


class CommandStatus(enum.Enum):
    """Where a command is in its life."""

    WAITING = "waiting"  # for a precondition (vehicle heard, ready to arm)
    SENT = "sent"  # on the wire, no final answer yet
    ACCEPTED = "accepted"
    FAILED = "failed"  # refused by the autopilot, or superseded
    TIMED_OUT = "timed_out"  # precondition never held, no answer, or effect never seen


def result_name(result: int) -> str:
    """MAV_RESULT number -> its name (``MAV_RESULT_FAILED``)."""
    entry = mavlink2.enums["MAV_RESULT"].get(result)
    return entry.name if entry is not None else f"MAV_RESULT {result}"


@dataclass(eq=False)
class Command:
    """Handle of one request to the vehicle; it progresses only inside ``VehicleLink.poll()``."""

    name: str
    status: CommandStatus = CommandStatus.WAITING
    result: int | None = None  # MAV_RESULT of the final ack, when there was one
    reason: str = ""  # why it failed: the autopilot's STATUSTEXT, the ack, or the timeout
    attempts: int = 0  # transmissions so far (1 + retries)

    @property
    def done(self) -> bool:
        """Finished, one way or the other."""
        return self.status in (CommandStatus.ACCEPTED, CommandStatus.FAILED, CommandStatus.TIMED_OUT)

    @property
    def ok(self) -> bool:
        """Finished and accepted."""
        return self.status is CommandStatus.ACCEPTED


@dataclass(frozen=True)
class Setpoint:
    """The last fire-and-forget set-point sent, for the recorder and for hover decisions.

    ``kind`` and ``values``: ``"position"`` (lat_deg, lon_deg, alt_rel_m, yaw_enu_rad or nan);
    ``"velocity"`` (east, north, up m/s, yaw_rate rad/s CCW or nan); ``"rc_override"`` (roll,
    pitch, throttle, yaw PWM; 65535 = left alone); ``"rc_release"`` ().
    """

    kind: str
    t_s: float  # link time (the injected monotonic) when it was sent
    values: tuple[float, ...] = ()


@dataclass(eq=False)
class _Pending:
    """A command in flight plus what the tracker needs to finish it."""

    cmd: Command
    key: tuple[str, object]  # ("cmd", MAV_CMD id) / ("param_set", name) / ("param_get", name)
    send: Callable[[int], None]  # send(attempt_index); attempt 0 is the first transmission
    blocker: Callable[[], str | None]  # None when it may be sent, else why not yet
    wait_until: float  # give up waiting for the precondition at this time
    confirm: Callable[[], bool] | None  # effect visible in telemetry (mode in HEARTBEAT, armed flag)
    matches: Callable[[float], bool] | None = None  # param echo check
    submitted: float = float("nan")
    first_sent: float = float("nan")
    deadline: float = float("nan")  # next retry / final timeout
    acked: bool = False
    acked_at: float = float("nan")
    beats_at_ack: int = 0  # the vehicle's heartbeats heard when the ack came
    echo_mismatch: str = ""
    failed_at: float = float("nan")
    texts: list[str] = field(default_factory=list)


class CommandTracker:
    """Drives every pending :class:`Command` through wait -> send -> (retry) -> answer -> confirm.

    A newer command with the same key (same MAV_CMD, or same parameter) supersedes an older one
    still in flight: its ack could not be told apart, and the newest intent is what should fly.
    """

    def __init__(self, *, ack_timeout_s: float, retries: int, confirm_timeout_s: float,
                 heartbeats: Callable[[], int] | None = None) -> None:
        """``heartbeats``: how many of the vehicle's HEARTBEATs have been heard so far. Given, an acked
        command is not called unconfirmed before two of them came after its ack (up to three times
        ``confirm_timeout_s``): on a noisy link a lost heartbeat is not the vehicle saying no."""
        self.ack_timeout_s = ack_timeout_s
        self.retries = retries
        self.confirm_timeout_s = confirm_timeout_s
        self._heartbeats = heartbeats
        self.retried = 0  # retransmissions, for diagnostics
        self._pending: list[_Pending] = []
        self._failed: list[_Pending] = []  # recently refused, still collecting their explanation
        self._texts: deque[tuple[float, int, str]] = deque(maxlen=20)

    def submit(
        self,
        cmd: Command,
        key: tuple[str, object],
        send: Callable[[int], None],
        now: float,
        *,
        blocker: Callable[[], str | None],
        wait_s: float,
        confirm: Callable[[], bool] | None = None,
        matches: Callable[[float], bool] | None = None,
    ) -> Command:
        """Track ``cmd``; it is sent at once if ``blocker()`` is None, else when it becomes None."""
        for p in [p for p in self._pending if p.key == key]:
            self._finish(p, CommandStatus.FAILED, f"superseded by a newer {cmd.name}", now)
        p = _Pending(cmd, key, send, blocker, now + wait_s, confirm, matches, submitted=now)
        self._pending.append(p)
        self._advance(p, now)
        return cmd

    def accept_now(self, cmd: Command) -> Command:
        """Finish ``cmd`` as accepted without sending anything (the vehicle is already there)."""
        cmd.status = CommandStatus.ACCEPTED
        return cmd

    def find(self, key: tuple[str, object]) -> Command | None:
        """The command in flight under ``key``, if any."""
        return next((p.cmd for p in self._pending if p.key == key), None)

    @property
    def in_flight(self) -> list[Command]:
        """Commands not yet done, oldest first."""
        return [p.cmd for p in self._pending]

    def tick(self, now: float) -> None:
        """Advance timers: precondition waits, retries, timeouts, confirmations."""
        for p in list(self._pending):
            self._advance(p, now)
        self._failed = [p for p in self._failed if now - p.failed_at <= self.ack_timeout_s]

    def on_ack(self, command_id: int, result: int, now: float) -> bool:
        """Apply a COMMAND_ACK to the oldest sent, unanswered command with that id."""
        for p in self._pending:
            if p.key == ("cmd", command_id) and p.cmd.status is CommandStatus.SENT and not p.acked:
                break
        else:
            return False
        if result == mavlink2.MAV_RESULT_IN_PROGRESS:
            p.deadline = now + self.ack_timeout_s  # still working: wait, do not resend
        elif result == mavlink2.MAV_RESULT_ACCEPTED:
            p.cmd.result = result
            p.acked, p.acked_at = True, now
            p.beats_at_ack = self._heartbeats() if self._heartbeats is not None else 0
            p.deadline = now + self.confirm_timeout_s
            self._advance(p, now)
        else:
            p.cmd.result = result
            self._finish(p, CommandStatus.FAILED, result_name(result), now)
        return True

    def on_param_value(self, name: str, value: float, now: float) -> None:
        """Apply a PARAM_VALUE: finishes reads of ``name``, and writes whose value it echoes."""
        for p in list(self._pending):
            if p.cmd.status is not CommandStatus.SENT:
                continue
            if p.key == ("param_get", name):
                self._finish(p, CommandStatus.ACCEPTED, "", now)
            elif p.key == ("param_set", name):
                if p.matches is not None and p.matches(value):
                    self._finish(p, CommandStatus.ACCEPTED, "", now)
                else:
                    p.echo_mismatch = f"vehicle reports {name} = {value:g}"

    def on_statustext(self, severity: int, text: str, now: float) -> None:
        """Remember autopilot explanations; attach late ones to commands just refused."""
        if severity > _REASON_SEVERITY:
            return
        self._texts.append((now, severity, text))
        for p in self._failed:
            p.texts.append(text)
            p.cmd.reason = self._reason(p, result_name(p.cmd.result) if p.cmd.result is not None else "")

    def _advance(self, p: _Pending, now: float) -> None:
        cmd = p.cmd
        if cmd.status is CommandStatus.WAITING:
            why = p.blocker()
            if why is None:
                p.first_sent = now
                self._transmit(p, now)
            elif now >= p.wait_until:
                self._finish(p, CommandStatus.TIMED_OUT, f"not sent: {why}", now)
            return
        if p.acked:
            if p.confirm is None or p.confirm():
                self._finish(p, CommandStatus.ACCEPTED, "", now)
            elif now >= p.deadline and not self._heartbeats_missing(p, now):
                self._finish(
                    p, CommandStatus.TIMED_OUT,
                    f"accepted, but telemetry did not show it within {self.confirm_timeout_s:g} s", now,
                )
            return
        if p.confirm is not None and p.confirm():  # the ack was lost, but telemetry shows the effect
            log.info("%s: no answer, but telemetry shows it done", cmd.name)
            self._finish(p, CommandStatus.ACCEPTED, "", now)
            return
        if now < p.deadline:
            return
        if cmd.attempts <= self.retries:
            self.retried += 1
            log.info("%s: no answer after %.1f s, resending (attempt %d)", cmd.name, self.ack_timeout_s, cmd.attempts + 1)
            self._transmit(p, now)
        elif p.echo_mismatch:
            self._finish(p, CommandStatus.FAILED, p.echo_mismatch, now)
        else:
            self._finish(p, CommandStatus.TIMED_OUT, f"no answer after {cmd.attempts} attempts", now)

    def _heartbeats_missing(self, p: _Pending, now: float) -> bool:
        """Fewer than two heartbeats since the ack, and still within three confirmation windows."""
        if self._heartbeats is None or now >= p.acked_at + 3 * self.confirm_timeout_s:
            return False
        return self._heartbeats() - p.beats_at_ack < 2

    def _transmit(self, p: _Pending, now: float) -> None:
        p.send(p.cmd.attempts)
        p.cmd.attempts += 1
        p.cmd.status = CommandStatus.SENT
        p.deadline = now + self.ack_timeout_s

    def _finish(self, p: _Pending, status: CommandStatus, why: str, now: float) -> None:
        self._pending.remove(p)
        was_waiting = p.cmd.status is CommandStatus.WAITING
        p.cmd.status = status
        if status is CommandStatus.ACCEPTED:
            return
        if status is CommandStatus.FAILED and p.cmd.result is not None:
            # The explanation may already be here (sent before the ack) or follow shortly.
            p.texts = [t for (t_rx, _, t) in self._texts if t_rx >= p.first_sent]
            p.failed_at = now
            self._failed.append(p)
        elif was_waiting:
            # e.g. "PreArm: Need 3D Fix", repeated by ArduPilot while it is not ready
            p.texts = [t for (t_rx, _, t) in self._texts if t_rx >= p.submitted][-1:]
        p.cmd.reason = self._reason(p, why)
        # A parameter read that nobody answers is a name this autopilot does not have (ArduCopter
        # renames some between versions; the caller asks for both): not a warning.
        level = logging.INFO if p.key[0] == "param_get" else logging.WARNING
        log.log(level, "%s %s: %s", p.cmd.name, status.value, p.cmd.reason)

    @staticmethod
    def _reason(p: _Pending, why: str) -> str:
        return "; ".join([why, *p.texts]) if why else "; ".join(p.texts)
