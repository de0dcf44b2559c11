"""The mission runner: ticks a validated tree against a vehicle at a fixed rate on a Clock.

The runner owns the wiring every mission shares, so behaviours stay thin:

* shared resources reach behaviours through py_trees' ``setup(link=..., clock=...)``;
* the vehicle's state is written to the blackboard under :data:`VEHICLE_STATE_KEY` (and the mission
  time under :data:`MISSION_TIME_KEY`) before every tick, so leaves read it through their ports;
* ticks happen when the clock says one is due, never from a sleep, so the same loop runs lock-step
  inside a rehearsal (:meth:`tick_if_due`) and in real time against a vehicle (:meth:`run`);
* :meth:`run` ticks only once the vehicle has reported what every tree reads: a HEARTBEAT,
  SYS_STATUS (battery, pre-arm health) and a position in the mission's frame (GLOBAL_POSITION_INT and
  home). A freshly booted ArduCopter sends HEARTBEATs long before its home is set, and a tree
  ticked on that reads "battery unknown" and "disarmed on the ground". The wait is bounded
  (``telemetry_timeout_s`` on the link's clock) and ends in an error naming what never came;
* a stop (success, failure, Ctrl-C, an exception in a leaf, a disarm in the air) halts the tree,
  which makes every running leaf terminate and hover, then sends the hover command once more for
  good measure (paper section 3.2: hover on exit); :meth:`run` then watches the hold take effect
  (:meth:`confirm_hold`);
* every run ends in one outcome (:mod:`chaser_bt.mission.outcome`): the root's status judged with
  what a :class:`~chaser_bt.mission.outcome.FlightWitness` saw of the vehicle beside the tree.
"""

from __future__ import annotations

import enum
import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np
import py_trees

from chaser_bt.clock import Clock
from chaser_bt.mission.outcome import PHASE_KEY, FlightWitness, Outcome, Verdict, judge
from chaser_bt.mission.resources import missing_resources
from chaser_bt.mission.retask import (
    Retask,
    RetaskRejected,
    RetaskRequest,
    prepare_subtree,
    prepare_tree,
    spliced_hash,
    tree_hash,
)
from chaser_bt.tree import MissionTree, NodeKind
from chaser_bt.tree.documents import merge_includes, parse_document
from chaser_bt.tree.model import TreeDocument
from chaser_bt.tree.node_base import is_active
from chaser_bt.tree.splice import Splice
from chaser_bt.vehicle import VehicleError, VehicleLink, VehicleQuiet

__all__ = ["MISSION_TIME_KEY", "VEHICLE_STATE_KEY", "MissionRunner", "RunResult", "RunStatus", "StatusChange"]

log = logging.getLogger(__name__)

VEHICLE_STATE_KEY = "/vehicle/state"
MISSION_TIME_KEY = "/mission/time_s"

#: The class attribute of the leaves that command the aircraft (behaviours.base.CommandingBehaviour): a
#: subtree retask that halts one of them running holds the aircraft.
_COMMANDING_MARK = "HOVER_ON_HALT"

# Modes in which the mission's own hold (a GUIDED position target, centred sticks) keeps the aircraft.
_MISSION_HOLD_MODES = ("GUIDED", "STABILIZE", "ALT_HOLD")

# What the first tick needs from the vehicle besides its home: message type, and why.
_FIRST_TICK_NEEDS = (
    ("HEARTBEAT", "mode and armed state"),
    ("SYS_STATUS", "battery and pre-arm health"),
    ("GLOBAL_POSITION_INT", "position"),
)


class RunStatus(enum.Enum):
    """How a mission run ended."""

    SUCCESS = "success"  # the root returned SUCCESS
    FAILURE = "failure"  # the root returned FAILURE
    INTERRUPTED = "interrupted"  # stopped from outside (Ctrl-C, time limit)
    ERROR = "error"  # a leaf raised, or the vehicle link failed


