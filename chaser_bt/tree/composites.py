"""BehaviorTree.CPP v4's control nodes, written on py_trees' Composite with BT.CPP's exact semantics.

py_trees' Sequence and Selector come close (with and without memory) but know no SKIPPED child,
no SequenceWithMemory (resume *at the failed child*), no IfThenElse/WhileDoElse and no Parallel
thresholds, so every control node is written here against BT.CPP's sources and documentation
(behaviortree.dev, "Sequences", "Fallbacks", "Parallel", "Pre and post conditions").

Conventions shared by all of them:

- a child that is INVALID right after its tick was SKIPPED (:mod:`chaser_bt.tree.node_base`);
  a control node whose children were all skipped is itself skipped, as in BT.CPP;
- whenever a node stops with children still RUNNING it halts them (``stop(INVALID)``), so a
  halted flight behaviour's ``terminate(INVALID)`` can leave no command in force (DESIGN §3);
- finished children keep their SUCCESS/FAILURE status until their parent starts again (py_trees'
  habit, so the tick log and ``show`` see what happened); BT.CPP's reset to IDLE only matters for
  when a child is next initialised, and a py_trees node re-initialises whenever it is ticked while
  not RUNNING, so the two agree on every tick.
"""

from __future__ import annotations

import abc
import enum
from collections.abc import Iterator, Mapping
from typing import Any, ClassVar

import py_trees
from py_trees.common import Status

from chaser_bt.tree.expressions import number_text
from chaser_bt.tree.node_base import (
    SKIPPED,
    ControlPorts,
    PortCheck,
    Steps,
    halt,
    is_active,
)
from chaser_bt.tree.ports import Port, input_port

__all__ = [
    "ControlNode",
    "Sequence",
    "SequenceWithMemory",
    "ReactiveSequence",
    "Fallback",
    "ReactiveFallback",
    "AsyncSequence",
    "AsyncFallback",
    "Parallel",
    "ParallelAll",
    "TryCatch",
    "Switch",
    "SWITCHES",
    "IfThenElse",
    "WhileDoElse",
]

Behaviour = py_trees.behaviour.Behaviour


class ControlNode(ControlPorts, py_trees.composites.Composite, register=False):
    """A composite whose :meth:`step` ticks children and returns the new status.

    ``SYMBOL`` is its mark in ``chaser-bt show`` (py_trees' unicode-tree symbols).
    """

    SYMBOL: ClassVar[str] = "{-}"
    #: How many children the node takes, (min, max); None = no upper limit.
    CHILDREN: ClassVar[tuple[int, int | None]] = (1, None)

    def __init__(self, name: str) -> None:
        super().__init__(name=name)

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        low, high = cls.CHILDREN
        if child_count == 0:
            return []  # validation already says a composite needs children
        if child_count < low or (high is not None and child_count > high):
            wanted = f"{low} to {high}" if high is not None and high != low else f"at least {low}"
            return [("", f"{cls.__name__} takes {wanted} children, got {child_count}")]
        return []

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.start()
            self.initialise()
        new_status = yield from self.step()
        if new_status == Status.RUNNING:
            self.status = Status.RUNNING
        else:
            self.stop(new_status)
        yield self

    def start(self) -> None:
        """A new run begins (the node was not RUNNING): reset what the run keeps."""

    @abc.abstractmethod
    def step(self) -> Steps:
        """Tick children (``yield from self.tick_child(c)``) and return this node's new status."""

    def halted(self) -> None:
        """Reset what a halt resets (called by ``stop(INVALID)``)."""

    def stop(self, new_status: Status = Status.INVALID) -> None:
        for child in self.children:
            if is_active(child):
                child.stop(Status.INVALID)
        if new_status == Status.INVALID:
            self.halted()
        super().stop(new_status)

    def tick_child(self, child: Behaviour) -> Steps:
        """Tick one child and return its status; remembers it as the current child for ``tip()``."""
        self.current_child = child
        yield from child.tick()
        return child.status

    def halt_from(self, index: int) -> None:
        """Halt every RUNNING child from ``index`` on."""
        for child in self.children[index:]:
            if is_active(child):
                child.stop(Status.INVALID)


