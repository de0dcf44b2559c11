"""What BT.CPP's built-in nodes share here: port plumbing, static port checks, halting, SKIPPED, the clock.

BT.CPP v4 has a fifth status, SKIPPED: a node whose pre-condition (``_skipIf``, ``_while``) told it
not to run. py_trees has no such status, so a skipped node ends its tick INVALID, py_trees' own
"not running" status, and every control node here reads a child that is INVALID right after being
ticked as SKIPPED, exactly where BT.CPP tests for ``NodeStatus::SKIPPED``.
"""

from __future__ import annotations

from collections.abc import Generator, Mapping
from typing import Any, ClassVar

import py_trees
from py_trees.common import Status
from py_trees.ports import PortsMixin

from chaser_bt.clock import Clock
from chaser_bt.tree.ports import Port

#: What a control node's ``step()`` is: a generator that yields ticked nodes and returns a status.
Steps = Generator[py_trees.behaviour.Behaviour, None, Status]

__all__ = ["ControlPorts", "PortCheck", "SKIPPED", "check_count", "halt", "is_active", "require_clock", "now"]

#: BT.CPP's SKIPPED, as a node's status right after its tick (see the module docstring).
SKIPPED = Status.INVALID

#: (port name, message) pairs a node reports about statically known port values.
PortCheck = list[tuple[str, str]]


class ControlPorts(PortsMixin):
    """Port plumbing shared by the built-in nodes: no ports unless declared, static checks."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {}
    OUTPUT_PORTS: ClassVar[dict[str, Port]] = {}

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        """Problems with port values known before the tree runs (literals and defaults)."""
        return []


def is_active(node: py_trees.behaviour.Behaviour) -> bool:
    """Whether BT.CPP would see the node RUNNING: it is, or it is a decorator whose child was just skipped.

    A BT.CPP decorator sets itself RUNNING before ticking its child and stays so when the child is
    skipped (only SKIPPED goes up), so it keeps its state (a Repeat's count, a Delay's timer) and a
    parent that halts its RUNNING children halts it. Ours reports SKIPPED as INVALID and marks
    itself ``suspended``.
    """
    return node.status == Status.RUNNING or getattr(node, "suspended", False)


def halt(node: py_trees.behaviour.Behaviour) -> None:
    """BT.CPP's ``haltChild``/``resetChild``: a RUNNING node is halted (terminate INVALID), a finished one reset."""
    if node.status != Status.INVALID or is_active(node):
        node.stop(Status.INVALID)


def check_count(values: Mapping[str, Any], port: str, minimum: int) -> PortCheck:
    value = values.get(port)
    if isinstance(value, int) and value < minimum:
        return [(port, f"{port} must be >= {minimum}{' (-1 = forever)' if minimum == -1 else ''}, got {value}")]
    return []


def require_clock(node: py_trees.behaviour.Behaviour, kwargs: Mapping[str, Any]) -> Clock:
    clock = kwargs.get("clock")
    if not isinstance(clock, Clock):
        raise RuntimeError(f"{node.name}: {type(node).__name__} needs a Clock: call setup(clock=...)")
    return clock


def now(node: py_trees.behaviour.Behaviour, clock: Clock | None) -> float:
    if clock is None:
        raise RuntimeError(f"{node.name}: {type(node).__name__} was not set up with a Clock: call setup(clock=...)")
    return clock.now()
