"""The behaviour registry: which node ids a tree may use, and the ports each one declares.

Mirrors BT.CPP's ``BehaviorTreeFactory``: control nodes are built in, behaviours are added by
registration. Behaviour modules are plug-ins found through the ``chaser_bt.behaviours``
entry-point group, so chaser_bt never imports ``behaviours/`` directly (DESIGN §2) and a third
party adds nodes by shipping a package with the same entry point.
"""

from __future__ import annotations

import difflib
import importlib.metadata
import logging
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TypeVar

import py_trees
from py_trees.ports import PortInformation, PortsMixin

from chaser_bt.tree.control import CONTROL_NODES
from chaser_bt.tree.errors import UnknownNode
from chaser_bt.tree.model import SUBTREE_ID
from chaser_bt.tree.node_kind import NodeKind

__all__ = [
    "NodeKind",
    "NodeType",
    "Registry",
    "register_behaviour",
    "default_registry",
    "RESERVED_ATTRIBUTES",
    "ENTRY_POINT_GROUP",
]

logger = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "chaser_bt.behaviours"

#: Attribute names a tree node uses for structure, so no port may take them.
RESERVED_ATTRIBUTES = frozenset({"name", "children", "child", "ID", "_autoremap"})

B = TypeVar("B", bound=type)


@dataclass(frozen=True)
class NodeType:
    """A registered node: its id, class and kind, with the class's port declarations."""

    node_id: str
    cls: type
    kind: NodeKind

    @property
    def input_ports(self) -> Mapping[str, PortInformation]:
        return self.cls.input_ports()

    @property
    def output_ports(self) -> Mapping[str, PortInformation]:
        return self.cls.output_ports()

    def port(self, name: str) -> PortInformation | None:
        """The declaration of port ``name`` (input or output), or None."""
        return self.input_ports.get(name) or self.output_ports.get(name)

    def port_names(self) -> list[str]:
        return [*self.input_ports, *self.output_ports]

    @property
    def description(self) -> str:
        """The class docstring's summary: its first paragraph, on one line (a summary may wrap)."""
        doc = (self.cls.__doc__ or "").strip()
        return " ".join(line.strip() for line in doc.split("\n\n")[0].splitlines())


def _kind_of(cls: type) -> NodeKind:
    if issubclass(cls, py_trees.composites.Composite):
        return NodeKind.CONTROL
    if issubclass(cls, py_trees.decorators.Decorator):
        return NodeKind.DECORATOR
    kind = getattr(cls, "NODE_KIND", NodeKind.ACTION)
    if not isinstance(kind, NodeKind) or not kind.is_leaf:
        raise TypeError(f"{cls.__name__}.NODE_KIND must be NodeKind.ACTION or NodeKind.CONDITION, got {kind!r}")
    return kind


class Registry:
    """Node ids -> node types. ``Registry.with_control_nodes()`` starts from the built-in control nodes."""

    def __init__(self, classes: Iterable[type] = ()) -> None:
        self._types: dict[str, NodeType] = {}
        #: BT.CPP's scripting enums: names a script reads as integer constants (``registerScriptingEnum``).
        self.scripting_enums: dict[str, int] = {}
        for cls in classes:
            self.register(cls)

    @classmethod
    def with_control_nodes(cls) -> Registry:
        """A registry holding BT.CPP's standard control, decorator and utility nodes."""
        return cls(CONTROL_NODES)

    def register(self, cls: B, node_id: str | None = None) -> B:
        """Add a ports-declaring behaviour class under ``node_id`` (default: its class name).

        Raises:
            TypeError: ``cls`` is not a concrete py_trees behaviour with declared ports.
            ValueError: the id is taken by another class, or a port uses a reserved attribute name.
        """
        behaviour = py_trees.behaviour.Behaviour
        if not (isinstance(cls, type) and issubclass(cls, PortsMixin) and issubclass(cls, behaviour)):
            raise TypeError(f"{cls!r} is not a py_trees behaviour with ports (subclass BehaviourWithPorts)")
        if not (hasattr(cls, "INPUT_PORTS") and hasattr(cls, "OUTPUT_PORTS")):
            raise TypeError(f"{cls.__name__} declares no INPUT_PORTS / OUTPUT_PORTS")
        node_id = node_id or cls.__name__
        if node_id == SUBTREE_ID:
            raise ValueError(f"'{SUBTREE_ID}' is reserved for subtree instances")
        reserved = sorted(RESERVED_ATTRIBUTES.intersection([*cls.INPUT_PORTS, *cls.OUTPUT_PORTS]))
        if reserved:
            raise ValueError(f"{cls.__name__} uses reserved attribute names as ports: {', '.join(reserved)}")
        existing = self._types.get(node_id)
        if existing is not None and existing.cls is not cls:
            owner = f"{existing.cls.__module__}.{existing.cls.__qualname__}"
            raise ValueError(f"node id '{node_id}' is already registered to {owner}")
        self._types[node_id] = NodeType(node_id=node_id, cls=cls, kind=_kind_of(cls))
        return cls

    def register_scripting_enum(self, name: str, value: int) -> None:
        """Let scripts use ``name`` for the integer ``value`` (BT.CPP's ``registerScriptingEnum``)."""
        self.scripting_enums[name] = int(value)

    def get(self, node_id: str) -> NodeType:
        """The node type registered as ``node_id``.

        Raises:
            UnknownNode: listing the known ids, best matches first.
        """
        try:
            return self._types[node_id]
        except KeyError:
            raise UnknownNode(node_id, self.ranked_ids(node_id), self.suggestions(node_id)) from None

    def __contains__(self, node_id: object) -> bool:
        return node_id in self._types

    def ids(self) -> list[str]:
        """Every registered node id, sorted."""
        return sorted(self._types)

    @property
    def specs(self) -> Mapping[str, NodeType]:
        """Read-only view of every node type by id."""
        return MappingProxyType(self._types)

    def suggestions(self, node_id: str) -> list[str]:
        """Close matches for a mistyped id, best first (case-insensitive)."""
        by_lower = {i.lower(): i for i in self._types}
        close = difflib.get_close_matches(node_id.lower(), list(by_lower), n=3, cutoff=0.6)
        return [by_lower[c] for c in close]

    def ranked_ids(self, node_id: str) -> list[str]:
        """Every id ordered by similarity to ``node_id``, best first."""
        target = node_id.lower()
        return sorted(self._types, key=lambda i: (-difflib.SequenceMatcher(None, target, i.lower()).ratio(), i))

    def copy(self) -> Registry:
        """An independent registry with the same entries."""
        clone = Registry()
        clone._types = dict(self._types)
        clone.scripting_enums = dict(self.scripting_enums)
        return clone


_default = Registry.with_control_nodes()
_plugins_loaded = False


def register_behaviour(cls: B) -> B:
    """Class decorator: add a behaviour to the default registry under its class name."""
    return _default.register(cls)


def default_registry() -> Registry:
    """Control nodes plus every behaviour module of the ``chaser_bt.behaviours`` entry points.

    The plug-in modules are imported once, on the first call; their ``@register_behaviour``
    decorators fill the registry as they import.
    """
    global _plugins_loaded
    if not _plugins_loaded:
        _plugins_loaded = True
        for entry_point in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
            try:
                entry_point.load()
            except Exception as e:
                _plugins_loaded = False
                plugin = f"'{entry_point.name}' ({entry_point.value})"
                raise ImportError(f"behaviour plug-in {plugin} failed to import: {e}") from e
            logger.debug("loaded behaviour plug-in %s = %s", entry_point.name, entry_point.value)
    return _default
