"""BehaviorTree.CPP's standard control, decorator and utility nodes, on py_trees.

Names, ports and semantics follow BT.CPP v4 so trees read the same in Groot2 (DESIGN §4).
Where py_trees already behaves like BT.CPP the node is a thin subclass (Sequence is py_trees'
Sequence with memory, ReactiveSequence the one without; Fallback/ReactiveFallback likewise on
Selector; the three status-flipping decorators). Parallel's thresholds, the looping decorators
and everything timed are written here: py_trees' Timeout reads ``time.monotonic``, whereas a
mission's time comes only from the Clock handed to ``setup(clock=...)`` (DESIGN §3), so the
same tree behaves alike at 1x and at simulator speed-up.

Whenever a node stops with children still RUNNING it stops them with INVALID, so a halted
behaviour's ``terminate(INVALID)`` can leave no command in force (DESIGN §3).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any, ClassVar

import py_trees
from py_trees.common import Status
from py_trees.ports import PortsMixin

from chaser_bt.mission.clock import Clock
from chaser_bt.tree.ports import Port, input_port

__all__ = [
    "Sequence",
    "ReactiveSequence",
    "Fallback",
    "ReactiveFallback",
    "Parallel",
    "Inverter",
    "ForceSuccess",
    "ForceFailure",
    "Repeat",
    "RetryUntilSuccessful",
    "Timeout",
    "Delay",
    "SubTree",
    "AlwaysSuccess",
    "AlwaysFailure",
    "Wait",
    "SetBlackboard",
    "CONTROL_NODES",
    "PortCheck",
]

#: (port name, message) pairs a node reports about statically known port values.
PortCheck = list[tuple[str, str]]


class _ControlPorts(PortsMixin):
    """Port plumbing shared by the built-in nodes: no ports unless declared, static checks."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {}
    OUTPUT_PORTS: ClassVar[dict[str, Port]] = {}

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        """Problems with port values known before the tree runs (literals and defaults)."""
        return []


def _check_count(values: Mapping[str, Any], port: str, minimum: int) -> PortCheck:
    value = values.get(port)
    if isinstance(value, int) and value < minimum:
        return [(port, f"{port} must be >= {minimum}{' (-1 = forever)' if minimum == -1 else ''}, got {value}")]
    return []


def _require_clock(node: py_trees.behaviour.Behaviour, kwargs: Mapping[str, Any]) -> Clock:
    clock = kwargs.get("clock")
    if not isinstance(clock, Clock):
        raise RuntimeError(f"{node.name}: {type(node).__name__} needs a Clock: call setup(clock=...)")
    return clock


# ---------------------------------------------------------------------------------------- composites


class Sequence(_ControlPorts, py_trees.composites.Sequence, register=False):
    """BT.CPP Sequence: children in order; a RUNNING child is resumed, a FAILURE restarts from the first."""

    def __init__(self, name: str) -> None:
        super().__init__(name=name, memory=True)


class ReactiveSequence(_ControlPorts, py_trees.composites.Sequence, register=False):
    """BT.CPP ReactiveSequence: re-ticks earlier children every tick; one failing halts the running child."""

    def __init__(self, name: str) -> None:
        super().__init__(name=name, memory=False)


class Fallback(_ControlPorts, py_trees.composites.Selector, register=False):
    """BT.CPP Fallback: children in order until one succeeds; a RUNNING child is resumed."""

    def __init__(self, name: str) -> None:
        super().__init__(name=name, memory=True)


class ReactiveFallback(_ControlPorts, py_trees.composites.Selector, register=False):
    """BT.CPP ReactiveFallback: re-ticks earlier children every tick; one succeeding or running halts later ones."""

    def __init__(self, name: str) -> None:
        super().__init__(name=name, memory=False)


class Parallel(_ControlPorts, py_trees.composites.Composite, register=False):
    """BT.CPP Parallel: ticks every unfinished child; thresholds of successes and failures decide.

    SUCCESS once ``success_count`` children succeeded, FAILURE once ``failure_count`` failed or
    success became impossible; a negative threshold counts from the number of children
    (-1 = all). Finished children are not ticked again until the Parallel itself finishes.
    """

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

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.status != Status.RUNNING:
            for child in self.children:
                if child.status != Status.INVALID:
                    child.stop(Status.INVALID)
            self._finished = {}
            self.initialise()
        count = len(self.children)
        needed_successes = _threshold(self.get_input("success_count"), count)
        needed_failures = _threshold(self.get_input("failure_count"), count)
        new_status = Status.RUNNING
        for index, child in enumerate(self.children):
            if index not in self._finished:
                yield from child.tick()
                if child.status in (Status.SUCCESS, Status.FAILURE):
                    self._finished[index] = child.status
            successes = sum(1 for s in self._finished.values() if s == Status.SUCCESS)
            failures = len(self._finished) - successes
            if successes >= needed_successes:
                new_status = Status.SUCCESS
                break
            if count - failures < needed_successes or failures >= needed_failures:
                new_status = Status.FAILURE
                break
        if new_status != Status.RUNNING:
            self.stop(new_status)
        self.status = new_status
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        for child in self.children:
            if child.status == Status.RUNNING:
                child.stop(Status.INVALID)
        self._finished = {}
        super().stop(new_status)