@dataclass
class RunResult:
    """Outcome of :meth:`MissionRunner.run` (or of a lock-step rehearsal)."""

    status: RunStatus
    ticks: int
    message: str = ""
    verdict: Verdict | None = None  # the flight's outcome (:mod:`chaser_bt.mission.outcome`)
    hand_back: str = ""  # what :meth:`MissionRunner.confirm_hold` saw ("" when the aircraft was not in the air)


@dataclass(frozen=True)
class StatusChange:
    """One entry of the tick log: a node's status changed at mission time ``t``."""

    t: float
    node: str  # the node's instance name
    old: str  # py_trees status names: INVALID, RUNNING, SUCCESS, FAILURE
    new: str


@dataclass
class _TickStats:
    count: int = 0
    wall_ms: list[float] = field(default_factory=list)


class MissionRunner:
    """Tick a :class:`MissionTree` against a :class:`VehicleLink` at ``rate_hz`` on ``clock``.

    Args:
        tree: a validated mission tree (see :func:`chaser_bt.tree.load_tree`).
        link: the vehicle link; polled by :meth:`run`, or by the caller in lock-step use.
        clock: mission time; vehicle time against the simulator, wall time on a real aircraft.
        rate_hz: tick rate in clock seconds.
        resources: more shared objects for behaviours' ``setup()`` beside ``link`` and ``clock``
            (e.g. ``radar=RadarFeed(...)``); a behaviour that needs one says so at setup.
        perf_counter: wall timer used only to measure how long a tick takes (diagnostics).
        telemetry_timeout_s: how long :meth:`run` waits, on the link's clock, for the telemetry the
            first tick needs (:meth:`waiting_for`); ArduCopter sets home ~40 s after boot.
    """

    def __init__(
        self,
        tree: MissionTree,
        link: VehicleLink,
        clock: Clock,
        *,
        rate_hz: float = 10.0,
        resources: Mapping[str, Any] | None = None,
        perf_counter: Callable[[], float] = time.perf_counter,
        telemetry_timeout_s: float = 90.0,
    ) -> None:
        if rate_hz <= 0:
            raise ValueError(f"rate_hz must be positive, got {rate_hz}")
        if not telemetry_timeout_s > 0:
            raise ValueError(f"telemetry_timeout_s must be positive, got {telemetry_timeout_s}")
        self.telemetry_timeout_s = float(telemetry_timeout_s)
        self.tree = tree
        self.link = link
        self.clock = clock
        self.period_s = 1.0 / rate_hz
        self.resources = dict(resources or {})
        clash = {"link", "clock"} & self.resources.keys()
        if clash:
            raise ValueError(f"resources may not replace {sorted(clash)}: pass them as link= and clock=")
        self._perf = perf_counter
        self._bt = _BehaviourTree(tree.root)
        self._next_tick_s: float | None = None
        self._stats = _TickStats()
        self._blackboard = py_trees.blackboard.Client(name="MissionRunner")
        self._blackboard.register_key(VEHICLE_STATE_KEY, access=py_trees.common.Access.WRITE)
        self._blackboard.register_key(MISSION_TIME_KEY, access=py_trees.common.Access.WRITE)
        self._blackboard.register_key(PHASE_KEY, access=py_trees.common.Access.READ)
        self.witness = FlightWitness()
        self.tick_log: list[StatusChange] = []
        self._tick_listeners: list[Callable[[list[StatusChange]], None]] = []
        self._retask_listeners: list[Callable[[Retask], None]] = []
        self._visitors: list[py_trees.visitors.VisitorBase] = []
        self.retask_sources: list[Callable[[], RetaskRequest | None]] = []
        self.retasks: list[Retask] = []
        source = tree.source.read_bytes() if tree.source is not None and tree.source.is_file() else None
        self._tree_hash = tree_hash(source) if source is not None else ""
        # What a subtree retask splices into: the running tree's document, parsed from these bytes at the first.
        self._document: TreeDocument | None = None
        self._source = (source, tree.source) if source is not None else None
        self._last_status: dict[object, py_trees.common.Status] = {}
        self._changed_last_tick: set = set()
        self._set_up = False

    # -- lifecycle --------------------------------------------------------------------------

    def setup(self) -> None:
        """Hand the link, clock and resources to every behaviour (py_trees ``setup(**kwargs)``).

        Raises:
            MissingResources: a leaf requires a resource the runner was not given (before any
                behaviour's setup runs).
        """
        missing = missing_resources(self._bt.root, self.resources)
        if missing is not None:
            raise missing
        self._publish(self.clock.now())
        self.witness = FlightWitness.attach(self.link, self.clock.now)
        self._bt.setup(link=self.link, clock=self.clock, **self.resources)
        self._set_up = True

    @property
    def status(self) -> py_trees.common.Status:
        """The root's status after the last tick (INVALID before the first)."""
        return self._bt.root.status

    @property
    def finished(self) -> bool:
        """True once the root has returned SUCCESS or FAILURE."""
        return self.status in (py_trees.common.Status.SUCCESS, py_trees.common.Status.FAILURE)

    @property
    def ticks(self) -> int:
        return self._stats.count

    @property
    def tick_wall_ms(self) -> list[float]:
        """Wall time of every tick so far, in milliseconds (for benchmarks)."""
        return self._stats.wall_ms

    def on_tick(self, listener: Callable[[list[StatusChange]], None]) -> None:
        """Call ``listener(changes)`` after every tick with that tick's status changes (maybe none)."""
        self._tick_listeners.append(listener)

    def add_visitor(self, visitor: py_trees.visitors.VisitorBase) -> None:
        """Run a py_trees visitor on the nodes every tick visits (Groot2's monitor sees the ticked nodes)."""
        self._visitors.append(visitor)
        self._bt.add_visitor(visitor)

    def on_retask(self, listener: Callable[[Retask], None]) -> None:
        """Call ``listener(retask)`` after every retask attempt, taken or not (after the swap when taken)."""
        self._retask_listeners.append(listener)

    # -- retasking (chaser_bt.mission.retask) ----------------------------------------------------

    def poll_retasks(self) -> None:
        """Offer every retask the sources have (between ticks: the safe point)."""
        for source in self.retask_sources:
            try:
                request = source()
            except Exception:  # a source must never stop the flight
                log.exception("a retask source raised")
                continue
            if request is not None:
                self.retask(request)

    def retask(self, request: RetaskRequest) -> Retask:
        """Check ``request`` against this flight and, if it passes, make its tree the mission, or, with
        ``request.subtree``, put it in place of that subtree (:meth:`_splice_in`).

        A whole tree: the running tree is halted (its leaves' exit holds), the aircraft held (hover)
        and the new tree, already set up, ticks from the next tick. A rejected request changes
        nothing; either way the attempt is logged and kept in :attr:`retasks`. Never raises.
        """
        now = self.clock.now()
        subtree = request.subtree
        new_hash = tree_hash(request.data) if subtree is None else spliced_hash(self._tree_hash, subtree, request.data)
        try:
            if subtree is None:
                tree, document = prepare_tree(request, self.link, self.resources)
                bt = _BehaviourTree(tree.root)
                self._set_up_new(request, lambda: bt.setup(link=self.link, clock=self.clock, **self.resources))
            else:
                splice = prepare_subtree(request, self.link, self.resources, self.tree, self._running_document())
                self._set_up_new(request, lambda: self._set_up_sites(splice))
        except RetaskRejected as exc:
            record = Retask(now, False, request.origin, request.name, self._tree_hash, new_hash, str(exc), subtree)
            log.warning("%s: the mission goes on unchanged", exc)
        else:
            if subtree is None:
                self._hand_over(bt, tree)
                message = f"tree {self._tree_hash or '(text)'} -> {new_hash}, aircraft held at the hand-over"
            else:
                document = splice.document
                message = (f"tree {self._tree_hash or '(text)'} -> {new_hash}, subtree {subtree} replaced by "
                           f"{request.name} {tree_hash(request.data)}: {self._splice_in(splice)}")
            record = Retask(now, True, request.origin, request.name, self._tree_hash, new_hash, message, subtree)
            self._tree_hash, self._document, self._source = new_hash, document, None
            log.info("retask %s (%s) taken: %s", request.name, request.origin, message)
        self.retasks.append(record)
        for listener in self._retask_listeners:
            listener(record)
        return record

    def _running_document(self) -> TreeDocument | None:
        """The document the running tree was built from, its includes merged (None: built from text)."""
        if self._document is None and self._source is not None:
            data, path = self._source
            self._source = None
            document, problems = parse_document(data.decode("utf-8", errors="replace"), str(path))
            merged, more = merge_includes(document, path.parent)
            self._document = None if problems or more else merged
        return self._document

    def _set_up_new(self, request: RetaskRequest, setup: Callable[[], object]) -> None:
        """Run the new leaves' ``setup``; a leaf that refuses this flight rejects the retask."""
        try:
            setup()
        except Exception as exc:  # a leaf refused this flight (a weights file, a key file, a port)
            raise RetaskRejected(f"{request.label}: {type(exc).__name__}: "
                                 f"{str(exc).splitlines()[0] if str(exc) else ''}") from None

    def _set_up_sites(self, splice: Splice) -> None:
        for site in splice.sites:
            py_trees.trees.setup(site.new, link=self.link, clock=self.clock, **self.resources)

    def _hand_over(self, bt: py_trees.trees.BehaviourTree, tree: MissionTree) -> None:
        """Halt the running tree, hold the aircraft, make ``bt`` the mission."""
        try:
            self._bt.root.stop(py_trees.common.Status.INVALID)
        except Exception:
            log.exception("a behaviour raised while being halted for a retask")
        self._record_status_changes(self.clock.now())
        self._hold()
        try:
            self._bt.shutdown()
        except Exception:
            log.exception("a behaviour raised while shutting down for a retask")
        self.tree, self._bt = tree, bt
        for visitor in self._visitors:
            self._bt.add_visitor(visitor)
        self._last_status = {}

    def _hold(self) -> None:
        """Send the hover command at a hand-over; never raises."""
        try:
            self.link.hover()
        except Exception as exc:  # the halted leaves' own holds went first; the autopilot's failsafes remain
            log.error("could not send hover at the retask: %s", exc)

    def _splice_in(self, splice: Splice) -> str:
        """Put the new subtree in place of every instance of the old one; what happened, in words.

        An instance that is running is halted (its leaves' exit holds) and, if one of its leaves was
        commanding the aircraft, the aircraft is held (hover); its ``SubTree`` node stays RUNNING, so
        its parent ticks the new instance from its start on the next tick. One that is not running
        (not reached yet, or finished) is swapped as it is: the new one runs when its parent next
        ticks it. The rest of the tree keeps its state.
        """
        halted, swapped, commanding = [], [], False
        for site in splice.sites:
            if not is_active(site.old):
                swapped.append(site.path)
                continue
            commanding = commanding or any(node.status == py_trees.common.Status.RUNNING and not node.children
                                           and hasattr(type(node), _COMMANDING_MARK) for node in site.old.iterate())
            try:
                site.old.stop(py_trees.common.Status.INVALID)
            except Exception:
                log.exception("a behaviour raised while being halted for a retask of subtree %s", splice.name)
            halted.append(site.path)
        self._record_status_changes(self.clock.now())
        if commanding:
            self._hold()
        splice.apply()
        for site in splice.sites:
            for node in site.old.iterate():
                self._last_status.pop(node.id, None)
                try:
                    node.shutdown()
                except Exception:
                    log.exception("a behaviour raised while shutting down for a retask of subtree %s", splice.name)
        self.tree = splice.tree
        parts = []
        if halted:
            parts.append(f"{', '.join(halted)} halted" + (", aircraft held at the hand-over" if commanding else ""))
        if swapped:
            parts.append(f"{', '.join(swapped)} not running, swapped")
        return "; ".join(parts)

    # -- ticking ----------------------------------------------------------------------------

    def due(self) -> bool:
        """True when the clock has reached the next tick time."""
        now = self.clock.now()
        if math.isnan(now):  # no vehicle time yet
            return False
        return self._next_tick_s is None or now >= self._next_tick_s

    def tick(self) -> py_trees.common.Status:
        """Publish the vehicle state, tick the tree once, schedule the next tick."""
        if not self._set_up:
            self.setup()
        now = self.clock.now()
        self._publish(now)
        self.witness.observe(now, self.link.state)
        start = self._perf()
        self._bt.tick()
        self._stats.wall_ms.append((self._perf() - start) * 1e3)
        self._stats.count += 1
        # Keep to the grid rather than drifting by the tick's own lateness.
        if self._next_tick_s is None:
            self._next_tick_s = now
        self._next_tick_s = max(self._next_tick_s + self.period_s, now)
        changes = self._record_status_changes(now)
        for listener in self._tick_listeners:
            listener(changes)
        return self.status

    def tick_if_due(self) -> bool:
        """Tick when due; returns whether it ticked. The lock-step entry point."""
        if self.due():
            self.tick()
            return True
        return False

    def stop(self, reason: str = "stopped") -> None:
        """Halt the tree (running leaves terminate and hover) and leave the aircraft hovering.

        Never raises: it runs on the way out of errors, and must not mask them.
        """
        log.info("stopping mission: %s", reason)
        try:
            self._bt.root.stop(py_trees.common.Status.INVALID)
        except Exception:
            log.exception("a behaviour raised while being halted")
        self._record_status_changes(self.clock.now())
        try:
            self.link.hover()
        except Exception as exc:  # nothing more can be sent; the autopilot's failsafes take over
            log.error("could not send hover on stop: %s", exc)

    def waiting_for(self) -> list[str]:
        """The telemetry the first tick needs and the vehicle has not sent yet (empty: ready)."""
        link, missing = self.link, []
        for mtype, why in _FIRST_TICK_NEEDS:
            if link.last_heard_s(mtype) is None:
                missing.append(f"{mtype} ({why})")
        if link.frame is None:
            missing.append("HOME_POSITION (the mission's ENU frame; ArduCopter sets home at its GPS fix)")
        return missing

    def tip_message(self) -> str:
        """The deepest running node and its feedback: why the tree is where it is."""
        return _said(self._bt.root.tip())

    def end_message(self) -> str:
        """Why the root finished: on FAILURE, the first action that failed in the last tick (a
        fallback's alternatives failing after it, e.g. "battery above 30 %", are not the cause);
        otherwise, or when no action failed, :meth:`tip_message`."""
        if self.status == py_trees.common.Status.FAILURE:
            for node in _nodes_post_order(self._bt.root, []):
                if (not node.children and node.id in self._changed_last_tick and node.status == py_trees.common.Status.FAILURE
                        and getattr(type(node), "NODE_KIND", NodeKind.ACTION) is NodeKind.ACTION):
                    return _said(node)
        return self.tip_message()

    def run(
        self,
        *,
        should_stop: Callable[[], bool] = lambda: False,
        idle: Callable[[], None] = lambda: time.sleep(0.002),
    ) -> RunResult:
        """Real-time loop: poll the link, tick when due, until the root finishes or a stop.

        ``idle`` is called between polls (a short sleep by default). Ctrl-C, a vehicle error or a
        leaf's exception all end in :meth:`stop`, so the aircraft is left hovering; with the aircraft
        in the air, :meth:`confirm_hold` then watches the hold take effect (``RunResult.hand_back``).
        """
        result = self._run(should_stop, idle)
        if self.ticks and result.status is not RunStatus.INTERRUPTED and result.verdict.outcome is not Outcome.LINK_LOST:
            self._listen(1.0, idle)  # a second more of telemetry: a lie (a clone's "disarmed") shows as one
            if self.link.state.telemetry_fault:
                result.verdict = self.verdict(result.status, result.message)
        if self.link.state.airborne or self.witness.untrusted:
            result.hand_back = self.confirm_hold(idle=idle)
            log.info("hand-back: %s", result.hand_back)
        return result

    def _listen(self, seconds: float, idle: Callable[[], None]) -> None:
        """Poll the link for ``seconds`` of its time (at most twice that of wall time); quiet ends it."""
        start, wall_start = self.link.now(), time.monotonic()
        try:
            while self.link.now() - start < seconds and time.monotonic() - wall_start < 2 * seconds:
                idle()
                self.link.poll()
        except VehicleError:
            return

    def confirm_hold(self, *, timeout_s: float = 10.0, idle: Callable[[], None] = lambda: time.sleep(0.002)) -> str:
        """After :meth:`stop`: poll until the aircraft shows it is held, re-sending the hold each second.

        Held means disarmed, in a mode that flies itself (LOITER, RTL, LAND, BRAKE ...), or holding
        in GUIDED or by the sticks with the horizontal speed under 1 m/s and the vertical under
        0.5 m/s. Bounded by ``timeout_s`` on the link's clock (vehicle time when the link runs on
        it, so the same at 1x and 10x) and 1.5 ``timeout_s`` of wall time. Returns what was seen.
        """
        link, wall_start = self.link, time.monotonic()
        start = last_sent = link.now()
        try:
            if link.state.telemetry_fault:  # nothing it says can confirm anything: stop it, and say so
                for _ in range(3):
                    link.hover()
                    self._listen(1.0, idle)
                return f"hold sent (zero velocity), NOT confirmed: {link.state.telemetry_fault}"
            while True:
                s = link.state
                speed = float(np.hypot(*s.velocity_enu[:2]))
                if not s.armed:
                    return "hold confirmed: disarmed"
                if s.mode not in _MISSION_HOLD_MODES:
                    return f"hold confirmed: the autopilot's {s.mode} has the aircraft"
                if speed < 1.0 and abs(float(s.velocity_enu[2])) < 0.5:
                    return f"hold confirmed: {s.mode} at {speed:.1f} m/s"
                if link.now() - start > timeout_s or time.monotonic() - wall_start > 1.5 * timeout_s:
                    return f"hold NOT confirmed within {timeout_s:g} s: {s.mode} at {speed:.1f} m/s"
                if link.now() - last_sent >= 1.0:
                    link.hover()
                    last_sent = link.now()
                idle()
                link.poll()
        except KeyboardInterrupt:
            return "hold NOT confirmed: interrupted again"
        except VehicleError as exc:
            return f"hold NOT confirmed: {exc}"

    def _run(self, should_stop: Callable[[], bool], idle: Callable[[], None]) -> RunResult:
        try:
            if not self._set_up:
                self.setup()
            missing = self._await_telemetry(should_stop, idle)
            if missing:
                message = (f"no {', no '.join(missing)} from the vehicle within {self.telemetry_timeout_s:g} s: "
                           f"not ticking a tree on a vehicle it cannot see")
                self.stop(message)
                return self._result(RunStatus.ERROR, message)
            while not should_stop():
                self.link.poll()
                self.poll_retasks()
                if self.tick_if_due() and self.finished:
                    status = RunStatus.SUCCESS if self.status == py_trees.common.Status.SUCCESS else RunStatus.FAILURE
                    message = self.end_message()
                    self.stop(f"root returned {self.status.name}")
                    return self._result(status, message)
                if self.witness.crash:  # disarmed in the air: nothing is left for the tree to fly
                    message = self.tip_message()
                    self.stop(self.witness.crash)
                    return self._result(RunStatus.FAILURE, message)
                idle()
            self.stop("stop requested")
            return self._result(RunStatus.INTERRUPTED, "stop requested")
        except KeyboardInterrupt:
            self.stop("interrupted by the operator")
            return self._result(RunStatus.INTERRUPTED, "interrupted by the operator")
        except VehicleError as exc:
            self.stop(str(exc))
            return self._result(RunStatus.ERROR, str(exc), link_lost=isinstance(exc, VehicleQuiet))
        except Exception as exc:  # a leaf raised: never leave a command in force
            log.exception("mission tick raised")
            self.stop(f"{type(exc).__name__}: {exc}")
            return self._result(RunStatus.ERROR, f"{type(exc).__name__}: {exc}")

    def verdict(self, status: RunStatus, message: str, *, link_lost: bool = False) -> Verdict:
        """The flight's outcome for a run that ended in ``status`` (:func:`chaser_bt.mission.outcome.judge`)."""
        try:
            phase = self._blackboard.get(PHASE_KEY)
        except KeyError:  # the tree names no phase
            phase = None
        self.witness.untrusted = self.witness.untrusted or self.link.state.telemetry_fault
        return judge(status.value, message, self.witness, phase, link_lost=link_lost)

    def _result(self, status: RunStatus, message: str, *, link_lost: bool = False) -> RunResult:
        return RunResult(status, self.ticks, message, self.verdict(status, message, link_lost=link_lost))

    # -- internals --------------------------------------------------------------------------

    def _await_telemetry(self, should_stop: Callable[[], bool], idle: Callable[[], None]) -> list[str]:
        """Poll until :meth:`waiting_for` is empty or the timeout passes; what is still missing."""
        start = self.link.now()
        missing = self.waiting_for()
        logged = False
        while missing and not should_stop():
            if self.link.now() - start >= self.telemetry_timeout_s:
                return missing
            if not logged:
                log.info("waiting for the vehicle's %s before the first tick", ", ".join(missing))
                logged = True
            idle()
            self.link.poll()
            missing = self.waiting_for()
        return []

    def _publish(self, now: float) -> None:
        self._blackboard.set(VEHICLE_STATE_KEY, self.link.state)
        self._blackboard.set(MISSION_TIME_KEY, now)

    def _record_status_changes(self, now: float) -> list[StatusChange]:
        """Append this tick's status changes to :attr:`tick_log` (kept for replay and plots)."""
        changes = []
        self._changed_last_tick = set()
        for node in _nodes_post_order(self._bt.root, []):
            old = self._last_status.get(node.id, py_trees.common.Status.INVALID)
            if old != node.status:
                self._last_status[node.id] = node.status
                self._changed_last_tick.add(node.id)
                changes.append(StatusChange(now, node.name, old.name, node.status.name))
        self.tick_log.extend(changes)
        return changes


