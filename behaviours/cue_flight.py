"""Flying on a radar cue (paper section 2.2.1, state 3), and two small leaves the chase tree needs.

- :class:`CueFresh`: a target cue no older than ``max_age_s`` is on the blackboard (state 3 vs 4).
- :class:`FlyToCue`: GUIDED position targets to a standoff point short of the cue, at a safe
  altitude, facing it (:func:`chaser_bt.control.cue_approach.approach_point`), re-targeted as the
  cue moves (Nav2's follow-point pattern: a rate-limited goal update beside a long-running leaf).
- :class:`SetMode`: ask for a flight mode and wait until the vehicle shows it.
"""

from __future__ import annotations

import math

import numpy as np
import py_trees

from behaviours.base import CommandingBehaviour, FlightMode, VehicleBehaviour, optional_input, state_port
from chaser_bt.control.cue_approach import approach_point
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
    than ``max_age_s`` or the vehicle is not in GUIDED.
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
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._sent_goal: np.ndarray | None = None
        self._sent_at = -math.inf
        speed = self.get_input("speed_mps")
        if speed > 0:
            self._link().set_speed(speed)

    def update(self) -> Status:
        state, now = self.state, self._now()
        if state.mode != "GUIDED":
            self.feedback_message = f"vehicle is in {state.mode or 'an unknown mode'}, not GUIDED"
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
        self.feedback_message = f"{plan.distance_m:.0f} m to the standoff point of cue {cue.track_id}"
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
