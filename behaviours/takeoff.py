"""ArmAndTakeoff: GUIDED, arm, take off, and succeed once the target altitude is reached; with a cue to
fly towards, the climb turns towards it once clear of the ground (paper state 2)."""

from __future__ import annotations

import enum
import math

import numpy as np
import py_trees

from behaviours.base import CommandingBehaviour, optional_input, state_port
from chaser_bt.control.cue_approach import approach_point
from chaser_bt.cue import TargetCue
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
    pre-arm readiness before arming (DESIGN §5). Already airborne: climbs straight to the altitude
    with a position target, since ArduCopter refuses a takeoff command in flight. Once in GUIDED,
    a change to any other mode (a failsafe RTL, the pilot's switch) fails it at once: the climb
    is no longer ours to report.

    With ``toward`` set (a radar cue, say), the climb does not stay over the take-off point: once
    airborne and ``clearance_m`` up, while the cue is fresh, it flies GUIDED velocity set-points,
    up at ``climb_mps`` and across at up to ``speed_mps`` towards the point ``standoff_m`` short of
    the cue, nose on it (paper 2.2.1: in state 2 "the information from the radar can update the
    latitude and longitude to fly towards"). Velocity, not a position goal: ArduCopter takes a GUIDED
    position target along a straight 3D line (AC_PosControl::input_pos_xyz), which on a 300 m leg
    would climb at 1 m/s. A cue gone stale: climb where it is.
    """

    INPUT_PORTS = {
        "altitude_m": input_port(float, "Take-off altitude above home (m)", default=20.0, above=0),
        "tolerance_m": input_port(float, "Altitude counted as reached within this (m)", default=1.0, minimum=0),
        "toward": input_port(TargetCue, "Climb towards this cue once clear of the ground (unset: straight up)",
                             required=False),
        "clearance_m": input_port(float, "Height above home before the climb turns towards the cue (m)",
                                  default=10.0, minimum=0),
        "standoff_m": input_port(float, "Head for the point this far short of the cue, horizontally (m)",
                                 default=20.0, minimum=0),
        "max_cue_age_s": input_port(float, "An older cue is not flown towards (s)", default=2.0, minimum=0),
        "speed_mps": input_port(float, "Horizontal speed towards the cue (m/s)", default=10.0, above=0),
        "climb_mps": input_port(float, "Climb rate while flying towards the cue (m/s; the autopilot's "
                                       "WPNAV_SPEED_UP, ArduCopter's default 2.5)", default=2.5, above=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._command: Command | None = None
        self._steering = False  # flying velocity set-points towards the cue
        self._guided = self.state.mode == "GUIDED"  # from here on, leaving GUIDED fails the take-off
        if self.state.airborne:
            self._phase = _Phase.CLIMB
            pos = self.state.position_enu
            self._link().goto_enu([pos[0], pos[1], self.get_input("altitude_m")])
        else:
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
        self._phase = _NEXT[self._phase]
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
        if state.alt_rel_m >= altitude - self.get_input("tolerance_m"):
            self.feedback_message = f"at {state.alt_rel_m:.1f} m"
            return Status.SUCCESS
        self.feedback_message = f"climbing: {state.alt_rel_m:.1f} / {altitude:.1f} m{self._steer(altitude)}"
        return Status.RUNNING

    def _steer(self, altitude: float) -> str:
        """Send the climb towards the cue (see the class docstring); the feedback's tail."""
        state, cue = self.state, optional_input(self, "toward")
        if cue is None or not state.airborne or state.alt_rel_m < self.get_input("clearance_m"):
            return ""
        climb = min(self.get_input("climb_mps"), max(altitude - state.alt_rel_m, 0.5))
        if cue.age(self._now()) > self.get_input("max_cue_age_s"):
            if not self._steering:  # never turned: the take-off's own climb goes on
                return ""
            self._link().velocity_enu([0.0, 0.0, climb])
            return ", cue lost: straight up"
        self._steering = True
        plan = approach_point(state.position_enu, cue.position_enu, standoff_m=self.get_input("standoff_m"),
                              min_alt_m=altitude, height_above_m=-math.inf)
        across = plan.goal_enu[:2] - state.position_enu[:2]
        dist = float(np.hypot(*across))
        speed = min(self.get_input("speed_mps"), 0.5 * dist)  # slow down over the last 2 s
        v = across * (speed / dist) if dist > 1e-6 else np.zeros(2)
        self._link().velocity_enu([v[0], v[1], climb], yaw_enu_rad=plan.yaw_enu_rad)
        return f", {dist:.0f} m to the cue's standoff point"


_NEXT = {_Phase.GUIDED: _Phase.ARM, _Phase.ARM: _Phase.TAKEOFF, _Phase.TAKEOFF: _Phase.CLIMB}
