"""RTL and Land: hand the aircraft to ArduCopter's own return and landing, and wait for touchdown.

Both succeed only for a flight that happened: a vehicle disarmed on the ground when the leaf
starts has nothing to return from, and "landed and disarmed" would report a flight that never
flew (a tree whose take-off failed, ticked into its RTL, must not end in SUCCESS). They fail then,
without commanding anything. And "landed" means a touchdown seen before the disarm
(:class:`~chaser_bt.vehicle.touchdown.TouchdownJudge`): an aircraft disarmed in the air fails the
leaf as a crash, never "landed". A return or descent that gets no nearer the ground at home for
``stall_s`` fails too, with what the autopilot said, instead of waiting for ever.
"""

from __future__ import annotations

import abc

import numpy as np
import py_trees

from behaviours.base import CommandingBehaviour, stall_message, state_port
from chaser_bt.control.progress import ProgressWatch
from chaser_bt.tree import input_port, register_behaviour
from chaser_bt.vehicle import Command, VehicleState
from chaser_bt.vehicle.touchdown import Touchdown, TouchdownJudge

Status = py_trees.common.Status


class _AutopilotLanding(CommandingBehaviour):
    """Request a landing mode once; SUCCESS on acceptance, or once landed and disarmed; FAILURE at
    once when the vehicle was disarmed on the ground to begin with, and when it is disarmed in the air."""

    MODE = ""
    # RTL and LAND are already the safe end state: halting them must not replace them with a hover.
    HOVER_ON_HALT = False

    INPUT_PORTS = {
        "wait_landed": input_port(bool, "Stay RUNNING until landed and disarmed", default=True),
        "stall_s": input_port(float, "Fail after this long without coming 2 m nearer home's ground (s; 0 = never)",
                              default=60.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    @abc.abstractmethod
    def _request(self) -> Command:
        """Send this leaf's one link command."""

    def initialise(self) -> None:
        self._touchdown = TouchdownJudge()
        self._progress = ProgressWatch(window_s=self.get_input("stall_s"))
        self._command: Command | None = self._request() if self.state.armed else None

    def update(self) -> Status:
        state = self.state
        verdict = self._touchdown.observe(self._now(), state)
        if self._command is None:
            self.feedback_message = f"disarmed on the ground: no flight to end with {self.MODE}"
            return Status.FAILURE
        if verdict is Touchdown.CRASHED:
            self.feedback_message = self._touchdown.detail
            return Status.FAILURE
        if not self._command.done:
            self.feedback_message = f"requesting {self.MODE}"
            return Status.RUNNING
        if not self._command.ok:
            self.feedback_message = f"{self.MODE} refused: {self._command.reason or self._command.status.name}"
            return Status.FAILURE
        if not self.get_input("wait_landed"):
            self.feedback_message = f"in {self.MODE}"
            return Status.SUCCESS
        if verdict is Touchdown.LANDED:
            self.feedback_message = self._touchdown.detail
            return Status.SUCCESS
        if state.mode != self.MODE:
            self.feedback_message = f"left {self.MODE} for {state.mode} before landing"
            return Status.FAILURE
        to_go = self._to_go(state)
        self._progress.observe(self._now(), to_go)
        if self._progress.stalled(self._now()):
            self.feedback_message = stall_message(self._progress, self._now(), to_go, state)
            return Status.FAILURE
        self.feedback_message = f"{self.MODE}: {state.alt_rel_m:.1f} m above home"
        return Status.RUNNING

    def _to_go(self, state: VehicleState) -> float:
        """Distance left to the ground at home: the way down, and for RTL the way back."""
        return float(state.alt_rel_m)


@register_behaviour
class RTL(_AutopilotLanding):
    """Return to launch (ArduCopter RTL: climb to RTL_ALT, fly home, land, disarm)."""

    MODE = "RTL"

    def _request(self) -> Command:
        return self._link().rtl()

    def _to_go(self, state: VehicleState) -> float:
        frame, home = self._link().frame, state.home
        if frame is None or home is None:
            return float(state.alt_rel_m)
        east, north, _ = frame.point_to_enu(home)
        pos = state.position_enu
        return float(np.hypot(np.hypot(pos[0] - east, pos[1] - north), state.alt_rel_m))


@register_behaviour
class Land(_AutopilotLanding):
    """Land where the aircraft is (ArduCopter LAND) and wait for the disarm."""

    MODE = "LAND"

    def _request(self) -> Command:
        return self._link().land()