def _reset_children(node: ControlNode, first: int = 0) -> None:
    for child in node.children[first:]:
        halt(child)


class Sequence(ControlNode, register=False):
    """BT.CPP Sequence: children in order; a RUNNING child is resumed, a FAILURE restarts from the first."""

    SYMBOL = "{-}"
    #: After a FAILURE, resume at the failed child (SequenceWithMemory) instead of the first.
    RESUME_AFTER_FAILURE: ClassVar[bool] = False
    #: Return RUNNING after a child that succeeded at once (AsyncSequence, SequenceWithMemory):
    #: BT.CPP 4.x emits a wake-up and gives the tick back, so a reactive parent re-checks its
    #: conditions between children.
    YIELD_BETWEEN_CHILDREN: ClassVar[bool] = False

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self.index = 0
        self.all_skipped = True

    def start(self) -> None:
        self.all_skipped = True
        _reset_children(self, self.index)

    def step(self) -> Steps:
        while self.index < len(self.children):
            child = self.children[self.index]
            was_running = is_active(child)
            status = yield from self.tick_child(child)
            self.all_skipped &= status == SKIPPED
            if status == Status.RUNNING:
                return Status.RUNNING
            if status == Status.FAILURE:
                if not self.RESUME_AFTER_FAILURE:
                    self.index = 0
                return Status.FAILURE
            self.index += 1
            if (
                status == Status.SUCCESS
                and self.YIELD_BETWEEN_CHILDREN
                and not was_running
                and self.index < len(self.children)
            ):
                return Status.RUNNING
        self.index = 0
        return SKIPPED if self.all_skipped else Status.SUCCESS

    def halted(self) -> None:
        if not self.RESUME_AFTER_FAILURE:
            self.index = 0


class SequenceWithMemory(Sequence, register=False):
    """BT.CPP SequenceWithMemory: like Sequence, but after a FAILURE the next run resumes at the failed child.

    Children that already succeeded are not run again until the whole sequence succeeds; a halt
    keeps the position too (BT.CPP v4).
    """

    SYMBOL = "{-m}"
    RESUME_AFTER_FAILURE = True
    YIELD_BETWEEN_CHILDREN = True


class AsyncSequence(Sequence, register=False):
    """BT.CPP AsyncSequence: a Sequence that gives the tick back (RUNNING) after each child that succeeded at once."""

    SYMBOL = "{-a}"
    YIELD_BETWEEN_CHILDREN = True


class _Reactive(ControlNode, register=False):
    """Re-ticks every child from the first on every tick (BT.CPP's reactive nodes).

    A RUNNING child halts every later one and makes the node RUNNING; a child returning
    ``DECIDES`` ends the node with that status; otherwise ``OTHERWISE`` (SKIPPED if all skipped).
    """

    DECIDES: Status
    OTHERWISE: Status

    def start(self) -> None:
        _reset_children(self)

    def step(self) -> Steps:
        all_skipped = True
        for index, child in enumerate(self.children):
            status = yield from self.tick_child(child)
            all_skipped &= status == SKIPPED
            if status == Status.RUNNING:
                self.halt_from(index + 1)
                return Status.RUNNING
            if status == self.DECIDES:
                return status
        return SKIPPED if all_skipped else self.OTHERWISE


class ReactiveSequence(_Reactive, register=False):
    """BT.CPP ReactiveSequence: re-ticks every child from the first on every tick; a failure halts the running one."""

    SYMBOL = "[-]"
    DECIDES, OTHERWISE = Status.FAILURE, Status.SUCCESS


