"""BT.CPP v4 pre- and post-conditions around any node, and scripts bound to the blackboard.

BT.CPP evaluates a node's conditions inside ``TreeNode::executeTick``; py_trees behaviours have no
such hook, so the builder wraps a node that declares any in :class:`Preconditions`, a decorator
that does what ``checkPreConditions`` / ``checkPostConditions`` / ``haltNode`` do:

- while the node is not RUNNING, in this order: ``_failureIf`` true -> FAILURE, ``_successIf``
  true -> SUCCESS, ``_skipIf`` true -> SKIPPED, ``_while`` false -> SKIPPED; the node is not ticked;
- while it is RUNNING, only ``_while`` is checked: false halts the node -> SKIPPED;
- otherwise the node is ticked;
- when the result is SUCCESS ``_onSuccess`` runs, FAILURE ``_onFailure``; then ``_post`` (either);
- a halt of the RUNNING node runs ``_onHalted`` after halting it.

SKIPPED is INVALID after the tick (:mod:`chaser_bt.tree.node_base`). A pre-condition that cannot
be evaluated (a key with no value yet, text compared with a number) makes the node FAIL without
running it, and halts it if it was running: BT.CPP throws; for something that flies, not acting
is the safe answer. Post-condition scripts, like ``Script`` nodes, raise as BT.CPP does.
"""

from __future__ import annotations

import logging
from collections.abc import Generator
from dataclasses import dataclass
from typing import Any

import py_trees
from py_trees.common import Status

from chaser_bt.tree.decorators import DecoratorNode
from chaser_bt.tree.expressions import Expression, ExpressionError, truth
from chaser_bt.tree.model import PRECONDITIONS
from chaser_bt.tree.node_base import SKIPPED, is_active

__all__ = ["BlackboardEnv", "Condition", "Constant", "Preconditions"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Constant:
    """A variable a SubTree remapping set to a literal."""

    value: Any


class BlackboardEnv:
    """A script's names -> py_trees blackboard keys (or SubTree literals), as validation bound them."""

    def __init__(self, bindings: dict[str, str | Constant]) -> None:
        self.bindings = bindings

    def get(self, name: str) -> Any:
        binding = self.bindings[name]
        if isinstance(binding, Constant):
            return binding.value
        return py_trees.blackboard.Blackboard.get(binding)

    def has(self, name: str) -> bool:
        binding = self.bindings[name]
        return isinstance(binding, Constant) or py_trees.blackboard.Blackboard.exists(binding)

    def set(self, name: str, value: Any) -> None:
        binding = self.bindings[name]
        if isinstance(binding, Constant):
            raise ExpressionError(f"'{name}' is a literal its SubTree gave: a script cannot assign it")
        py_trees.blackboard.Blackboard.set(binding, value)


@dataclass(frozen=True)
class Condition:
    """One script: its attribute or port (``_while``, ``code``...), the parsed script, where each name lives.

    ``bindings`` maps each variable of the script to an absolute blackboard key or a :class:`Constant`.
    """

    kind: str
    expression: Expression
    bindings: dict[str, str | Constant]

    def run(self) -> Any:
        return self.expression.run(BlackboardEnv(self.bindings))

    def holds(self) -> bool:
        return truth(self.run())

    def __str__(self) -> str:
        return f"{self.kind}={self.expression.text!r}"


class Preconditions(DecoratorNode, register=False):
    """Checks BT.CPP pre-conditions before (and, for ``_while``, during) its node's run; runs its post-conditions."""

    #: A node its pre-condition skipped keeps BT.CPP's IDLE: no state to keep here.
    KEEPS_STATE_WHEN_SKIPPED = False

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour, conditions: list[Condition]) -> None:
        super().__init__(name=name, child=child)
        self.conditions = [c for c in conditions if c.kind in PRECONDITIONS]
        self.post = {c.kind: c for c in conditions if c.kind not in PRECONDITIONS}

    def step(self) -> Generator[py_trees.behaviour.Behaviour, None, Status]:
        try:
            verdict = self._verdict(is_active(self.decorated))
        except ExpressionError as e:
            logger.warning("%s: pre-condition cannot be evaluated: %s", self.name, e)
            self.feedback_message = f"pre-condition error: {e}"
            verdict = Status.FAILURE
        if verdict is None:
            self.feedback_message = ""
            yield from self.decorated.tick()
            verdict = self.decorated.status
        if verdict in (Status.SUCCESS, Status.FAILURE):
            self._post("_onSuccess" if verdict == Status.SUCCESS else "_onFailure")
            self._post("_post")
        return verdict

    def _post(self, kind: str) -> None:
        script = self.post.get(kind)
        if script is not None:
            script.run()

    def stop(self, new_status: Status = Status.INVALID) -> None:
        halted = new_status == Status.INVALID and is_active(self.decorated)
        super().stop(new_status)
        if halted:
            self._post("_onHalted")

    def _verdict(self, running: bool) -> Status | None:
        for condition in self.conditions:
            if running:
                if condition.kind == "_while" and not condition.holds():
                    self.feedback_message = f"halted: {condition} is false"
                    self.decorated.stop(Status.INVALID)
                    self._post("_onHalted")
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
