"""Hover: hold the current position, for a while or until halted."""

from __future__ import annotations

import py_trees

from behaviours.base import CommandingBehaviour, state_port
from chaser_bt.tree import input_port, register_behaviour

Status = py_trees.common.Status

#: The longest hold a tree may ask for (s): a day, longer than any battery lasts (past it, a typo).
MAX_HOLD_S = 86_400


@register_behaviour
class Hover(CommandingBehaviour):
    """Send the hover command for the current mode, then stay RUNNING.

    SUCCESS after ``duration_s`` of mission time; with ``duration_s: 0`` it holds until halted,
    which makes it the natural last child of a fallback ("if nothing else applies, hold still").
    """

    INPUT_PORTS = {
        "duration_s": input_port(float, "Hold this long (s); 0 = until halted", default=0.0, minimum=0,
                                 maximum=MAX_HOLD_S),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._link().hover()
        self._started_s = self._now()

    def update(self) -> Status:
        duration = self.get_input("duration_s")
        held = self._now() - self._started_s
        if duration > 0 and held >= duration:
            self.feedback_message = f"held {held:.1f} s"
            return Status.SUCCESS
        self.feedback_message = f"hovering {held:.1f} s" + (f" / {duration:.1f} s" if duration > 0 else "")
        return Status.RUNNING