class Fallback(ControlNode, register=False):
    """BT.CPP Fallback: children in order until one succeeds; a RUNNING child is resumed."""

    SYMBOL = "{o}"

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self.index = 0
        self.all_skipped = True

    def start(self) -> None:
        self.all_skipped = True
        _reset_children(self)

    #: Return RUNNING after a child that failed at once (AsyncFallback).
    YIELD_BETWEEN_CHILDREN: ClassVar[bool] = False

    def step(self) -> Steps:
        while self.index < len(self.children):
            child = self.children[self.index]
            was_running = is_active(child)
            status = yield from self.tick_child(child)
            self.all_skipped &= status == SKIPPED
            if status == Status.RUNNING:
                return Status.RUNNING
            if status == Status.SUCCESS:
                self.index = 0
                return Status.SUCCESS
            self.index += 1
            if (
                status == Status.FAILURE
                and self.YIELD_BETWEEN_CHILDREN
                and not was_running
                and self.index < len(self.children)
            ):
                return Status.RUNNING
        self.index = 0
        return SKIPPED if self.all_skipped else Status.FAILURE

    def halted(self) -> None:
        self.index = 0


class AsyncFallback(Fallback, register=False):
    """BT.CPP AsyncFallback: a Fallback that gives the tick back (RUNNING) after each child that failed at once."""

    SYMBOL = "{o-a}"
    YIELD_BETWEEN_CHILDREN = True


class ReactiveFallback(_Reactive, register=False):
    """BT.CPP ReactiveFallback: re-ticks from the first child every tick; a higher child succeeding or running halts a lower one."""

    SYMBOL = "[o]"
    DECIDES, OTHERWISE = Status.SUCCESS, Status.FAILURE


class Parallel(ControlNode, register=False):
    """BT.CPP Parallel: ticks every unfinished child; thresholds of successes and failures decide.

    SUCCESS once ``success_count`` children succeeded, FAILURE once ``failure_count`` failed or
    success became impossible; a negative threshold counts from the number of children
    (-1 = all). Finished children are not ticked again until the Parallel itself finishes.
    Skipped children count towards a negative ``success_count``; all skipped = skipped.
    """

    SYMBOL = "/_/"
    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "success_count": input_port(int, "successes needed for SUCCESS (-1 = all children)", default=-1),
        "failure_count": input_port(int, "failures that make FAILURE (-1 = all children)", default=1),
    }

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self._finished: dict[int, Status] = {}

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        problems = []
        for port in ("success_count", "failure_count"):
            value = values.get(port)
            if isinstance(value, int) and _threshold(value, child_count) > child_count:
                children = "child" if child_count == 1 else "children"
                problems.append((port, f"{port} {value} can never be reached with {child_count} {children}"))
        return problems

    def start(self) -> None:
        _reset_children(self)
        self._finished = {}

    def step(self) -> Steps:
        count = len(self.children)
        success_port = self.get_input("success_count")
        needed_successes = _threshold(success_port, count)
        needed_failures = _threshold(self.get_input("failure_count"), count)
        skipped = 0
        for index, child in enumerate(self.children):
            if index not in self._finished:
                status = yield from self.tick_child(child)
                if status in (Status.SUCCESS, Status.FAILURE):
                    self._finished[index] = status
                elif status == SKIPPED:
                    skipped += 1
            successes = sum(1 for s in self._finished.values() if s == Status.SUCCESS)
            failures = len(self._finished) - successes
            if successes >= needed_successes or (success_port < 0 and successes + skipped >= needed_successes):
                return Status.SUCCESS
            if count - failures < needed_successes or failures >= needed_failures:
                return Status.FAILURE
        return SKIPPED if skipped == count else Status.RUNNING

    def stop(self, new_status: Status = Status.INVALID) -> None:
        self._finished = {}
        super().stop(new_status)


