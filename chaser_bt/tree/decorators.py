"""BehaviorTree.CPP v4's decorators on py_trees' Decorator, with BT.CPP's semantics.

py_trees' Decorator always ticks its child once and then asks ``update()``; BT.CPP's looping and
timed decorators tick it several times, or not at all, so each decorator here implements
:meth:`DecoratorNode.step` instead. Time comes only from the mission Clock handed to
``setup(clock=...)`` (DESIGN §3), never from ``time.monotonic`` as py_trees' own Timeout does.
A skipped child (INVALID right after its tick, see :mod:`chaser_bt.tree.node_base`) makes the
decorator skipped too, as in BT.CPP.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any, ClassVar

import py_trees
from py_trees.common import Status

from chaser_bt.clock import Clock
from chaser_bt.tree.entry_versions import entry_version
from chaser_bt.tree.expressions import ExpressionError, copy_into, truth
from chaser_bt.tree.node_base import (
    SKIPPED,
    ControlPorts,
    PortCheck,
    Steps,
    check_count,
    is_active,
    now,
    require_clock,
)
from chaser_bt.tree.ports import ANY_TYPE, BtcppInputs, Port, input_port, output_port

__all__ = [
    "DecoratorNode",
    "Inverter",
    "ForceSuccess",
    "ForceFailure",
    "Repeat",
    "RetryUntilSuccessful",
    "Timeout",
    "Delay",
    "RunOnce",
    "KeepRunningUntilFailure",
    "Precondition",
    "SkipUnlessUpdated",
    "WaitValueUpdate",
    "LoopInt",
    "LoopBool",
    "LoopDouble",
    "LoopString",
    "SubTree",
]

Behaviour = py_trees.behaviour.Behaviour


class DecoratorNode(BtcppInputs, ControlPorts, py_trees.decorators.Decorator, register=False):
    """A decorator whose :meth:`step` decides when to tick the child and returns the new status.

    Its ports convert a blackboard value as BT.CPP's ``getInput`` does (:class:`BtcppInputs`).

    When it returns SKIPPED (its child was skipped) it keeps its state, ``suspended``, as a BT.CPP
    decorator stays RUNNING: the next tick resumes (a Repeat's count, a Delay's timer), a halt
    resets it (:func:`~chaser_bt.tree.node_base.is_active`).
    """

    #: Keep the run's state when the decorator returns SKIPPED (BT.CPP's decorators do).
    KEEPS_STATE_WHEN_SKIPPED: ClassVar[bool] = True
    suspended = False

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING and not self.suspended:
            self.initialise()
        self.suspended = False
        new_status = yield from self.step()
        if new_status == Status.RUNNING:
            self.status = Status.RUNNING
        elif new_status == SKIPPED and self.KEEPS_STATE_WHEN_SKIPPED and not is_active(self.decorated):
            self.status = SKIPPED
            self.suspended = True
        else:
            self.stop(new_status)
        yield self

    def step(self) -> Steps:
        yield from self.decorated.tick()
        return self.decorated.status

    def update(self) -> Status:
        """Unused: ``tick()`` sets the status (py_trees declares ``update`` abstract)."""
        return self.status

    def stop(self, new_status: Status = Status.INVALID) -> None:
        # Halt a running child; reset a finished one on a halt. A child that never ran is left
        # alone, so it sees no spurious terminate().
        self.terminate(new_status)
        self.suspended = False
        child = self.decorated
        if is_active(child) or (new_status == Status.INVALID and child.status != Status.INVALID):
            child.stop(Status.INVALID)
        self.status = new_status
        self.iterator = self.tick()


class Inverter(DecoratorNode, register=False):
    """BT.CPP Inverter: SUCCESS <-> FAILURE; RUNNING and SKIPPED pass through."""

    def step(self) -> Steps:
        status = yield from super().step()
        flipped = {Status.SUCCESS: Status.FAILURE, Status.FAILURE: Status.SUCCESS}.get(status, status)
        self.feedback_message = (
            f"{status.name.lower()} -> {flipped.name.lower()}" if flipped != status else self.decorated.feedback_message
        )
        return flipped


class ForceSuccess(DecoratorNode, register=False):
    """BT.CPP ForceSuccess: a finished child's status becomes SUCCESS; RUNNING and SKIPPED pass through."""

    def step(self) -> Steps:
        status = yield from super().step()
        self.feedback_message = "failure is success" if status == Status.FAILURE else self.decorated.feedback_message
        return Status.SUCCESS if status == Status.FAILURE else status


