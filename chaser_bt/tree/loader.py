"""Loading a mission tree: read, validate everything, and only then build (DESIGN §4).

A tree that fails validation never ticks: :func:`load_tree` raises :class:`TreeError` with
every problem found, and builds nothing, when there is any. ``.xml`` files are BT.CPP v4 XML,
anything else YAML (:mod:`chaser_bt.tree.documents`); includes are read relative to the file.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass, field
from pathlib import Path

import py_trees

from chaser_bt.tree.builder import build_node
from chaser_bt.tree.documents import merge_includes, parse_document, read_document
from chaser_bt.tree.model import TreeDocument
from chaser_bt.tree.errors import Problem, TreeError
from chaser_bt.tree.preconditions import Preconditions
from chaser_bt.tree.registry import Registry, default_registry
from chaser_bt.tree.validation import Resolution, ResolvedNode, resolve_document

__all__ = ["MissionTree", "build_tree", "collect_wiring", "load_tree", "load_tree_text", "validate_tree", "validate_tree_text"]


@dataclass
class MissionTree:
    """A built, validated tree.

    Attributes:
        name: the id of the tree that executes (``main``).
        root: the py_trees root behaviour.
        source: the file it came from, None for text.
        inputs: absolute blackboard keys the mission provides from outside the tree.
        wiring: per node id, how each port was given ("20", "{/alt}"), for display.
        resolved: the resolved tree it was built from (Groot2's monitor describes the tree with it).
    """

    name: str
    root: py_trees.behaviour.Behaviour
    source: Path | None
    inputs: tuple[str, ...]
    wiring: dict[uuid.UUID, dict[str, str]] = field(default_factory=dict)
    resolved: ResolvedNode | None = field(default=None, repr=False)


def load_tree(path: str | Path, registry: Registry | None = None) -> MissionTree:
    """Read, validate and build the tree in ``path`` (BT.CPP XML for ``.xml``, YAML otherwise).

    Raises:
        TreeError: listing every problem, one per line as ``file:line:col: message``.
    """
    path = Path(path)
    document, problems = read_document(path)
    tree = build_tree(document, problems, registry)
    tree.source = path
    return tree


def load_tree_text(
    text: str,
    source: str = "<string>",
    registry: Registry | None = None,
    fmt: str | None = None,
    base_dir: str | Path = ".",
) -> MissionTree:
    """Validate and build a tree given as text; ``source`` names it in problems.

    Args:
        fmt: ``"yaml"`` or ``"xml"``; default by ``source``'s extension, else XML when the text starts with '<'.
        base_dir: the folder includes are relative to.
    """
    return build_tree(*_parse_text(text, source, fmt, base_dir), registry)


def build_tree(document: TreeDocument, problems: list[Problem], registry: Registry | None) -> MissionTree:
    """Resolve a parsed document (with the parser's ``problems``) and build its behaviours; TreeError
    listing every problem when it cannot fly."""
    resolution, problems = _resolve(document, problems, registry)
    if problems:
        raise TreeError(problems)
    assert resolution.root is not None and resolution.main is not None
    wiring: dict[uuid.UUID, dict[str, str]] = {}
    root = build_node(resolution.root)
    collect_wiring(resolution.root, root, wiring)
    return MissionTree(resolution.main, root, None, resolution.inputs, wiring, resolution.root)


def validate_tree(path: str | Path, registry: Registry | None = None) -> list[Problem]:
    """Every problem in the tree file ``path`` (and its includes), sorted by position; empty when it is valid."""
    return _resolve(*read_document(Path(path)), registry)[1]


def validate_tree_text(
    text: str,
    source: str = "<string>",
    registry: Registry | None = None,
    fmt: str | None = None,
    base_dir: str | Path = ".",
) -> list[Problem]:
    """Every problem in a tree given as text (see :func:`load_tree_text` for the arguments)."""
    return _resolve(*_parse_text(text, source, fmt, base_dir), registry)[1]


def _parse_text(text: str, source: str, fmt: str | None, base_dir: str | Path) -> tuple[TreeDocument, list[Problem]]:
    document, problems = parse_document(text, source, fmt)
    merged, more = merge_includes(document, Path(base_dir))
    return merged, problems + more


def _resolve(
    document: TreeDocument, problems: list[Problem], registry: Registry | None
) -> tuple[Resolution, list[Problem]]:
    resolution, more = resolve_document(document, registry if registry is not None else default_registry())
    return resolution, sorted(set(problems + more))


def collect_wiring(
    resolved: ResolvedNode, node: py_trees.behaviour.Behaviour, wiring: dict[uuid.UUID, dict[str, str]]
) -> None:
    """Record, by node id, the port wiring of ``node`` and its descendants as ``resolved`` gives it
    (what ``chaser-bt show`` and Groot2 describe)."""
    if isinstance(node, Preconditions):
        wiring[node.id] = {c.kind: repr(c.expression.text) for c in node.conditions}
        node = node.decorated
    wiring[node.id] = dict(resolved.wiring)
    for resolved_child, child in zip(resolved.children, node.children, strict=True):
        collect_wiring(resolved_child, child, wiring)
