"""Which shared resources a tree's leaves need from the runner, known before anything connects.

A leaf that cannot work without a resource beside ``link`` and ``clock`` (the ground radar's feed,
the camera) names it in its class attribute ``REQUIRES_RESOURCES``. Reading those before the flight
lets ``chaser-bt run`` refuse a chase tree given no ``--radar`` with a sentence naming the flag,
instead of a ``KeyError`` from a leaf's ``setup()`` after the link is up. A leaf that uses one when
it is there and works without it (the target's telemetry, the ground uplink, what the ground stream
sends) names it in ``USES_RESOURCES``: a report then says which sensors the flight actually used.
"""

from __future__ import annotations

from typing import Iterable

import py_trees

__all__ = ["MissingResources", "missing_resources", "required_resources", "used_resources"]

REQUIRES_ATTRIBUTE = "REQUIRES_RESOURCES"
USES_ATTRIBUTE = "USES_RESOURCES"


class MissingResources(ValueError):
    """A tree needs resources the mission was not given; ``missing`` maps each to its nodes."""

    def __init__(self, message: str, missing: dict[str, list[str]]) -> None:
        super().__init__(message)
        self.missing = missing


def required_resources(root: py_trees.behaviour.Behaviour) -> dict[str, list[str]]:
    """Resource name -> the names of the nodes under ``root`` that require it (in tree order, once each)."""
    needs: dict[str, list[str]] = {}
    for node in root.iterate():
        for resource in getattr(type(node), REQUIRES_ATTRIBUTE, ()):
            names = needs.setdefault(resource, [])
            if node.name not in names:
                names.append(node.name)
    return needs


def used_resources(root: py_trees.behaviour.Behaviour) -> set[str]:
    """Every resource a leaf under ``root`` requires or uses when given."""
    return {r for node in root.iterate() for attr in (REQUIRES_ATTRIBUTE, USES_ATTRIBUTE)
            for r in getattr(type(node), attr, ())}


def missing_resources(
    root: py_trees.behaviour.Behaviour, given: Iterable[str], *, how: dict[str, str] | None = None,
    what: str | None = None,
) -> MissingResources | None:
    """The error to raise when the tree needs resources not in ``given`` (None: all there).

    ``how`` says, per resource, how the caller provides it (e.g. ``{"radar": "--radar HOST:PORT"}``);
    the message names that, and ``what`` the tree (default: its root's name).
    """
    available = set(given)
    missing = {r: nodes for r, nodes in required_resources(root).items() if r not in available}
    if not missing:
        return None
    how = how or {}
    parts = []
    for resource, nodes in missing.items():
        shown = ", ".join(nodes[:3]) + (f" and {len(nodes) - 3} more" if len(nodes) > 3 else "")
        remedy = f": give {how[resource]}" if resource in how else ""
        parts.append(f"a {resource} (needed by {shown}){remedy}")
    return MissingResources(f"{what or root.name} needs " + "; ".join(parts), missing)