class _BehaviourTree(py_trees.trees.BehaviourTree):
    """py_trees' tree, less the walk over every node its tick makes for visitors when it has none.

    With no visitors and no tick handlers, py_trees' tick is the root's tick and that walk; a
    rehearsal ticks hundreds of times a wall second, so the walk is left out. With any of them the
    tick is py_trees' own.
    """

    def tick(
        self,
        pre_tick_handler: Callable[[py_trees.trees.BehaviourTree], None] | None = None,
        post_tick_handler: Callable[[py_trees.trees.BehaviourTree], None] | None = None,
    ) -> None:
        if (self.visitors or self.pre_tick_handlers or self.post_tick_handlers or pre_tick_handler is not None
                or post_tick_handler is not None):
            super().tick(pre_tick_handler, post_tick_handler)
            return
        for _ in self.root.tick():
            pass
        self.count += 1


def _said(node: py_trees.behaviour.Behaviour | None) -> str:
    """``name: feedback`` of a node (its name alone without feedback; "" for none)."""
    if node is None:
        return ""
    return f"{node.name}: {node.feedback_message}" if node.feedback_message else node.name


def _nodes_post_order(node: py_trees.behaviour.Behaviour, out: list) -> list:
    """``node.iterate()``'s nodes in its order (children first), gathered without py_trees' nested generators."""
    for child in node.children:
        _nodes_post_order(child, out)
    out.append(node)
    return out