def _threshold(value: int, child_count: int) -> int:
    """BT.CPP's threshold: a negative value counts back from the number of children (-1 = all)."""
    return max(child_count + value + 1, 0) if value < 0 else value


# ---------------------------------------------------------------------------------------- decorators


class Inverter(_ControlPorts, py_trees.decorators.Inverter, register=False):
    """BT.CPP Inverter: SUCCESS <-> FAILURE, RUNNING passes through."""


class ForceSuccess(_ControlPorts, py_trees.decorators.FailureIsSuccess, register=False):
    """BT.CPP ForceSuccess: FAILURE becomes SUCCESS, RUNNING passes through."""


class ForceFailure(_ControlPorts, py_trees.decorators.SuccessIsFailure, register=False):
    """BT.CPP ForceFailure: SUCCESS becomes FAILURE, RUNNING passes through."""


class _TickingDecorator(_ControlPorts, py_trees.decorators.Decorator, register=False):
    """A decorator whose ``tick()`` decides when to tick the child and what status to take.

    py_trees' Decorator always ticks its child first and then asks ``update()``; BT.CPP's
    looping and timed decorators need to tick it several times, or not at all.
    """

    def update(self) -> Status:
        """Unused: ``tick()`` sets the status (py_trees declares ``update`` abstract)."""
        return self.status


class _LoopingDecorator(_TickingDecorator, register=False):
    """Ticks its child again within the same tick while ``_again`` says so (BT.CPP's loop).

    With a count of -1 (forever) it returns RUNNING between rounds instead, so a child that
    finishes instantly cannot hang the tick.
    """

    COUNT_PORT: ClassVar[str]
    #: The child status that starts another round (SUCCESS for Repeat, FAILURE for Retry).
    AGAIN_ON: ClassVar[Status]

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour) -> None:
        super().__init__(name=name, child=child)
        self.rounds = 0
        self._limit = 0

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        return _check_count(values, cls.COUNT_PORT, -1)

    def initialise(self) -> None:
        self.rounds = 0
        self._limit = self.get_input(self.COUNT_PORT)

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.status != Status.RUNNING:
            self.initialise()
        new_status = Status.SUCCESS if self.AGAIN_ON == Status.SUCCESS else Status.FAILURE
        while self._limit == -1 or self.rounds < self._limit:
            yield from self.decorated.tick()
            child_status = self.decorated.status
            if child_status != self.AGAIN_ON:
                new_status = child_status
                break
            self.rounds += 1
            if self._limit == -1:
                new_status = Status.RUNNING
                break
        self.feedback_message = f"{self.rounds}/{self._limit if self._limit >= 0 else 'inf'}"
        if new_status != Status.RUNNING:
            self.stop(new_status)
        self.status = new_status
        yield self


class Repeat(_LoopingDecorator, register=False):
    """BT.CPP Repeat: runs the child ``num_cycles`` times while it succeeds; a FAILURE ends it."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "num_cycles": input_port(int, "times to run the child (-1 = forever)"),
    }
    COUNT_PORT = "num_cycles"
    AGAIN_ON = Status.SUCCESS


class RetryUntilSuccessful(_LoopingDecorator, register=False):
    """BT.CPP RetryUntilSuccessful: retries a failing child up to ``num_attempts`` times."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "num_attempts": input_port(int, "attempts before giving up (-1 = forever)"),
    }
    COUNT_PORT = "num_attempts"
    AGAIN_ON = Status.FAILURE


