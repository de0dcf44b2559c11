"""Loading a mission tree: read, validate everything, and only then build (DESIGN §4).

A tree that fails validation never ticks: :func:`load_tree` raises :class:`TreeError` with
every problem found, and builds nothing, when there is any.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass, field
from pathlib import Path

import py_trees

from chaser_bt.tree.builder import build_node
from chaser_bt.tree.errors import Problem, TreeError
from chaser_bt.tree.registry import Registry, default_registry
from chaser_bt.tree.validation import Resolution, ResolvedNode, resolve_document
from chaser_bt.tree.yaml_format import parse_yaml

__all__ = ["MissionTree", "load_tree", "load_tree_text", "validate_tree", "validate_tree_text"]


@dataclass
class MissionTree:
    """A built, validated tree.

    Attributes:
        name: the id of the tree that executes (``main``).
        root: the py_trees root behaviour.
        source: the file it came from, None for text.
        inputs: absolute blackboard keys the mission provides from outside the tree.
        wiring: per node id, how each port was given ("20", "{/alt}"), for display.
    """

    name: str
    root: py_trees.behaviour.Behaviour
    source: Path | None
    inputs: tuple[str, ...]
    wiring: dict[uuid.UUID, dict[str, str]] = field(default_factory=dict)


def load_tree(path: str | Path, registry: Registry | None = None) -> MissionTree:
    """Read, validate and build the tree in ``path`` (YAML).

    Raises:
        TreeError: listing every problem, one per line as ``file:line:col: message``.
    """
    path = Path(path)
    tree = load_tree_text(_read(path), source=str(path), registry=registry)
    tree.source = path
    return tree


def load_tree_text(text: str, source: str = "<string>", registry: Registry | None = None) -> MissionTree:
    """Validate and build tree YAML given as text; ``source`` names it in problems."""
    resolution, problems = _resolve(text, source, registry)
    if problems:
        raise TreeError(problems)
    assert resolution.root is not None and resolution.main is not None
    wiring: dict[uuid.UUID, dict[str, str]] = {}
    root = build_node(resolution.root)
    _collect_wiring(resolution.root, root, wiring)
    return MissionTree(resolution.main, root, None, resolution.inputs, wiring)


def validate_tree(path: str | Path, registry: Registry | None = None) -> list[Problem]:
    """Every problem in the tree file ``path``, sorted by position; empty when it is valid."""
    path = Path(path)
    try:
        text = _read(path)
    except TreeError as e:
        return e.problems
    return validate_tree_text(text, str(path), registry)


def validate_tree_text(text: str, source: str = "<string>", registry: Registry | None = None) -> list[Problem]:
    """Every problem in tree YAML given as text."""
    return _resolve(text, source, registry)[1]


def _read(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise TreeError([Problem(str(path), 1, 1, f"cannot read tree file: {e}")]) from e


def _resolve(text: str, source: str, registry: Registry | None) -> tuple[Resolution, list[Problem]]:
    document, problems = parse_yaml(text, source)
    resolution, more = resolve_document(document, registry if registry is not None else default_registry())
    return resolution, sorted(set(problems + more))


def _collect_wiring(
    resolved: ResolvedNode, node: py_trees.behaviour.Behaviour, wiring: dict[uuid.UUID, dict[str, str]]
) -> None:
    wiring[node.id] = dict(resolved.wiring)
    for resolved_child, child in zip(resolved.children, node.children, strict=True):
        _collect_wiring(resolved_child, child, wiring)
