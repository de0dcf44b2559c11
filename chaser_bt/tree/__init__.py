"""Mission trees as data: port declarations, the behaviour registry, YAML and BT.CPP v4 XML, validation, loading.

Behaviours declare typed ports (:func:`input_port`, :func:`output_port`) and register with
:func:`register_behaviour`; :func:`load_tree` reads a tree file (``.xml``: BehaviorTree.CPP v4
XML, else YAML; both give the same model), reports every problem at once (:class:`TreeError` of
:class:`Problem`) and only then builds the py_trees tree. Conversion between the formats is in
:mod:`chaser_bt.tree.conversion`, Groot2's node model in :mod:`chaser_bt.tree.node_model`. The
formats are documented in ``docs/trees.md``.
"""

from chaser_bt.tree.blackboard import reset_blackboard
from chaser_bt.tree.display import render_node_reference, render_tree
from chaser_bt.tree.errors import Problem, TreeError, UnknownNode
from chaser_bt.tree.loader import MissionTree, load_tree, load_tree_text, validate_tree, validate_tree_text
from chaser_bt.tree.ports import Port, input_port, output_port
from chaser_bt.tree.registry import NodeKind, NodeType, Registry, default_registry, register_behaviour

__all__ = [
    "Port",
    "input_port",
    "output_port",
    "NodeKind",
    "NodeType",
    "Registry",
    "register_behaviour",
    "default_registry",
    "MissionTree",
    "load_tree",
    "load_tree_text",
    "validate_tree",
    "validate_tree_text",
    "render_node_reference",
    "render_tree",
    "reset_blackboard",
    "Problem",
    "TreeError",
    "UnknownNode",
]
