"""Flying on a radar cue (paper section 2.2.1, state 3), and two small leaves the chase tree needs.

- :class:`CueFresh`: a target cue no older than ``max_age_s`` is on the blackboard (state 3 vs 4).
- :class:`FlyToCue`: GUIDED position targets to a standoff point short of the cue, at a safe
  altitude, facing it (:func:`chaser_bt.control.cue_approach.approach_point`), re-targeted as the
  cue moves (Nav2's follow-point pattern: a rate-limited goal update beside a long-running leaf).
- :class:`ClimbTowardsCue`: beside the take-off (paper state 2), once clear of the ground, GUIDED
  velocity up and towards the cue, so the climb closes on the target.
- :class:`SetMode`: ask for a flight mode and wait until the vehicle shows it.
"""

from __future__ import annotations

import math

import numpy as np
import py_trees

from behaviours.base import (CommandingBehaviour, FlightMode, VehicleBehaviour, optional_input, send_speed_after_target,
                             stall_message, state_port)
from chaser_bt.control.cue_approach import approach_point
from chaser_bt.control.progress import ClosingWatch
from chaser_bt.cue import TargetCue
from chaser_bt.tree import NodeKind, input_port, register_behaviour
from chaser_bt.vehicle import Command

Status = py_trees.common.Status

CUE_KEY = "/target/cue"


