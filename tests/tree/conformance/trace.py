"""chaser-bt's side of the conformance suite: tick a conformance tree and write its trace.

The trace has the format the C++ harness (``harness/conformance_harness.cpp``) prints for
BehaviorTree.CPP 4.10: per root tick ``tick N STATUS``, then the events of the ``Scripted``
leaves in order (``  A S`` ticked and returned SUCCESS, ``  A halt`` halted while RUNNING), then
``bb key=value`` for every root blackboard entry the tree's header names. Lines starting with
``#`` (the harness's every status transition) are information and are not compared.
"""

from __future__ import annotations

import decimal
import enum
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import py_trees
from py_trees.common import Status

from chaser_bt.clock import ManualClock
from chaser_bt.tree import Registry, TreeError, input_port, load_tree, reset_blackboard
from chaser_bt.tree.ports import BtcppInputs

HERE = Path(__file__).parent
_RESULTS = {"S": Status.SUCCESS, "F": Status.FAILURE, "R": Status.RUNNING}
_NAMES = {Status.SUCCESS: "SUCCESS", Status.FAILURE: "FAILURE", Status.RUNNING: "RUNNING", Status.INVALID: "SKIPPED"}


@dataclass
class Config:
    ticks: int = 5
    period_ms: int = 0
    keys: list[str] = field(default_factory=list)


def read_config(text: str) -> Config:
    config = Config()
    header = re.search(r"<!--\s*conformance([^>]*)-->", text)
    if header:
        body = header.group(1)
        if m := re.search(r"ticks=(\d+)", body):
            config.ticks = int(m.group(1))
        if m := re.search(r"period_ms=(\d+)", body):
            config.period_ms = int(m.group(1))
        if m := re.search(r"bb=([A-Za-z0-9_@,/]+)", body):
            config.keys = [k for k in m.group(1).split(",") if k]
    return config


class Scripted(BtcppInputs, py_trees.ports.BehaviourWithPorts, register=False):
    """The harness's scripted leaf: tick k returns the k-th of ``results`` (the last repeats).

    As the harness's: ``results`` is read at the first tick (converted as BT.CPP's ``getInput``
    does), and anything but F or R is a SUCCESS.
    """

    INPUT_PORTS = {"results": input_port(str, "per-tick results: S, F or R", default="S")}
    OUTPUT_PORTS: dict = {}

    def setup(self, **kwargs: Any) -> None:
        self.events: list[str] = kwargs["events"]
        self.count = 0
        self.results: list[str] | None = None

    def update(self) -> Status:
        if self.results is None:
            try:
                text = self.get_input("results")
            except TypeError:  # the harness ignores a getInput that fails and keeps "S"
                text = "S"
            self.results = [r for r in text.split(",") if r] or ["S"]
        result = self.results[min(self.count, len(self.results) - 1)]
        self.count += 1
        self.events.append(f"{self.name} {result}")
        return _RESULTS.get(result, Status.SUCCESS)

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING:
            self.events.append(f"{self.name} halt")


def registry() -> Registry:
    registry = Registry.with_control_nodes()
    registry.register(Scripted)
    for value, name in enumerate(("RED", "GREEN", "BLUE"), 1):  # as the harness registers them
        registry.register_scripting_enum(name, value)
    return registry


def to_chars(value: float) -> str:
    """``std::to_chars(double)``: the shortest digits, fixed or scientific, whichever is shorter (fixed on a tie)."""
    if math.isnan(value):
        return "-nan" if math.copysign(1.0, value) < 0 else "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    sign, digits, exponent = decimal.Decimal(repr(value)).as_tuple()
    text = "".join(map(str, digits)).rstrip("0") or "0"
    exponent += len(digits) - len(text)  # value = text * 10**exponent
    point = len(text) + exponent  # digits before the decimal point
    if exponent >= 0:
        fixed = text + "0" * exponent
    elif point > 0:
        fixed = text[:point] + "." + text[point:]
    else:
        fixed = "0." + "0" * -point + text
    power = point - 1
    scientific = text[0] + ("." + text[1:] if len(text) > 1 else "") + f"e{'-' if power < 0 else '+'}{abs(power):02d}"
    if text == "0":
        fixed = scientific = "0"
    return ("-" if sign else "") + (fixed if len(fixed) <= len(scientific) else scientific)


