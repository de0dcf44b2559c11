"""Builds py_trees behaviours from a resolved tree and wires their ports.

Every node gets ``setup_ports(remappings, subtree_namespace)`` (py_trees' port wiring): ``{key}``
references and default keys are remapped to absolute blackboard keys; literals are left to
py_trees' private per-node key, which is then seeded with the typed value, so ``get_input``
returns it exactly as declared. py_trees' own parser encodes literals into key names
(``__const_``), which loses lists, dots and slashes; seeding the private key does not.

A literal is part of its node's configuration (BT.CPP keeps it in the node, not on the
blackboard), so the builder remembers the literals of every live node and
:func:`restore_literals` puts them back after the process-wide blackboard is cleared.
"""

from __future__ import annotations

import copy
import weakref
from typing import Any

import py_trees

from chaser_bt.tree.preconditions import Preconditions
from chaser_bt.tree.registry import NodeKind
from chaser_bt.tree.validation import ResolvedNode

__all__ = ["build_node", "wire_ports", "restore_literals"]

#: Blackboard key -> literal value, for every node still alive.
_literals: weakref.WeakKeyDictionary[py_trees.behaviour.Behaviour, dict[str, Any]] = weakref.WeakKeyDictionary()


def build_node(resolved: ResolvedNode) -> py_trees.behaviour.Behaviour:
    """Construct the behaviour for ``resolved`` and its subtree, with every port wired.

    A node with pre-conditions comes back wrapped in :class:`Preconditions` (same name).
    """
    children = [build_node(child) for child in resolved.children]
    cls = resolved.node_type.cls
    if resolved.node_type.kind is NodeKind.DECORATOR:
        node = cls(name=resolved.name, child=children[0])
    else:
        node = cls(name=resolved.name)
        if children:
            node.add_children(children)
    wire_ports(node, resolved.remappings, resolved.literals, resolved.namespace)
    if resolved.scripts:
        node.scripts = dict(resolved.scripts)
    if resolved.conditions:
        wrapper = Preconditions(name=resolved.name, child=node, conditions=resolved.conditions)
        wire_ports(wrapper, namespace=resolved.namespace)
        return wrapper
    return node


def wire_ports(
    node: py_trees.ports.PortsMixin,
    remappings: dict[str, str] | None = None,
    literals: dict[str, Any] | None = None,
    namespace: str = "/",
) -> None:
    """``setup_ports`` with ``remappings``, then store each literal on the node's private key for that port."""
    node.setup_ports(port_remappings=dict(remappings or {}), subtree_namespace=namespace)
    stored = {node._get_blackboard_key(port): value for port, value in (literals or {}).items()}
    if stored:
        _literals[node] = stored
        _seed(stored)


def restore_literals() -> None:
    """Store the literal port values of every live node again (after the blackboard was cleared)."""
    for stored in list(_literals.values()):
        _seed(stored)


def _seed(stored: dict[str, Any]) -> None:
    # A copy each time: a behaviour that mutates a list it read cannot change the tree's literal.
    for key, value in stored.items():
        py_trees.blackboard.Blackboard.set(key, copy.deepcopy(value))
