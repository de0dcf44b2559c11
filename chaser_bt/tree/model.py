"""The parsed tree model, neutral between the YAML and the BT.CPP-XML formats.

A file becomes a :class:`TreeDocument`: named tree definitions (BT.CPP's ``<BehaviorTree ID>``)
whose nodes keep their port values exactly as written, each with the position it came from,
so validation can point at the offending line. Nothing here knows the registry: whether a node
id exists or a literal fits its port is decided by :mod:`chaser_bt.tree.validation`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "Location",
    "PortArg",
    "SubTreeRef",
    "NodeSpec",
    "TreeSpec",
    "TreeDocument",
    "SUBTREE_ID",
    "PRECONDITIONS",
    "POSTCONDITIONS",
    "MAX_DEPTH",
]

#: The node id that instantiates another tree of the same document (BT.CPP ``<SubTree ID=...>``).
SUBTREE_ID = "SubTree"

#: The deepest nesting of nodes a tree file may have (a guard against files built to exhaust the stack).
MAX_DEPTH = 100

#: BT.CPP v4's pre-condition attributes, in the order BT.CPP evaluates them.
PRECONDITIONS = ("_failureIf", "_successIf", "_skipIf", "_while")

#: BT.CPP v4's post-condition scripts: run when the node succeeds, fails, finishes either way, is halted.
POSTCONDITIONS = ("_onSuccess", "_onFailure", "_post", "_onHalted")


@dataclass(frozen=True)
class Location:
    """A position in a source file; line and column count from 1."""

    file: str
    line: int
    column: int


@dataclass
class PortArg:
    """A port's value as written: a literal (typed by the format) or a ``"{key}"`` string.

    ``location`` is where the port is named, ``value_location`` where its value starts
    (the same place in XML; a later line for a block list in YAML). ``from_text`` marks a value
    that is attribute text (XML), to be typed by its port (:func:`chaser_bt.tree.ports.literal_from_text`).
    """

    value: Any
    location: Location = field(compare=False)
    value_location: Location | None = field(default=None, compare=False)
    from_text: bool = field(default=False, compare=False)

    @property
    def value_at(self) -> Location:
        return self.value_location or self.location


@dataclass
class SubTreeRef:
    """What a ``SubTree`` node instantiates: the tree id and whether unmapped keys pass through."""

    tree_id: str
    autoremap: bool = False
    location: Location = field(default=Location("", 0, 0), compare=False)


@dataclass
class NodeSpec:
    """One node as written: its id, optional instance name, port values and children.

    For a ``SubTree`` node, ``ports`` are the BT.CPP remappings of the subtree's keys.
    ``conditions`` are BT.CPP pre-conditions (``_while`` ...) by attribute name, each an expression.
    ``unreadable_children`` counts children the parser already reported as malformed, so
    validation does not also call the node childless.
    """

    node_id: str
    location: Location = field(compare=False)
    name: str | None = None
    ports: dict[str, PortArg] = field(default_factory=dict)
    children: list[NodeSpec] = field(default_factory=list)
    subtree: SubTreeRef | None = None
    unreadable_children: int = field(default=0, compare=False)
    conditions: dict[str, PortArg] = field(default_factory=dict)
    #: The XML element it was written as when that was the explicit form (``Action``, ``Condition``...).
    explicit_tag: str | None = field(default=None, compare=False)

    @property
    def display_name(self) -> str:
        """The instance name, defaulting to the node id (BT.CPP does the same)."""
        return self.name if self.name else self.node_id


@dataclass
class TreeSpec:
    """A named tree definition; ``root`` is None when the definition was unusable."""

    tree_id: str
    root: NodeSpec | None
    location: Location = field(compare=False)


@dataclass
class TreeDocument:
    """A whole tree file: format version, the tree to execute, mission inputs, the trees and included files.

    ``includes`` are the paths as written (relative to the file's folder); the loader reads them
    and merges their trees (:mod:`chaser_bt.tree.includes`).
    """

    source: str
    version: Any = None
    main: str | None = None
    main_location: Location | None = field(default=None, compare=False)
    inputs: list[PortArg] = field(default_factory=list)
    trees: dict[str, TreeSpec] = field(default_factory=dict)
    includes: list[PortArg] = field(default_factory=list)
    #: Port defaults of ``<SubTree>`` entries in a ``<TreeNodesModel>`` (Groot2 writes them), by
    #: tree id: BT.CPP uses each as the remapping when a SubTree node leaves that port out.
    subtree_defaults: dict[str, dict[str, PortArg]] = field(default_factory=dict)
