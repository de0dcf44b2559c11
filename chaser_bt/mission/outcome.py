"""How a flight ended, in the field's terms: one :class:`Outcome`, its cause, and the exit code.

The root's status says what the tree concluded; it cannot say what happened to the aircraft
behind its back. :class:`FlightWitness` watches the vehicle beside the tree (from telemetry only,
never a simulator's truth): every disarm (a landing or a fall, :class:`TouchdownJudge`), every
mode nobody in the mission asked for (:class:`ModeAuthority`: the pilot, a ground station, a
failsafe), and the autopilot's failsafe texts. :func:`judge` joins them with the run's status and
the tree's ``/mission/phase`` (the shipped trees' guards write ``safety:<why>`` there) into a
:class:`Verdict`. Only ``completed`` exits 0.
"""

from __future__ import annotations

import enum
import logging
import re
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

from chaser_bt.vehicle.mode_authority import ForeignModeChange, ModeAuthority
from chaser_bt.vehicle.state import VehicleState, statustext_str
from chaser_bt.vehicle.touchdown import Touchdown, TouchdownJudge

__all__ = ["EXIT_CODES", "FlightWitness", "Outcome", "PHASE_KEY", "Verdict", "judge"]

log = logging.getLogger(__name__)

#: Where trees name what the aircraft is doing; a guard's branch writes ``safety:<why>``.
PHASE_KEY = "/mission/phase"

#: ArduCopter's texts that mean it acted on its own (failsafes, fence, EKF, crash check, thrust loss).
_AUTOPILOT_TEXT = re.compile(r"failsafe(?! cleared)|fence breach|battery \d+ is (low|critical)|crash|thrust loss|ekf variance",
                             re.IGNORECASE)
#: How long before a mode change an autopilot text still explains it (s).
_TEXT_EXPLAINS_S = 5.0


class Outcome(enum.Enum):
    """How a run ended. Values are what the CLI and reports print."""

    COMPLETED = "completed"  # the tree succeeded the way it meant to
    RETURNED_EARLY = "returned early"  # a guard of the tree (battery, geofence) cut it short
    FAILED = "failed"  # the tree failed (a leaf's cause)
    AUTOPILOT_ABORT = "aborted by the autopilot"  # its failsafe, fence or EKF took the mode
    PILOT_TOOK_OVER = "taken over"  # the pilot or a ground station took the mode or the switch
    CRASHED = "crashed"  # disarmed in the air
    LINK_LOST = "link lost"
    INTERRUPTED = "interrupted"  # Ctrl-C, SIGTERM, a time limit
    ERROR = "error"  # a leaf raised, or the link failed otherwise


#: Exit code of ``chaser-bt run`` per outcome (2 stays "bad input", as for every command).
EXIT_CODES: dict[Outcome, int] = {
    Outcome.COMPLETED: 0,
    Outcome.FAILED: 1,
    Outcome.RETURNED_EARLY: 3,
    Outcome.AUTOPILOT_ABORT: 4,
    Outcome.PILOT_TOOK_OVER: 5,
    Outcome.CRASHED: 6,
    Outcome.LINK_LOST: 7,
    Outcome.ERROR: 8,
    Outcome.INTERRUPTED: 130,
}


@dataclass(frozen=True)
class Verdict:
    """An outcome and its cause in words; ``notes`` are the autopilot's warnings that changed nothing."""

    outcome: Outcome
    cause: str
    notes: tuple[str, ...] = ()

    @property
    def exit_code(self) -> int:
        return EXIT_CODES[self.outcome]

    def line(self) -> str:
        """One line for a person: ``crashed: disarmed in the air at 19.5 m above home``."""
        text = f"{self.outcome.value}: {self.cause or '-'}"
        return text + (f" (autopilot: {'; '.join(self.notes)})" if self.notes else "")


