"""The tree the Groot2 tests tick, shared with the BT.CPP recorder (tests/log/groot2_reference/tree.xml).

``Countdown`` is the one custom node, written the same way in ``recorder.cpp``: RUNNING for
``ticks`` ticks after it starts, then SUCCESS.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import py_trees
from py_trees.common import Status

from chaser_bt.tree import MissionTree, Registry, input_port, load_tree

REFERENCE = Path(__file__).parent / "groot2_reference"
TREE_XML = REFERENCE / "tree.xml"
#: Ticks the recorder ran (the tree finishes on the last).
TICKS = 6


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


def registry() -> Registry:
    reg = Registry.with_control_nodes()
    reg.register(Countdown)
    return reg


def reference_tree() -> tuple[MissionTree, Registry]:
    reg = registry()
    return load_tree(TREE_XML, reg), reg


def ticked_bt(tree: MissionTree, *visitors: Any) -> py_trees.trees.BehaviourTree:
    bt = py_trees.trees.BehaviourTree(tree.root)
    for visitor in visitors:
        bt.add_visitor(visitor)
    bt.setup()
    return bt
