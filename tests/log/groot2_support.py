"""The tree the Groot2 tests tick, shared with the BT.CPP recorder (tests/log/groot2_reference/tree.xml).

``Countdown`` and ``Tally`` are the custom nodes, written the same way in ``recorder.cpp``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import py_trees
from py_trees.common import Status

from chaser_bt.tree import MissionTree, Registry, input_port, load_tree, output_port

REFERENCE = Path(__file__).parent / "groot2_reference"
TREE_XML = REFERENCE / "tree.xml"
#: More control nodes and decorators, ports with default remappings, a SubTree with a remapping.
SEMANTICS_XML = REFERENCE / "semantics.xml"


class Countdown(py_trees.ports.BehaviourWithPorts, register=False):
    """RUNNING for ``ticks`` ticks after it starts, then SUCCESS."""

    INPUT_PORTS = {"ticks": input_port(int, "ticks to stay RUNNING", default=2)}
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self.remaining: int = self.get_input("ticks")

    def update(self) -> Status:
        if self.remaining == 0:
            return Status.SUCCESS
        self.remaining -= 1
        return Status.RUNNING


class Tally(py_trees.ports.BehaviourWithPorts, register=False):
    """Writes ``add`` to ``total``; SUCCESS."""

    INPUT_PORTS = {"add": input_port(int, "amount to add", default=1)}
    OUTPUT_PORTS = {"total": output_port(int, "the amount, written", default_key="tally")}

    def update(self) -> Status:
        self._set_output("total", self.get_input("add"))
        return Status.SUCCESS


def registry() -> Registry:
    reg = Registry.with_control_nodes()
    reg.register(Countdown)
    reg.register(Tally)
    return reg


def reference_tree(path: Path = TREE_XML) -> tuple[MissionTree, Registry]:
    reg = registry()
    return load_tree(path, reg), reg


def ticked_bt(tree: MissionTree, *visitors: Any) -> py_trees.trees.BehaviourTree:
    bt = py_trees.trees.BehaviourTree(tree.root)
    for visitor in visitors:
        bt.add_visitor(visitor)
    bt.setup()
    return bt
