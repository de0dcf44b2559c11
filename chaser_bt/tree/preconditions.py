"""BT.CPP v4 pre-conditions (``_failureIf``, ``_successIf``, ``_skipIf``, ``_while``) around any node.

BT.CPP evaluates a node's pre-conditions inside the node itself; py_trees behaviours have no such
hook, so the builder wraps a node that declares any in :class:`Preconditions`, a decorator that
does exactly what BT.CPP's ``TreeNode::checkPreConditions`` does (behaviortree.dev, "Pre and post
conditions"):

- while the node is not RUNNING, in this order: ``_failureIf`` true -> FAILURE, ``_successIf``
  true -> SUCCESS, ``_skipIf`` true -> SKIPPED, ``_while`` false -> SKIPPED; the node is not ticked;
- while it is RUNNING, only ``_while`` is checked: false halts the node -> SKIPPED;
- otherwise the node is ticked and its status passed through.

SKIPPED is INVALID after the tick (:mod:`chaser_bt.tree.node_base`). An expression that cannot be
evaluated (a key with no value yet, text compared with a number) makes the node FAIL without
running it, and halts it if it was running: for something that flies, not acting is the safe answer
(BT.CPP would throw).
"""

from __future__ import annotations

import logging
from collections.abc import Generator
from dataclasses import dataclass
from typing import Any

import py_trees
from py_trees.common import Status

from chaser_bt.tree.decorators import DecoratorNode
from chaser_bt.tree.expressions import Expression, ExpressionError
from chaser_bt.tree.node_base import SKIPPED

__all__ = ["Condition", "Constant", "Preconditions"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Constant:
    """A variable a SubTree remapping set to a literal."""

    value: Any


@dataclass(frozen=True)
class Condition:
    """One pre-condition: its attribute (``_while``...), the expression, and where each variable lives.

    ``bindings`` maps each variable of the expression to an absolute blackboard key or a :class:`Constant`.
    """

    kind: str
    expression: Expression
    bindings: dict[str, str | Constant]

    def holds(self) -> bool:
        return self.expression.evaluate(self._lookup)

    def _lookup(self, name: str) -> Any:
        binding = self.bindings[name]
        if isinstance(binding, Constant):
            return binding.value
        return py_trees.blackboard.Blackboard.get(binding)

    def __str__(self) -> str:
        return f"{self.kind}={self.expression.text!r}"


class Preconditions(DecoratorNode, register=False):
    """Checks BT.CPP pre-conditions before (and, for ``_while``, during) its node's run."""

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour, conditions: list[Condition]) -> None:
        super().__init__(name=name, child=child)
        self.conditions = list(conditions)

    def step(self) -> Generator[py_trees.behaviour.Behaviour, None, Status]:
        try:
            verdict = self._verdict(self.decorated.status == Status.RUNNING)
        except ExpressionError as e:
            logger.warning("%s: pre-condition cannot be evaluated: %s", self.name, e)
            self.feedback_message = f"pre-condition error: {e}"
            return Status.FAILURE
        if verdict is not None:
            return verdict
        self.feedback_message = ""
        yield from self.decorated.tick()
        return self.decorated.status

    def _verdict(self, running: bool) -> Status | None:
        for condition in self.conditions:
            if running:
                if condition.kind == "_while" and not condition.holds():
                    self.feedback_message = f"halted: {condition} is false"
                    return SKIPPED
                continue
            holds = condition.holds()
            if condition.kind == "_while" and not holds:
                self.feedback_message = f"skipped: {condition} is false"
                return SKIPPED
            if condition.kind != "_while" and holds:
                self.feedback_message = f"{condition} is true"
                return {"_failureIf": Status.FAILURE, "_successIf": Status.SUCCESS}.get(condition.kind, SKIPPED)
        return None