def show(value: Any) -> str:
    """A blackboard value as the harness prints it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, enum.Enum):
        value = value.value
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return to_chars(value)
    if isinstance(value, str):
        return f"'{value}'"
    return f"<{type(value).__name__}>"


def _tick(tree, n: int, events: list[str], lines: list[str]) -> bool:
    """Tick the root once and append the tick's line and its events; False when it raised (BT.CPP
    throws; the trace only says that it did)."""
    try:
        tree.root.tick_once()
    except Exception:
        lines.append(f"tick {n} exception")
        lines.extend(f"  {e}" for e in events)
        return False
    lines.append(f"tick {n} {_NAMES[tree.root.status]}")
    lines.extend(f"  {e}" for e in events)
    events.clear()
    return True


def chaser_trace(path: Path) -> list[str]:
    """Tick the tree in ``path`` as the harness does and return the trace lines."""
    config = read_config(path.read_text(encoding="utf-8"))
    reset_blackboard()
    try:
        tree = load_tree(path, registry())
    except TreeError:
        return ["load error"]
    events: list[str] = []
    clock = ManualClock(0.0)
    py_trees.trees.setup(tree.root, clock=clock, events=events)
    lines: list[str] = []
    for n in range(1, config.ticks + 1):
        if n > 1:
            clock.advance(config.period_ms / 1000.0)
        if not _tick(tree, n, events, lines):
            return lines
        for key in config.keys:
            try:
                value = show(py_trees.blackboard.Blackboard.get("/" + key))
            except KeyError:
                value = "<none>"
            lines.append(f"bb {key}={value}")
    return lines


def golden_trace(golden: Path) -> list[str]:
    """The golden's compared lines (without the '#' information lines)."""
    return [line for line in golden.read_text(encoding="utf-8").splitlines() if not line.startswith("#")]


#: The ids BehaviorTree.CPP 4.10's factory registers by default (``bt_factory.cpp``), SubTree aside.
BTCPP_BUILTINS = frozenset(
    """Fallback AsyncFallback Sequence AsyncSequence SequenceWithMemory Parallel ParallelAll
    ReactiveSequence ReactiveFallback IfThenElse WhileDoElse TryCatch Inverter RetryUntilSuccessful
    KeepRunningUntilFailure Repeat Timeout Delay RunOnce ForceSuccess ForceFailure AlwaysSuccess
    AlwaysFailure Script ScriptCondition SetBlackboard Sleep UnsetBlackboard Precondition Switch2
    Switch3 Switch4 Switch5 Switch6 LoopInt LoopBool LoopDouble LoopString WasEntryUpdated
    SkipUnlessUpdated WaitValueUpdate""".split()
)


def stub_registry(source: Registry) -> Registry:
    """``source``'s nodes, with every one BT.CPP does not provide replaced by a stub, as the harness's ``stubs`` mode does.

    Leaves record ``name ID`` and succeed; decorators pass their child's status through.
    """
    from chaser_bt.tree.decorators import DecoratorNode
    from chaser_bt.tree.registry import NodeKind

    registry = Registry.with_control_nodes()
    for node_id, node_type in source.specs.items():
        if node_id in BTCPP_BUILTINS or node_id in registry:
            continue
        ports = {"INPUT_PORTS": dict(node_type.input_ports), "OUTPUT_PORTS": dict(node_type.output_ports)}
        if node_type.kind is NodeKind.DECORATOR:
            cls = type(node_id, (DecoratorNode,), ports, register=False)
        else:
            cls = type(node_id, (_StubLeaf,), {**ports, "NODE_ID": node_id, "NODE_KIND": node_type.kind}, register=False)
        registry.register(cls, node_id)
    registry._types.pop("Wait", None)  # chaser-bt's own: BT.CPP sees a stub
    registry.register(type("Wait", (_StubLeaf,), {"INPUT_PORTS": dict(source.get("Wait").input_ports),
                                                   "OUTPUT_PORTS": {}, "NODE_ID": "Wait"}, register=False), "Wait")
    return registry


class _StubLeaf(py_trees.ports.BehaviourWithPorts, register=False):
    INPUT_PORTS: dict = {}
    OUTPUT_PORTS: dict = {}
    NODE_ID = ""

    def setup(self, **kwargs: Any) -> None:
        self.events: list[str] = kwargs["events"]

    def update(self) -> Status:
        self.events.append(f"{self.name} {self.NODE_ID}")
        return Status.SUCCESS


def stub_trace(path: Path, registry: Registry, ticks: int = 5) -> list[str]:
    """Tick a shipped tree with stub leaves as the harness's ``stubs`` mode does."""
    reset_blackboard()
    try:
        tree = load_tree(path, registry)
    except TreeError:
        return ["load error"]
    events: list[str] = []
    py_trees.trees.setup(tree.root, clock=ManualClock(0.0), events=events)
    lines: list[str] = []
    for n in range(1, ticks + 1):
        if not _tick(tree, n, events, lines):
            return lines
    return lines