class ForceFailure(DecoratorNode, register=False):
    """BT.CPP ForceFailure: a finished child's status becomes FAILURE; RUNNING and SKIPPED pass through."""

    def step(self) -> Steps:
        status = yield from super().step()
        self.feedback_message = "success is failure" if status == Status.SUCCESS else self.decorated.feedback_message
        return Status.FAILURE if status == Status.SUCCESS else status


class _LoopingDecorator(DecoratorNode, register=False):
    """Runs its child again while it returns ``AGAIN_ON``, up to the count (-1 = forever): BT.CPP 4.x's loop.

    A child that finished at once (it was not RUNNING) gives the tick back: the decorator returns
    RUNNING before the next round, as BT.CPP 4.x does (it emits a wake-up), so a reactive parent
    re-checks its conditions between rounds and an instant child never hangs a tick. A child that
    finishes after running starts its next round in the same tick. A skipped child makes the
    decorator skipped.

    The count is read at the start of every tick, as BT.CPP reads it (and Retry again after each
    failed attempt): a count the child lowers below the rounds already run ends the loop.
    """

    COUNT_PORT: ClassVar[str]
    #: The child status that starts another round (SUCCESS for Repeat, FAILURE for Retry).
    AGAIN_ON: ClassVar[Status]
    #: Read the count again after each round (BT.CPP's RetryNode does; its RepeatNode does not).
    READ_AFTER_ROUND: ClassVar[bool] = False

    def __init__(self, name: str, child: Behaviour) -> None:
        super().__init__(name=name, child=child)
        self.rounds = 0
        self._limit = 0

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        return check_count(values, cls.COUNT_PORT, -1)

    def initialise(self) -> None:
        self.rounds = 0

    def step(self) -> Steps:
        self._limit = self.get_input(self.COUNT_PORT)
        new_status = Status.SUCCESS if self.AGAIN_ON == Status.SUCCESS else Status.FAILURE
        while self._limit == -1 or self.rounds < self._limit:
            was_running = is_active(self.decorated)
            yield from self.decorated.tick()
            child_status = self.decorated.status
            if child_status != self.AGAIN_ON:
                new_status = child_status
                break
            self.rounds += 1
            if self.READ_AFTER_ROUND:
                try:
                    self._limit = self.get_input(self.COUNT_PORT)
                except (TypeError, KeyError, py_trees.ports.NoDataAvailable):
                    pass  # BT.CPP ignores this read's failure and keeps the count it had
            if not was_running and (self._limit == -1 or self.rounds < self._limit):
                new_status = Status.RUNNING
                break
        self.feedback_message = f"{self.rounds}/{self._limit if self._limit >= 0 else 'inf'}"
        return new_status


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
    READ_AFTER_ROUND = True


class _ClockedDecorator(DecoratorNode, register=False):
    def __init__(self, name: str, child: Behaviour) -> None:
        super().__init__(name=name, child=child)
        self._clock: Clock | None = None

    def setup(self, **kwargs: Any) -> None:
        self._clock = require_clock(self, kwargs)


class Timeout(_ClockedDecorator, register=False):
    """BT.CPP Timeout: halts the child and FAILS once ``msec`` have passed on the mission clock (0 = never)."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "msec": input_port(int, "milliseconds the child may run (0 = no limit)", btcpp_type="unsigned"),
    }

    def __init__(self, name: str, child: Behaviour) -> None:
        super().__init__(name=name, child=child)
        self._deadline: float | None = None

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        return check_count(values, "msec", 0)

    def initialise(self) -> None:
        msec = self.get_input("msec")
        self._deadline = None if msec <= 0 else now(self, self._clock) + msec / 1000.0

    def step(self) -> Steps:
        if self._deadline is not None and now(self, self._clock) >= self._deadline:
            self.feedback_message = f"timed out after {self.get_input('msec')} ms"
            return Status.FAILURE
        return (yield from super().step())


class Delay(_ClockedDecorator, register=False):
    """BT.CPP Delay: RUNNING for ``delay_msec`` on the mission clock, then ticks the child."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "delay_msec": input_port(int, "milliseconds to wait before ticking the child", btcpp_type="unsigned"),
    }

    def __init__(self, name: str, child: Behaviour) -> None:
        super().__init__(name=name, child=child)
        self._start = 0.0

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        return check_count(values, "delay_msec", 0)

    def initialise(self) -> None:
        self._start = now(self, self._clock)

    def step(self) -> Steps:
        if now(self, self._clock) - self._start < self.get_input("delay_msec") / 1000.0:
            self.feedback_message = "delaying"
            return Status.RUNNING
        return (yield from super().step())


