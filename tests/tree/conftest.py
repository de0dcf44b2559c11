"""Fixtures for the tree tests: scripted probe leaves, typed test behaviours, a test-local registry."""

from __future__ import annotations

import enum
import textwrap
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, Callable

import py_trees
import pytest
from py_trees.common import Status

from chaser_bt.clock import ManualClock
from chaser_bt.tree import (
    MissionTree,
    Registry,
    input_port,
    load_tree_text,
    output_port,
    reset_blackboard,
)


@dataclass
class Script:
    """What probes return, by instance name, and what happened to them."""

    statuses: dict[str, list[Status]] = field(default_factory=dict)
    events: list[tuple[str, ...]] = field(default_factory=list)
    reads: dict[str, dict[str, Any]] = field(default_factory=lambda: defaultdict(dict))

    def updates(self, name: str) -> int:
        return sum(1 for e in self.events if e == ("update", name))

    def terminations(self, name: str) -> list[str]:
        return [e[2] for e in self.events if e[0] == "terminate" and e[1] == name]


class Probe(py_trees.ports.BehaviourWithPorts, register=False):
    """Returns the next status scripted for its name (the last one repeats); logs its life."""

    INPUT_PORTS: dict = {}
    OUTPUT_PORTS: dict = {}

    def setup(self, **kwargs: Any) -> None:
        self.script: Script = kwargs["script"]

    def initialise(self) -> None:
        self.script.events.append(("initialise", self.name))

    def update(self) -> Status:
        self.script.events.append(("update", self.name))
        queue = self.script.statuses.get(self.name, [Status.SUCCESS])
        return queue.pop(0) if len(queue) > 1 else queue[0]

    def terminate(self, new_status: Status) -> None:
        self.script.events.append(("terminate", self.name, new_status.name))


class Mode(enum.Enum):
    LOITER = "LOITER"
    RTL = "RTL"


class VehicleStateStub:
    """An arbitrary class: only a blackboard reference can supply it."""


class Target(py_trees.ports.BehaviourWithPorts, register=False):
    """Reads every typed port into the script and reports the altitude it was given."""

    INPUT_PORTS = {
        "altitude_m": input_port(float, "target altitude"),
        "offset_m": input_port(list[float], "offset ENU", default=[0, 0, 0]),
        "count": input_port(int, "a count", default=1),
        "armed": input_port(bool, "a flag", default=False),
        "mode": input_port(Mode, "a mode", default=Mode.LOITER),
        "label": input_port(str, "a label", required=False),
        "state": input_port(VehicleStateStub, "vehicle state", default_key="/vehicle/state"),
    }
    OUTPUT_PORTS = {"reached_m": output_port(float, "altitude reached")}

    def setup(self, **kwargs: Any) -> None:
        self.script: Script = kwargs["script"]

    def update(self) -> Status:
        reads = self.script.reads[self.name]
        for port in self.INPUT_PORTS:
            try:
                reads[port] = self.get_input(port)
            except py_trees.ports.NoDataAvailable:
                reads[port] = None
        self._set_output("reached_m", reads["altitude_m"])
        return Status.SUCCESS


@pytest.fixture(autouse=True)
def fresh_blackboard():
    reset_blackboard()
    yield
    reset_blackboard()


@pytest.fixture
def registry() -> Registry:
    registry = Registry.with_control_nodes()
    registry.register(Probe)
    registry.register(Target)
    return registry


@pytest.fixture
def script() -> Script:
    return Script()


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock(100.0)


@pytest.fixture
def build(registry: Registry, script: Script, clock: ManualClock) -> Callable[[str], MissionTree]:
    """Load a one-tree file from the body of its root node and set it up with the script and clock."""

    def _build(body: str, inputs: tuple[str, ...] = ()) -> MissionTree:
        listed = f"inputs: [{', '.join(inputs)}]\n" if inputs else ""
        text = f"version: 1\n{listed}trees:\n  T:\n" + textwrap.indent(textwrap.dedent(body).strip("\n"), "    ") + "\n"
        tree = load_tree_text(text, registry=registry)
        py_trees.trees.setup(tree.root, clock=clock, script=script)
        return tree

    return _build


@pytest.fixture
def tick() -> Callable[[MissionTree], Status]:
    """Tick a tree once and return the root's status."""

    def _tick(tree: MissionTree) -> Status:
        tree.root.tick_once()
        return tree.root.status

    return _tick


@pytest.fixture
def build_xml(registry: Registry, script: Script, clock: ManualClock) -> Callable[..., MissionTree]:
    """Load BT.CPP v4 XML (the body of <root>, or of one <BehaviorTree ID="T">) and set it up."""

    def _build(body: str, *, trees: bool = False, main: str = "T", inputs: str = "") -> MissionTree:
        body = textwrap.dedent(body).strip("\n")
        if not trees:
            body = f'<BehaviorTree ID="{main}">\n{body}\n</BehaviorTree>'
        extra = f' mission_inputs="{inputs}"' if inputs else ""
        text = f'<root BTCPP_format="4" main_tree_to_execute="{main}"{extra}>\n{body}\n</root>\n'
        tree = load_tree_text(text, source="t.xml", registry=registry)
        py_trees.trees.setup(tree.root, clock=clock, script=script)
        return tree

    return _build