class ParallelAll(ControlNode, register=False):
    """BT.CPP ParallelAll: ticks every unfinished child until all have finished.

    Then FAILURE if at least ``max_failures`` failed (negative: counted back from the number of
    children), else SUCCESS; all skipped = skipped.
    """

    SYMBOL = "/A/"
    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "max_failures": input_port(int, "failures that make FAILURE once all finished (-1 = all children)", default=1),
    }

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self._finished: dict[int, Status] = {}

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        value = values.get("max_failures")
        if isinstance(value, int) and _threshold(value, child_count) > child_count:
            return [("max_failures", f"max_failures {value} can never be reached with {child_count} children")]
        return []

    def start(self) -> None:
        _reset_children(self)
        self._finished = {}

    def step(self) -> Steps:
        count = len(self.children)
        needed_failures = _threshold(self.get_input("max_failures"), count)
        skipped = 0
        for index, child in enumerate(self.children):
            if index in self._finished:
                continue
            status = yield from self.tick_child(child)
            if status in (Status.SUCCESS, Status.FAILURE):
                self._finished[index] = status
            elif status == SKIPPED:
                skipped += 1
        if skipped == count:
            return SKIPPED
        if skipped + len(self._finished) >= count:
            failures = sum(1 for s in self._finished.values() if s == Status.FAILURE)
            self._finished = {}
            return Status.FAILURE if failures >= needed_failures else Status.SUCCESS
        return Status.RUNNING

    def stop(self, new_status: Status = Status.INVALID) -> None:
        self._finished = {}
        super().stop(new_status)


class TryCatch(ControlNode, register=False):
    """BT.CPP TryCatch: the first children run as a Sequence; if one fails, the last child (the catch) runs, then FAILURE.

    With ``catch_on_halt`` a halt while the try children run also ticks the catch child once.
    """

    SYMBOL = "{!}"
    CHILDREN = (2, None)
    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "catch_on_halt": input_port(bool, "also run the catch child when halted during the try children", default=False),
    }

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self.index = 0
        self.in_catch = False
        self.skipped = 0

    def start(self) -> None:
        _reset_children(self)
        self.skipped = 0
        self.in_catch = False

    def step(self) -> Steps:
        catch = self.children[-1]
        if self.in_catch:
            status = yield from self.tick_child(catch)
            if status == Status.RUNNING:
                return Status.RUNNING
            self.index, self.in_catch = 0, False
            return Status.FAILURE
        tries = len(self.children) - 1
        while self.index < tries:
            status = yield from self.tick_child(self.children[self.index])
            if status == Status.RUNNING:
                return Status.RUNNING
            if status == Status.FAILURE:
                _reset_children(self)
                self.index, self.in_catch = 0, True
                return (yield from self.step())
            self.skipped += status == SKIPPED
            self.index += 1
        all_skipped = self.skipped == tries
        self.index, self.skipped = 0, 0
        return SKIPPED if all_skipped else Status.SUCCESS

    def stop(self, new_status: Status = Status.INVALID) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING and not self.in_catch:
            if self.get_input("catch_on_halt"):
                for child in self.children[:-1]:
                    halt_running(child)
                catch = self.children[-1]
                for _ in catch.tick():
                    pass
                halt_running(catch)
        self.index, self.skipped, self.in_catch = 0, 0, False
        super().stop(new_status)


class Switch(ControlNode, register=False):
    """BT.CPP SwitchN: ticks the child of the first ``case_i`` equal to ``variable``, else the last (default) child.

    A change of case halts the child that was running. Subclasses fix the number of cases.
    """

    SYMBOL = "<S>"
    CASES: ClassVar[int] = 0

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self.running = -1

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.CASES:
            cls.CHILDREN = (cls.CASES + 1, cls.CASES + 1)
            cls.INPUT_PORTS = {
                "variable": input_port(object, "the value to switch on", required=False),
                **{f"case_{i}": input_port(str, f"the value that selects child {i}", required=False)
                   for i in range(1, cls.CASES + 1)},
            }

    def start(self) -> None:
        _reset_children(self)
        self.running = -1

    def step(self) -> Steps:
        match = self.CASES
        variable = _input_or_none(self, "variable")
        if variable is not None:
            for index in range(self.CASES):
                case = _input_or_none(self, f"case_{index + 1}")
                if case is not None and _same_text(variable, case):
                    match = index
                    break
        if self.running not in (-1, match):
            halt_running(self.children[self.running])
        status = yield from self.tick_child(self.children[match])
        if status == SKIPPED:
            self.running = -1
        elif status == Status.RUNNING:
            self.running = match
        else:
            self.running = -1
        return status

    def halted(self) -> None:
        self.running = -1


