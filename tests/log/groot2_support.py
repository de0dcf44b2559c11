"""The tree the Groot2 tests tick, shared with the BT.CPP recorder (tests/log/groot2_reference/tree.xml).

``Countdown`` and ``Tally`` are the custom nodes, written the same way in ``recorder.cpp``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import py_trees
from py_trees.common import Status

from chaser_bt.tree import MissionTree, Registry, input_port, load_tree, output_port

REFERENCE = Path(__file__).parent / "groot2_reference"
TREE_XML = REFERENCE / "tree.xml"
#: More control nodes and decorators, ports with default remappings, a SubTree with a remapping.
SEMANTICS_XML = REFERENCE / "semantics.xml"
#: Halts: a ``_while`` turning false, a Parallel failing with a child running, a ReactiveFallback.
HALTS_XML = REFERENCE / "halts.xml"
#: Decorators that reset a finished child and carry on (KeepRunningUntilFailure, Retry, Repeat), RunOnce.
DECORATORS_XML = REFERENCE / "decorators.xml"


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


def models_json(reg: Registry) -> str:
    """The nodes BT.CPP does not have, for ``groot2_recorder --fulltree``: kind, ports with their defaults."""
    from chaser_bt.tree.node_model import BTCPP_BUILTIN_NODES
    from chaser_bt.tree.node_model import default_text

    out = {}
    for node_id in reg.ids():
        if node_id in BTCPP_BUILTIN_NODES:
            continue
        node = reg.get(node_id)
        ports = [{"name": name, "direction": direction, "default": default_text(port),
                  "description": port.description or ""}
                 for direction, group in (("input", node.input_ports), ("output", node.output_ports))
                 for name, port in group.items()]
        out[node_id] = {"kind": node.kind.value, "ports": ports}
    return json.dumps(out, indent=1, sort_keys=True) + "\n"


if __name__ == "__main__":  # python tests/log/groot2_support.py > models.json: the default registry's nodes
    from chaser_bt.tree import default_registry

    print(models_json(default_registry()), end="")