class Timeout(_TickingDecorator, register=False):
    """BT.CPP Timeout: halts the child and FAILS once ``msec`` have passed on the mission clock (0 = never)."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "msec": input_port(int, "milliseconds the child may run (0 = no limit)"),
    }

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour) -> None:
        super().__init__(name=name, child=child)
        self._clock: Clock | None = None
        self._deadline: float | None = None

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        return _check_count(values, "msec", 0)

    def setup(self, **kwargs: Any) -> None:
        self._clock = _require_clock(self, kwargs)

    def initialise(self) -> None:
        msec = self.get_input("msec")
        self._deadline = None if msec <= 0 else _now(self, self._clock) + msec / 1000.0

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.status != Status.RUNNING:
            self.initialise()
        if self._deadline is not None and _now(self, self._clock) >= self._deadline:
            self.feedback_message = f"timed out after {self.get_input('msec')} ms"
            new_status = Status.FAILURE
        else:
            yield from self.decorated.tick()
            new_status = self.decorated.status
        if new_status != Status.RUNNING:
            self.stop(new_status)
        self.status = new_status
        yield self


class Delay(_TickingDecorator, register=False):
    """BT.CPP Delay: RUNNING for ``delay_msec`` on the mission clock, then ticks the child."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "delay_msec": input_port(int, "milliseconds to wait before ticking the child"),
    }

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour) -> None:
        super().__init__(name=name, child=child)
        self._clock: Clock | None = None
        self._start = 0.0

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        return _check_count(values, "delay_msec", 0)

    def setup(self, **kwargs: Any) -> None:
        self._clock = _require_clock(self, kwargs)

    def initialise(self) -> None:
        self._start = _now(self, self._clock)

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.status != Status.RUNNING:
            self.initialise()
        if _now(self, self._clock) - self._start < self.get_input("delay_msec") / 1000.0:
            self.feedback_message = "delaying"
            new_status = Status.RUNNING
        else:
            yield from self.decorated.tick()
            new_status = self.decorated.status
        if new_status != Status.RUNNING:
            self.stop(new_status)
        self.status = new_status
        yield self


def _now(node: py_trees.behaviour.Behaviour, clock: Clock | None) -> float:
    if clock is None:
        raise RuntimeError(f"{node.name}: {type(node).__name__} was not set up with a Clock: call setup(clock=...)")
    return clock.now()


class SubTree(_ControlPorts, py_trees.decorators.PassThrough, register=False):
    """BT.CPP SubTree instance: passes its tree's status through; marks the blackboard scope boundary.

    Not in :data:`CONTROL_NODES`: trees instantiate it with a ``SubTree`` node, never by id.
    """


# ---------------------------------------------------------------------------------------- leaves


class AlwaysSuccess(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP AlwaysSuccess."""

    def update(self) -> Status:
        return Status.SUCCESS


class AlwaysFailure(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP AlwaysFailure."""

    def update(self) -> Status:
        return Status.FAILURE


class Wait(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """RUNNING until ``duration_s`` have passed on the mission clock, then SUCCESS (BT.CPP Sleep, in seconds)."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "duration_s": input_port(float, "seconds to wait"),
    }

    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self._clock: Clock | None = None
        self._start = 0.0

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        value = values.get("duration_s")
        if isinstance(value, float) and not value >= 0.0:
            return [("duration_s", f"duration_s must be >= 0, got {value}")]
        return []

    def setup(self, **kwargs: Any) -> None:
        self._clock = _require_clock(self, kwargs)

    def initialise(self) -> None:
        self._start = _now(self, self._clock)

    def update(self) -> Status:
        elapsed = _now(self, self._clock) - self._start
        duration = self.get_input("duration_s")
        self.feedback_message = f"{elapsed:.1f}/{duration:.1f} s"
        return Status.SUCCESS if elapsed >= duration else Status.RUNNING


class SetBlackboard(_ControlPorts, py_trees.behaviour.Behaviour, register=False):
    """BT.CPP SetBlackboard: writes ``value`` to the entry wired to ``output_key``."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "value": input_port(object, "value to write"),
    }
    OUTPUT_PORTS: ClassVar[dict[str, Port]] = {
        "output_key": Port(data_type=object, required=True, description="blackboard entry to write, as {key}"),
    }

    def update(self) -> Status:
        self._set_output("output_key", self.get_input("value"))
        return Status.SUCCESS


#: Every built-in node, in the order a model export lists them.
CONTROL_NODES: tuple[type, ...] = (
    Sequence,
    ReactiveSequence,
    Fallback,
    ReactiveFallback,
    Parallel,
    Inverter,
    ForceSuccess,
    ForceFailure,
    Repeat,
    RetryUntilSuccessful,
    Timeout,
    Delay,
    AlwaysSuccess,
    AlwaysFailure,
    Wait,
    SetBlackboard,
)