def _input_or_none(node: ControlNode, port: str) -> Any:
    try:
        return node.get_input(port)
    except (KeyError, py_trees.ports.NoDataAvailable):
        return None


def _same_text(variable: Any, case: str) -> bool:
    """BT.CPP's CheckStringEquality: equal as text, or as numbers when both read as numbers."""
    text = variable.name if isinstance(variable, enum.Enum) else variable
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        text = number_text(float(text))
    text = str(text)
    if text == case:
        return True
    try:
        return abs(float(text) - float(case)) < 1e-9
    except ValueError:
        return False


def _make_switches() -> tuple[type[Switch], ...]:
    made = []
    for cases in range(2, 7):
        doc = f"BT.CPP Switch{cases}: {cases} cases and a default child."
        namespace = {"CASES": cases, "__doc__": doc, "__module__": __name__}
        cls = type(f"Switch{cases}", (Switch,), namespace, register=False)
        made.append(cls)
    return tuple(made)


SWITCHES = _make_switches()


def _threshold(value: int, child_count: int) -> int:
    """BT.CPP's threshold: a negative value counts back from the number of children (-1 = all)."""
    return max(child_count + value + 1, 0) if value < 0 else value


class IfThenElse(ControlNode, register=False):
    """BT.CPP IfThenElse: the first child is the condition; SUCCESS runs the second, FAILURE the third.

    With two children a failed condition makes the node FAIL. The condition is not re-evaluated
    while the chosen branch is RUNNING (use WhileDoElse for that).
    """

    SYMBOL = "<?>"
    CHILDREN = (2, 3)

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self.branch = 0

    def start(self) -> None:
        _reset_children(self)
        self.branch = 0

    def step(self) -> Steps:
        if self.branch == 0:
            condition = yield from self.tick_child(self.children[0])
            if condition == Status.RUNNING:
                return Status.RUNNING
            if condition == Status.SUCCESS:
                self.branch = 1
            elif condition == Status.FAILURE and len(self.children) == 3:
                self.branch = 2
            elif condition == Status.FAILURE:
                return condition  # FAILURE without an else branch
            else:
                raise RuntimeError(f"{self.name}: IfThenElse's condition was skipped (BT.CPP throws)")
        status = yield from self.tick_child(self.children[self.branch])
        if status != Status.RUNNING:
            self.branch = 0
        return status

    def halted(self) -> None:
        self.branch = 0


class WhileDoElse(ControlNode, register=False):
    """BT.CPP WhileDoElse: re-evaluates the condition every tick; SUCCESS runs the second child, FAILURE the third.

    Switching branch halts the other one; with two children a failed condition makes the node FAIL.
    """

    SYMBOL = "<*>"
    CHILDREN = (2, 3)

    def start(self) -> None:
        _reset_children(self)

    def step(self) -> Steps:
        condition = yield from self.tick_child(self.children[0])
        if condition == Status.RUNNING:
            return Status.RUNNING
        if condition == Status.SUCCESS:
            if len(self.children) == 3:
                halt_running(self.children[2])
            return (yield from self.tick_child(self.children[1]))
        if condition == Status.FAILURE:
            halt_running(self.children[1])
            if len(self.children) == 3:
                return (yield from self.tick_child(self.children[2]))
            return Status.FAILURE
        raise RuntimeError(f"{self.name}: WhileDoElse's condition was skipped (BT.CPP throws)")


def halt_running(node: Behaviour) -> None:
    if is_active(node):
        node.stop(Status.INVALID)