@register_behaviour
class CueFresh(VehicleBehaviour):
    """SUCCESS while the target cue is no older than ``max_age_s`` (mission time)."""

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS = {
        "cue": input_port(TargetCue, "The target cue", required=False, default_key=CUE_KEY),
        "max_age_s": input_port(float, "Older than this, the cue is lost (s)", default=2.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def update(self) -> Status:
        cue = optional_input(self, "cue")
        if cue is None:
            self.feedback_message = "no cue yet"
            return Status.FAILURE
        age = cue.age(self._now())
        self.feedback_message = f"cue {age:.1f} s old"
        return Status.SUCCESS if age <= self.get_input("max_age_s") else Status.FAILURE


@register_behaviour
class FlyToCue(CommandingBehaviour):
    """Fly in GUIDED towards the cue: ``standoff_m`` short of it, ``height_above_m`` over it (never
    below ``min_alt_m``), nose on it. RUNNING while the cue is fresh, re-sending the goal when it
    moves more than ``retarget_m`` or every ``resend_s``; FAILURE (and hover) when the cue is older
    than ``max_age_s``, the vehicle is not in GUIDED or is disarmed, or it flies no closer to the goal
    for ``stall_s`` (:class:`~chaser_bt.control.progress.ClosingWatch`: the autopilot refuses the
    target, a fence holds it).
    """

    INPUT_PORTS = {
        "cue": input_port(TargetCue, "The target cue", required=False, default_key=CUE_KEY),
        "standoff_m": input_port(float, "Stop this far short of the cue, horizontally (m)", default=30.0, minimum=0),
        "height_above_m": input_port(float, "Height of the goal above the cue (m)", default=25.0),
        "min_alt_m": input_port(float, "Never lower than this above home (m)", default=20.0, minimum=0),
        "max_age_s": input_port(float, "A cue older than this is lost (s)", default=2.0, minimum=0),
        "retarget_m": input_port(float, "Re-send the goal when it moved this far (m)", default=5.0, minimum=0),
        "resend_s": input_port(float, "Re-send the goal at least this often (s)", default=1.0, minimum=0),
        "speed_mps": input_port(float, "Horizontal speed (m/s); 0 keeps the vehicle's WPNAV_SPEED", default=0.0, minimum=0),
        "stall_s": input_port(float, "Fail after this long without flying 2 m towards the goal (s; 0 = never)",
                              default=30.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._sent_goal: np.ndarray | None = None
        self._sent_at = -math.inf
        self._progress = ClosingWatch(window_s=self.get_input("stall_s"))
        self._speed_sent = False

    def update(self) -> Status:
        state, now = self.state, self._now()
        if state.mode != "GUIDED":
            self.feedback_message = f"vehicle is in {state.mode or 'an unknown mode'}, not GUIDED"
            return Status.FAILURE
        if not state.armed:
            self.feedback_message = "vehicle disarmed"
            return Status.FAILURE
        cue: TargetCue | None = optional_input(self, "cue")
        if cue is None or cue.age(now) > self.get_input("max_age_s"):
            self.feedback_message = "cue lost" if cue is not None else "no cue"
            return Status.FAILURE
        plan = approach_point(state.position_enu, cue.position_enu, standoff_m=max(0.0, self.get_input("standoff_m")),
                              min_alt_m=self.get_input("min_alt_m"), height_above_m=self.get_input("height_above_m"))
        moved = math.inf if self._sent_goal is None else float(np.linalg.norm(plan.goal_enu - self._sent_goal))
        if moved > self.get_input("retarget_m") or now - self._sent_at >= self.get_input("resend_s"):
            self._link().goto_enu(plan.goal_enu, plan.yaw_enu_rad)
            self._sent_goal, self._sent_at = plan.goal_enu, now
            self._speed_sent = self._speed_sent or send_speed_after_target(self._link(), self.get_input("speed_mps"))
        self._progress.observe(now, state.position_enu, plan.goal_enu)
        if self._progress.stalled(now):
            self.feedback_message = stall_message(self._progress, now, plan.distance_m, state)
            return Status.FAILURE
        self.feedback_message = f"{plan.distance_m:.0f} m to the standoff point of cue {cue.track_id}"
        return Status.RUNNING


@register_behaviour
class ClimbTowardsCue(CommandingBehaviour):
    """Beside ArmAndTakeoff (a Parallel that ends with it): once airborne and ``clearance_m`` up, while
    the cue is fresh, GUIDED velocity set-points up at ``climb_mps`` and across at up to ``speed_mps``
    towards the point ``standoff_m`` short of the cue at ``altitude_m``, nose on it (paper 2.2.1: in
    state 2 "the information from the radar can update the latitude and longitude to fly towards").
    Velocity, not a position goal: ArduCopter flies a GUIDED position target on a straight 3D line
    (AC_PosControl::input_pos_xyz), which on a 300 m leg climbs at 1 m/s. A cue gone stale after it
    turned: straight up. Always RUNNING: the take-off beside it decides when the climb is over.
    Halted, it sends no hover of its own: the take-off beside it has either succeeded (the next
    state commands in the same tick), failed (and hovers itself) or been halted too (and hovers).
    """

    HOVER_ON_HALT = False

    INPUT_PORTS = {
        "cue": input_port(TargetCue, "The target cue", required=False, default_key=CUE_KEY),
        "altitude_m": input_port(float, "The take-off altitude above home (m): the climb slows near it", above=0),
        "clearance_m": input_port(float, "Height above home before the climb turns towards the cue (m)",
                                  default=10.0, minimum=0),
        "standoff_m": input_port(float, "Head for the point this far short of the cue, horizontally (m)",
                                 default=20.0, minimum=0),
        "max_age_s": input_port(float, "An older cue is not flown towards (s)", default=2.0, minimum=0),
        "speed_mps": input_port(float, "Horizontal speed towards the cue (m/s)", default=10.0, above=0),
        "climb_mps": input_port(float, "Climb rate (m/s; the autopilot's WPNAV_SPEED_UP, ArduCopter's default "
                                       "2.5)", default=2.5, above=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._steering = False  # velocity set-points sent towards the cue

    def update(self) -> Status:
        state, cue = self.state, optional_input(self, "cue")
        if cue is None or not state.airborne or state.alt_rel_m < self.get_input("clearance_m"):
            self.feedback_message = "waiting to clear the ground" if cue is not None else "no cue"
            return Status.RUNNING
        altitude = self.get_input("altitude_m")
        climb = min(self.get_input("climb_mps"), max(altitude - state.alt_rel_m, 0.5))
        if cue.age(self._now()) > self.get_input("max_age_s"):
            if self._steering:  # it had turned: stop closing, keep climbing
                self._link().velocity_enu([0.0, 0.0, climb])
            self.feedback_message = "cue lost: straight up"
            return Status.RUNNING
        self._steering = True
        plan = approach_point(state.position_enu, cue.position_enu, standoff_m=self.get_input("standoff_m"),
                              min_alt_m=altitude, height_above_m=-math.inf)
        across = plan.goal_enu[:2] - state.position_enu[:2]
        dist = float(np.hypot(*across))
        speed = min(self.get_input("speed_mps"), 0.5 * dist)  # slow down over the last 2 s
        v = across * (speed / dist) if dist > 1e-6 else np.zeros(2)
        self._link().velocity_enu([v[0], v[1], climb], yaw_enu_rad=plan.yaw_enu_rad)
        self.feedback_message = f"climbing at {climb:.1f} m/s, {dist:.0f} m to the cue's standoff point"
        return Status.RUNNING


@register_behaviour
class SetMode(VehicleBehaviour):
    """Ask for ``mode`` and SUCCESS once the vehicle shows it (at once if it already does); FAILURE if refused."""

    INPUT_PORTS = {
        "mode": input_port(FlightMode, "ArduCopter mode name"),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._command: Command = self._link().set_mode(self.get_input("mode").name)

    def update(self) -> Status:
        cmd = self._command
        if not cmd.done:
            self.feedback_message = f"{cmd.name}: {cmd.status.name.lower()}"
            return Status.RUNNING
        self.feedback_message = f"in {self.get_input('mode').name}" if cmd.ok else f"{cmd.name} refused: {cmd.reason}"
        return Status.SUCCESS if cmd.ok else Status.FAILURE