class RunOnce(DecoratorNode, register=False):
    """BT.CPP RunOnce: runs the child to completion once; afterwards SKIPPED (``then_skip``) or its first result."""

    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "then_skip": input_port(bool, "after the first run: skip (true) or repeat the first result (false)", default=True),
    }

    def __init__(self, name: str, child: Behaviour) -> None:
        super().__init__(name=name, child=child)
        self.result: Status | None = None

    def step(self) -> Steps:
        if self.result is not None:
            self.feedback_message = f"ran once: {self.result.name}"
            try:
                skip = self.get_input("then_skip")
            except (TypeError, KeyError, py_trees.ports.NoDataAvailable):
                skip = True  # BT.CPP: a then_skip that cannot be read counts as true
            return SKIPPED if skip else self.result
        status = yield from super().step()
        if status in (Status.SUCCESS, Status.FAILURE):
            self.result = status
        return status


class KeepRunningUntilFailure(DecoratorNode, register=False):
    """BT.CPP KeepRunningUntilFailure: RUNNING while the child succeeds (restarted each tick) or is skipped, else FAILURE."""

    def step(self) -> Steps:
        status = yield from super().step()
        return Status.FAILURE if status == Status.FAILURE else Status.RUNNING


class Precondition(DecoratorNode, register=False):
    """BT.CPP Precondition: ticks the child while the script ``if`` holds (checked until it runs), else returns ``else``."""

    SCRIPT_PORTS: ClassVar[tuple[str, ...]] = ("if",)
    INPUT_PORTS: ClassVar[dict[str, Port]] = {
        "if": input_port(str, "the script that must be true to tick the child"),
        "else": input_port(
            str, "status returned when it is false: SUCCESS, FAILURE, SKIPPED or RUNNING", default="FAILURE",
            btcpp_type="NodeStatus",
        ),
    }

    def __init__(self, name: str, child: Behaviour) -> None:
        super().__init__(name=name, child=child)
        self.scripts: dict[str, Any] = {}
        self._running = False

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> PortCheck:
        value = values.get("else")
        if isinstance(value, str) and value.upper() not in _STATUS_NAMES:
            return [("else", f"else must be one of {', '.join(_STATUS_NAMES)}, got {value!r}")]
        return []

    def step(self) -> Steps:
        if not self._running:
            self._running = truth(self.scripts["if"].run())
        if not self._running:
            return _STATUS_NAMES[self.get_input("else").upper()]
        status = yield from super().step()
        if status in (Status.SUCCESS, Status.FAILURE):
            self._running = False
        return status

    def stop(self, new_status: Status = Status.INVALID) -> None:
        if new_status == Status.INVALID:
            self._running = False
        super().stop(new_status)


_STATUS_NAMES = {"SUCCESS": Status.SUCCESS, "FAILURE": Status.FAILURE, "SKIPPED": SKIPPED, "RUNNING": Status.RUNNING}


class _EntryUpdated(DecoratorNode, register=False):
    """Ticks the child only if the entry named by ``entry`` was written since the node last looked (EntryUpdatedDecorator)."""

    KEY_NAME_PORTS: ClassVar[tuple[str, ...]] = ("entry",)
    BRACES_ARE_OLD_FORM: ClassVar[bool] = False
    INPUT_PORTS: ClassVar[dict[str, Port]] = {}
    OUTPUT_PORTS: ClassVar[dict[str, Port]] = {
        "entry": Port(data_type=object, required=True, description="name of the blackboard entry to watch"),
    }
    #: What the decorator returns when the entry was not updated.
    IF_NOT_UPDATED: ClassVar[Status]

    def __init__(self, name: str, child: Behaviour) -> None:
        super().__init__(name=name, child=child)
        self._seen = 0
        self._child_running = False

    def step(self) -> Steps:
        if not self._child_running:
            version = entry_version(self._get_blackboard_key("entry"))
            previous = self._seen
            if version is not None:
                self._seen = version
            if version is None or version == previous:
                return self.IF_NOT_UPDATED
        status = yield from super().step()
        self._child_running = status == Status.RUNNING
        return status

    def stop(self, new_status: Status = Status.INVALID) -> None:
        if new_status == Status.INVALID:
            self._child_running = False
        super().stop(new_status)