@dataclass
class FlightWitness:
    """What the vehicle did beside the tree, from telemetry: disarms, foreign modes, autopilot texts.

    ``observe(t, state)`` every tick; attach it to the link with :meth:`attach` to hear modes and texts.
    """

    touchdown: TouchdownJudge = field(default_factory=TouchdownJudge)
    authority: ModeAuthority | None = None
    texts: deque[tuple[float, str]] = field(default_factory=lambda: deque(maxlen=100))  # the autopilot's failsafe-like texts
    crash: str = ""  # the first disarm in the air, in words
    untrusted: str = ""  # the first telemetry fault seen (a flood of absurd values, a second sender)
    _clock: Callable[[], float] | None = field(default=None, repr=False)
    _vehicle_sysid: Callable[[], int | None] = field(default=lambda: None, repr=False)

    @classmethod
    def attach(cls, link: Any, clock: Callable[[], float]) -> FlightWitness:
        witness = cls(authority=ModeAuthority.attach(link, clock), _clock=clock, _vehicle_sysid=lambda: link.target_sysid)
        link.add_listener(on_receive=witness._on_receive)
        return witness

    def observe(self, t: float, state: VehicleState) -> None:
        self.untrusted = self.untrusted or state.telemetry_fault
        if self.touchdown.observe(t, state) is Touchdown.CRASHED and not self.crash:
            self.crash = self.touchdown.detail

    def foreign_change(self) -> ForeignModeChange | None:
        """The first mode change in flight that the mission did not ask for."""
        if self.authority is None:
            return None
        return next((c for c in self.authority.foreign if c.armed), None)

    def autopilot_reason(self, change: ForeignModeChange) -> str:
        """The autopilot's own text that explains ``change`` ("" when none did: a person chose it)."""
        for t, text in reversed(self.texts):
            if change.t - _TEXT_EXPLAINS_S <= t <= change.t + 0.5:
                return text
        return change.why if _AUTOPILOT_TEXT.search(change.why or "") else ""

    def _on_receive(self, msg: Any) -> None:
        try:
            if msg.get_type() == "STATUSTEXT" and self._clock is not None and msg.get_srcSystem() == self._vehicle_sysid():
                text = statustext_str(msg)
                if _AUTOPILOT_TEXT.search(text):
                    self.texts.append((float(self._clock()), text))
        except Exception:  # a listener must not raise into the link
            log.debug("could not read a received message", exc_info=True)


def judge(status: str, message: str, witness: FlightWitness, phase: str | None = None, *, link_lost: bool = False) -> Verdict:
    """The outcome of a run whose runner ended in ``status`` ("success", "failure", "interrupted",
    "error") with ``message``; ``phase`` is the tree's last ``/mission/phase``; ``link_lost`` says the
    link went quiet. Precedence: telemetry that cannot be trusted (then nothing it said is, a
    "crash" included), a crash, an interruption, the link, an error, someone else's mode, the
    tree's guards, the tree's own status."""
    notes = tuple(dict.fromkeys(text for _, text in witness.texts))
    phase = phase if isinstance(phase, str) else ""
    if witness.untrusted:
        return Verdict(Outcome.ERROR, f"the vehicle's telemetry cannot be trusted ({witness.untrusted}); the tree "
                                      f"ended with: {message}", notes)
    if witness.crash:
        return Verdict(Outcome.CRASHED, witness.crash, notes)
    if status == "interrupted":
        return Verdict(Outcome.INTERRUPTED, message, notes)
    if link_lost or phase == "safety:link_lost":
        return Verdict(Outcome.LINK_LOST, message if link_lost else f"the tree's link-loss guard: {message}", notes)
    if status == "error":
        return Verdict(Outcome.ERROR, message, notes)
    change = witness.foreign_change()
    if change is not None:
        reason = witness.autopilot_reason(change)
        what = f"{change.previous} -> {change.mode} at {change.t:.1f} s"
        if reason:
            return Verdict(Outcome.AUTOPILOT_ABORT, f"{what}: {reason}", notes)
        return Verdict(Outcome.PILOT_TOOK_OVER, f"{what} (a pilot or ground station)", notes)
    if phase == "safety:pilot_gate":
        return Verdict(Outcome.PILOT_TOOK_OVER, f"the pilot's autonomy switch: {message}", notes)
    if status == "failure":
        return Verdict(Outcome.FAILED, message, notes)
    if phase.startswith("safety:"):
        return Verdict(Outcome.RETURNED_EARLY, f"{phase.removeprefix('safety:')} guard: {message}", notes)
    return Verdict(Outcome.COMPLETED, message, notes)
