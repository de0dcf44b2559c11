"""BehaviorTree.CPP's standard nodes, as the registry knows them: control nodes, decorators, utility leaves.

Names, ports and semantics follow BT.CPP v4 so trees read the same in Groot2 (DESIGN §4). The
control nodes live in :mod:`chaser_bt.tree.composites`, the decorators in
:mod:`chaser_bt.tree.decorators`; the few utility leaves are here. Everything timed reads the
Clock handed to ``setup(clock=...)``, never the wall clock, so a tree behaves alike at 1x and at
simulator speed-up (DESIGN §3).
"""

from __future__ import annotations

from typing import Any, ClassVar

import py_trees
from py_trees.common import Status

from chaser_bt.clock import Clock
from chaser_bt.tree import composites as _composites
from chaser_bt.tree.composites import (
    AsyncFallback,
    AsyncSequence,
    Fallback,
    IfThenElse,
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
    LoopBool,
    LoopDouble,
    LoopInt,
    LoopString,
    Precondition,
    Repeat,
    RetryUntilSuccessful,
    RunOnce,
    SkipUnlessUpdated,
    SubTree,
    Timeout,
    WaitValueUpdate,
)
from chaser_bt.tree.entry_versions import entry_version
from chaser_bt.tree.expressions import truth
from chaser_bt.tree.node_base import ControlPorts as _ControlPorts
from chaser_bt.tree.node_base import PortCheck, now, require_clock
from chaser_bt.tree.node_kind import NodeKind
from chaser_bt.tree.ports import BtcppInputs, Port, input_port

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
    "UnsetBlackboard",
    "Script",
    "ScriptCondition",
    "Sleep",
    "WasEntryUpdated",
    "SkipUnlessUpdated",
    "WaitValueUpdate",
    "CONTROL_NODES",
    "PortCheck",
]


# ------------------------------------------------------------------- control nodes with typed ports


def _converting(cls: type) -> type:
    """``cls`` whose ports convert a blackboard value as BT.CPP's ``getInput`` does (:class:`BtcppInputs`):
    a Parallel's ``success_count`` from a Script's ``2.0`` or ``'2'`` is 2, as in BT.CPP."""
    namespace = {"__doc__": cls.__doc__, "__module__": cls.__module__, "__qualname__": cls.__qualname__}
    return type(cls.__name__, (BtcppInputs, cls), namespace, register=False)


Parallel = _converting(_composites.Parallel)
ParallelAll = _converting(_composites.ParallelAll)
TryCatch = _converting(_composites.TryCatch)
SWITCHES: tuple[type, ...] = tuple(_converting(switch) for switch in _composites.SWITCHES)


# ---------------------------------------------------------------------------------------- leaves


