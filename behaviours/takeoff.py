"""ArmAndTakeoff: GUIDED, arm, take off, and succeed once the target altitude is reached."""

from __future__ import annotations

import enum

import numpy as np
import py_trees

from behaviours.base import CommandingBehaviour, state_port
from chaser_bt.tree import input_port, register_behaviour
from chaser_bt.vehicle import Command

Status = py_trees.common.Status


class _Phase(enum.Enum):
    GUIDED = "switching to GUIDED"
    ARM = "arming"
    TAKEOFF = "taking off"
    CLIMB = "climbing"


@register_behaviour
class ArmAndTakeoff(CommandingBehaviour):
    """Arm in GUIDED and climb to ``altitude_m`` above home; SUCCESS within ``tolerance_m`` of it.

    Each step is one non-blocking link command; the link itself waits (bounded) for the vehicle's
    pre-arm readiness before arming (DESIGN §5). Already airborne (a vehicle joined in flight): GUIDED
    if it is not in it, then straight to the altitude with a position target over where it is, once
    its position is known, since ArduCopter refuses a takeoff command in flight. Once in GUIDED,
    a change to any other mode (a failsafe RTL, the pilot's switch) fails it at once: the climb
    is no longer ours to report.
    """

    INPUT_PORTS = {
        "altitude_m": input_port(float, "Take-off altitude above home (m)", default=20.0, above=0,
                                 maximum=500),  # the command envelope's ceiling
        "tolerance_m": input_port(float, "Altitude counted as reached within this (m)", default=1.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._command: Command | None = None
        self._guided = self.state.mode == "GUIDED"  # from here on, leaving GUIDED fails the take-off
        self._joined, self._climb_sent = self.state.airborne, False  # joined in flight: climb by a target
        if self._joined and self._guided:
            self._phase = _Phase.CLIMB
        else:  # on the ground, or joined in flight in another mode (LOITER, a hover left by a previous run)
            self._phase = _Phase.GUIDED
            self._command = self._link().set_mode("GUIDED")

    def update(self) -> Status:
        mode = self.state.mode
        if self._guided and mode != "GUIDED":
            self.feedback_message = f"{self._phase.value}: mode taken away ({mode or 'unknown'})"
            return Status.FAILURE
        if self._phase is not _Phase.CLIMB:
            status = self._advance()
            if status is not None:
                return status
        return self._climb()

    def _advance(self) -> Status | None:
        """Move through GUIDED -> ARM -> TAKEOFF as each command is accepted; None once climbing."""
        assert self._command is not None
        if not self._command.done:
            self.feedback_message = f"{self._phase.value}: {self._command.status.name.lower()}"
            return Status.RUNNING
        if not self._command.ok:
            self.feedback_message = f"{self._phase.value} failed: {self._command.reason or self._command.status.name}"
            return Status.FAILURE
        self._phase = _Phase.CLIMB if self._phase is _Phase.GUIDED and self.state.airborne else _NEXT[self._phase]
        self._guided = True  # GUIDED was accepted and shows in the heartbeat
        link = self._link()
        if self._phase is _Phase.ARM:
            self._command = link.arm()
        elif self._phase is _Phase.TAKEOFF:
            self._command = link.takeoff(self.get_input("altitude_m"))
        else:
            return None
        self.feedback_message = self._phase.value
        return Status.RUNNING

    def _climb(self) -> Status:
        state, altitude = self.state, self.get_input("altitude_m")
        if not state.armed:
            self.feedback_message = "disarmed during the climb"
            return Status.FAILURE
        if self._joined and not self._climb_sent:
            pos = state.position_enu
            if not np.all(np.isfinite(pos[:2])):
                self.feedback_message = "airborne: waiting for the vehicle's position in the mission frame"
                return Status.RUNNING
            self._link().goto_enu([pos[0], pos[1], altitude])
            self._climb_sent = True
        if state.alt_rel_m >= altitude - self.get_input("tolerance_m"):
            self.feedback_message = f"at {state.alt_rel_m:.1f} m"
            return Status.SUCCESS
        self.feedback_message = f"climbing: {state.alt_rel_m:.1f} / {altitude:.1f} m"
        return Status.RUNNING


_NEXT = {_Phase.GUIDED: _Phase.ARM, _Phase.ARM: _Phase.TAKEOFF, _Phase.TAKEOFF: _Phase.CLIMB}
