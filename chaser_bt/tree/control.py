"""BehaviorTree.CPP's standard nodes, as the registry knows them: control nodes, decorators, utility leaves.

Names, ports and semantics follow BT.CPP v4 so trees read the same in Groot2 (DESIGN §4). The
control nodes live in :mod:`chaser_bt.tree.composites`, the decorators in
:mod:`chaser_bt.tree.decorators`; the few utility leaves are here. Everything timed reads the
Clock handed to ``setup(clock=...)``, never the wall clock, so a tree behaves alike at 1x and at
simulator speed-up (DESIGN §3).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import py_trees
from py_trees.common import Status

from chaser_bt.clock import Clock
from chaser_bt.tree.composites import (
    Fallback,
    IfThenElse,
    Parallel,
    ReactiveFallback,
    ReactiveSequence,
    Sequence,
    SequenceWithMemory,
    WhileDoElse,
)
from chaser_bt.tree.decorators import (
    Delay,
    ForceFailure,
    ForceSuccess,
    Inverter,
    KeepRunningUntilFailure,
    Repeat,
    RetryUntilSuccessful,
    RunOnce,
    SubTree,
    Timeout,
)
from chaser_bt.tree.node_base import ControlPorts as _ControlPorts
from chaser_bt.tree.node_base import PortCheck, now, require_clock
from chaser_bt.tree.ports import Port, input_port

__all__ = [
    "Sequence",
    "SequenceWithMemory",
    "ReactiveSequence",
    "Fallback",
    "ReactiveFallback",
    "Parallel",
    "IfThenElse",
    "WhileDoElse",
    "Inverter",
    "ForceSuccess",
    "ForceFailure",
    "Repeat",
    "RetryUntilSuccessful",
    "Timeout",
    "Delay",
    "RunOnce",
    "KeepRunningUntilFailure",
    "SubTree",
    "AlwaysSuccess",
    "AlwaysFailure",
    "Wait",
    "SetBlackboard",
    "CONTROL_NODES",
    "PortCheck",
]


# ---------------------------------------------------------------------------------------- leaves


class AlwaysSuccess(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP AlwaysSuccess."""

    def update(self) -> Status:
        return Status.SUCCESS


class AlwaysFailure(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP AlwaysFailure."""

    def update(self) -> Status:
        return Status.FAILURE


class Wait(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """RUNNING until ``duration_s`` have passed on the mission clock, then SUCCESS (BT.CPP Sleep, in seconds)."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "duration_s": input_port(float, "seconds to wait"),
    }

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self._clock: Clock | None = None
        self._start = 0.0

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        value = values.get("duration_s")
        if isinstance(value, float) and not value >= 0.0:
            return [("duration_s", f"duration_s must be >= 0, got {value}")]
        return []

    def setup(self, **kwargs: Any) -> None:
        self._clock = require_clock(self, kwargs)

    def initialise(self) -> None:
        self._start = now(self, self._clock)

    def update(self) -> Status:
        elapsed = now(self, self._clock) - self._start
        duration = self.get_input("duration_s")
        self.feedback_message = f"{elapsed:.1f}/{duration:.1f} s"
        return Status.SUCCESS if elapsed >= duration else Status.RUNNING


class SetBlackboard(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP SetBlackboard: writes ``value`` to the entry wired to ``output_key``."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "value": input_port(object, "value to write"),
    }
    OUTPUT_PORTS: ClassVar[dict[str, Port]] = {
        "output_key": Port(data_type=object, required=True, description="blackboard entry to write, as {key}"),
    }

    def update(self) -> Status:
        self._set_output("output_key", self.get_input("value"))
        return Status.SUCCESS


#: Every built-in node, in the order a model export lists them.
CONTROL_NODES: tuple[type, ...] = (
    Sequence,
    SequenceWithMemory,
    ReactiveSequence,
    Fallback,
    ReactiveFallback,
    Parallel,
    IfThenElse,
    WhileDoElse,
    Inverter,
    ForceSuccess,
    ForceFailure,
    Repeat,
    RetryUntilSuccessful,
    Timeout,
    Delay,
    RunOnce,
    KeepRunningUntilFailure,
    AlwaysSuccess,
    AlwaysFailure,
    Wait,
    SetBlackboard,
)