class SkipUnlessUpdated(_EntryUpdated, register=False):
    """BT.CPP SkipUnlessUpdated: SKIPPED unless ``entry`` was written since the last look; then ticks the child."""

    IF_NOT_UPDATED = SKIPPED


class WaitValueUpdate(_EntryUpdated, register=False):
    """BT.CPP WaitValueUpdate: RUNNING until ``entry`` is written; then ticks the child."""

    IF_NOT_UPDATED = Status.RUNNING


class Loop(DecoratorNode, register=False):
    """BT.CPP LoopInt/LoopBool/LoopDouble/LoopString: pops the next item of ``queue`` into ``value`` and ticks the child.

    RUNNING after each item the child finishes on (even the last: the next tick finds the queue
    empty and returns ``if_empty``, SUCCESS by default); a child FAILURE ends the loop with
    FAILURE. ``queue`` is a literal list (``1;2;3``), a blackboard list, or blackboard text
    (``'4;5'``, converted item by item as BT.CPP does); it is read when the loop starts.
    """

    ITEM: ClassVar[type] = object

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.ITEM is not object:
            cls.INPUT_PORTS = {
                "queue": input_port(list[cls.ITEM], "the items, in order", btcpp_type=ANY_TYPE),
                "if_empty": input_port(
                    str, "status when the queue is empty: SUCCESS, FAILURE or SKIPPED", default="SUCCESS",
                    btcpp_type="NodeStatus",
                ),
            }
            cls.OUTPUT_PORTS = {"value": output_port(cls.ITEM, "the current item")}

    def __init__(self, name: str, child: Behaviour) -> None:
        super().__init__(name=name, child=child)
        self._queue: list[Any] | None = None
        self._child_running = False

    def initialise(self) -> None:
        self._child_running = False
        self._queue = list(self.get_input("queue"))

    def step(self) -> Steps:
        popped = False
        if not self._child_running:
            assert self._queue is not None
            if self._queue:
                self._write_value(self._queue.pop(0))
                popped = True
        if not popped and not self._child_running:
            return _STATUS_NAMES[self.get_input("if_empty").upper()]
        status = yield from super().step()
        self._child_running = status == Status.RUNNING
        return Status.FAILURE if status == Status.FAILURE else Status.RUNNING


    def _write_value(self, item: Any) -> None:
        """BT.CPP's ``setOutput``: an entry that holds a value keeps its type (``Any::copyInto``).

        LoopDouble's 1.0 into an entry a script set to the int 3 is stored as the int 1; text into
        a number entry (or a number into a text one) raises, as BT.CPP throws.
        """
        try:
            current = py_trees.blackboard.Blackboard.get(self._get_blackboard_key("value"))
        except KeyError:
            self._set_output("value", item)
            return
        try:
            value = copy_into(item, current)
        except ExpressionError as e:
            raise TypeError(f"{self.name}: output port 'value': {e}") from None
        self.blackboard_client.set("value", value)


class LoopInt(Loop, register=False):
    """BT.CPP LoopInt."""

    ITEM = int


class LoopBool(Loop, register=False):
    """BT.CPP LoopBool."""

    ITEM = bool


class LoopDouble(Loop, register=False):
    """BT.CPP LoopDouble."""

    ITEM = float


class LoopString(Loop, register=False):
    """BT.CPP LoopString."""

    ITEM = str


class SubTree(DecoratorNode, register=False):
    """BT.CPP SubTree instance: passes its tree's status through; marks the blackboard scope boundary.

    Not in :data:`~chaser_bt.tree.control.CONTROL_NODES`: trees instantiate it with a ``SubTree``
    node, never by id.
    """