class AlwaysSuccess(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP AlwaysSuccess."""

    def update(self) -> Status:
        return Status.SUCCESS


class AlwaysFailure(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP AlwaysFailure."""

    def update(self) -> Status:
        return Status.FAILURE


#: The longest Wait a tree may ask for (s): a day, as Hover's longest hold (past it, a typo).
MAX_WAIT_S = 86_400


class Wait(BtcppInputs, _ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """RUNNING until ``duration_s`` have passed on the mission clock, then SUCCESS (BT.CPP Sleep, in seconds)."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "duration_s": input_port(float, "seconds to wait", minimum=0, maximum=MAX_WAIT_S),
    }
    DURATION_PORT: ClassVar[str] = "duration_s"
    UNITS_PER_SECOND: ClassVar[float] = 1.0

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self._clock: Clock | None = None
        self._start = 0.0

    def setup(self, **kwargs: Any) -> None:
        self._clock = require_clock(self, kwargs)

    def initialise(self) -> None:
        self._start = now(self, self._clock)

    def update(self) -> Status:
        elapsed = now(self, self._clock) - self._start
        duration = self.get_input(self.DURATION_PORT)
        self.feedback_message = f"{elapsed:.1f}/{duration / self.UNITS_PER_SECOND:.1f} s"
        return Status.SUCCESS if elapsed * self.UNITS_PER_SECOND >= duration else Status.RUNNING


class SetBlackboard(BtcppInputs, _ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP SetBlackboard: writes ``value`` (a literal, or ``{key}`` to copy an entry) to the entry named by ``output_key``.

    As in BT.CPP, ``output_key`` is the entry's *name* (``output_key="x"``); the old chaser-bt
    form ``"{x}"`` loads with a warning.
    """

    KEY_NAME_PORTS: ClassVar[tuple[str, ...]] = ("output_key",)
    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "value": input_port(object, "value to write"),
    }
    OUTPUT_PORTS: ClassVar[dict[str, Port]] = {
        "output_key": Port(data_type=object, required=True, description="name of the blackboard entry to write"),
    }

    def update(self) -> Status:
        self._set_output("output_key", self.get_input("value"))
        return Status.SUCCESS


class UnsetBlackboard(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP UnsetBlackboard: removes the entry named by ``key``."""

    KEY_NAME_PORTS: ClassVar[tuple[str, ...]] = ("key",)
    INPUT_PORTS: ClassVar[dict[str, Port]] = {}
    OUTPUT_PORTS: ClassVar[dict[str, Port]] = {
        "key": Port(data_type=object, required=True, description="name of the blackboard entry to remove"),
    }

    def update(self) -> Status:
        py_trees.blackboard.Blackboard.unset(self._get_blackboard_key("key"))
        return Status.SUCCESS


class WasEntryUpdated(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP WasEntryUpdated: SUCCESS if the entry named by ``entry`` was written since this node last looked, else FAILURE."""

    KEY_NAME_PORTS: ClassVar[tuple[str, ...]] = ("entry",)
    BRACES_ARE_OLD_FORM: ClassVar[bool] = False
    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS: ClassVar[dict[str, Port]] = {}
    OUTPUT_PORTS: ClassVar[dict[str, Port]] = {
        "entry": Port(data_type=object, required=True, description="name of the blackboard entry to watch"),
    }

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self._seen = 0

    def update(self) -> Status:
        version = entry_version(self._get_blackboard_key("entry"))
        if version is None:
            return Status.FAILURE
        previous, self._seen = self._seen, version
        return Status.SUCCESS if version != previous else Status.FAILURE


class Script(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP Script: runs the script in ``code`` (assignments to the blackboard); SUCCESS."""

    SCRIPT_PORTS: ClassVar[tuple[str, ...]] = ("code",)
    INPUT_PORTS: ClassVar[dict[str, Port]] = {"code": input_port(str, "the script to run")}

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self.scripts: dict[str, Any] = {}

    def update(self) -> Status:
        self.scripts["code"].run()
        return Status.SUCCESS


class ScriptCondition(Script, register=False):
    """BT.CPP ScriptCondition: SUCCESS when the script in ``code`` is true, else FAILURE."""

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS: ClassVar[dict[str, Port]] = {"code": input_port(str, "the script that must be true")}

    def update(self) -> Status:
        return Status.SUCCESS if truth(self.scripts["code"].run()) else Status.FAILURE


class Sleep(Wait, register=False):
    """BT.CPP Sleep: RUNNING until ``msec`` have passed on the mission clock, then SUCCESS (0: at once)."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "msec": input_port(int, "milliseconds to sleep", btcpp_type="unsigned", minimum=0, maximum=MAX_WAIT_S * 1000),
    }
    DURATION_PORT: ClassVar[str] = "msec"
    UNITS_PER_SECOND: ClassVar[float] = 1000.0


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
    AsyncSequence,
    AsyncFallback,
    ParallelAll,
    TryCatch,
    *SWITCHES,
    Precondition,
    LoopInt,
    LoopBool,
    LoopDouble,
    LoopString,
    Script,
    ScriptCondition,
    Sleep,
    UnsetBlackboard,
    WasEntryUpdated,
    SkipUnlessUpdated,
    WaitValueUpdate,
)
