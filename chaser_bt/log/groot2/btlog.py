"""Flights that Groot2 replays: BehaviorTree.CPP's ``FileLogger2`` log (``.btlog``), written from a py_trees tree.

The format, as BT.CPP 4.10 writes it (``src/loggers/bt_file_logger_v2.cpp``; the comment in its
header file leaves out the first two fields):

- the 18 ASCII bytes ``BTCPP4-FileLogger2`` and one byte, the format's version, 1;
- the size of the XML (i32, little-endian), then the XML: ``WriteTreeToXML(tree, true, true)``, the
  tree exactly as Groot2's monitor gets it with FULLTREE (:mod:`chaser_bt.log.groot2.tree_xml`:
  the ``_uid`` attributes are the uids below);
- the start time (i64, little-endian): microseconds since the epoch on the wall clock (BT.CPP:
  ``system_clock`` when the logger is made);
- then 9 bytes per transition, every status change of every node, IDLE included: the low 6 bytes
  of the microseconds since the start (u64, little-endian), the node's uid (u16), its new status
  (u8, :class:`~chaser_bt.log.groot2.protocol.NodeStatus`): GET_TRANSITIONS' record.

BT.CPP stamps a transition when it happens, on the wall clock; :class:`BtlogWriter` stamps every
transition of a tick with the mission clock at that tick, in microseconds since the writer started
(the mission clock then; its first reading if it had none yet, as a vehicle's clock before its first
telemetry), so the file's timeline is the flight's, a rehearsal's simulated time included. The
transitions are :class:`~chaser_bt.log.groot2.statuses.StatusMirror`'s (BT.CPP's statuses, checked
node by node against BT.CPP's own), put in the order BT.CPP's callbacks fire in (:class:`CallbackOrder`).
The file is flushed to the operating system after every tick that changed a status, so a flight
that is killed leaves every tick but the one under way: the file has no end marker, Groot2 reads
what is there.
"""

from __future__ import annotations

import logging
import math
import struct
import time
import uuid
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import py_trees
from py_trees.common import Status

from chaser_bt.log.groot2.protocol import NodeStatus, ProtocolError, Transition, decode_transitions, encode_transitions
from chaser_bt.log.groot2.statuses import StatusMirror
from chaser_bt.log.groot2.tree_xml import MonitoredNode, MonitoredTree, describe_tree
from chaser_bt.tree import MissionTree, Registry

__all__ = ["MAGIC", "VERSION", "SUFFIX", "Btlog", "BtlogError", "BtlogWriter", "CallbackOrder", "FlightConversion",
           "check_suffix", "convert_flight", "encode_header", "parse_btlog", "read_btlog"]

log = logging.getLogger(__name__)

#: The file's first bytes, then :data:`VERSION` as one byte.
MAGIC = b"BTCPP4-FileLogger2"
VERSION = 1
#: Groot2 opens only files with this suffix (BT.CPP's FileLogger2 refuses any other).
SUFFIX = ".btlog"
_SIZE = struct.Struct("<i")
_START = struct.Struct("<q")
_RECORD = 9
_MAX_US = (1 << 48) - 1  # 6 bytes of timestamp
_DONE = (NodeStatus.SUCCESS, NodeStatus.FAILURE)
_FROM_PY = {Status.RUNNING: NodeStatus.RUNNING, Status.SUCCESS: NodeStatus.SUCCESS, Status.FAILURE: NodeStatus.FAILURE}


class BtlogError(ValueError):
    """Bytes that are not a FileLogger2 log, or a file name Groot2 would not open."""


@dataclass(frozen=True)
class Btlog:
    """A parsed ``.btlog``: the tree's XML, the start (µs since the epoch), the transitions; ``partial``:
    the file ends inside a record (a flight killed mid-write), which was left out."""

    xml: str
    start_us: int
    transitions: list[Transition]
    partial: bool = False


def encode_header(xml: str, start_us: int) -> bytes:
    """Everything before the transitions: magic, version, XML size, XML, start time."""
    data = xml.encode("utf-8")
    return MAGIC + bytes([VERSION]) + _SIZE.pack(len(data)) + data + _START.pack(start_us)


def parse_btlog(data: bytes) -> Btlog:
    """Read a ``.btlog``'s bytes (ours or BT.CPP's).

    Raises:
        BtlogError: not a FileLogger2 log (wrong magic or version, cut inside the header).
    """
    head = len(MAGIC) + 1
    if data[:len(MAGIC)] != MAGIC:
        raise BtlogError(f"not a BT.CPP FileLogger2 log: it starts {bytes(data[:len(MAGIC)])!r}")
    if len(data) < head + _SIZE.size or data[len(MAGIC)] != VERSION:
        raise BtlogError(f"FileLogger2 version {data[len(MAGIC)] if len(data) > len(MAGIC) else None}, expected {VERSION}")
    (size,) = _SIZE.unpack_from(data, head)
    body = head + _SIZE.size + size
    if size < 0 or len(data) < body + _START.size:
        raise BtlogError(f"the file ends inside its header ({len(data)} bytes, the XML alone is {size})")
    xml = bytes(data[head + _SIZE.size:body]).decode("utf-8")
    (start,) = _START.unpack_from(data, body)
    records = data[body + _START.size:]
    whole = len(records) - len(records) % _RECORD
    try:
        transitions = decode_transitions(bytes(records[:whole]))
    except ProtocolError as exc:  # pragma: no cover - whole records only
        raise BtlogError(str(exc)) from None
    return Btlog(xml, start, transitions, partial=whole != len(records))


def read_btlog(path: str | Path) -> Btlog:
    """:func:`parse_btlog` of a file."""
    return parse_btlog(Path(path).read_bytes())


def check_suffix(path: str | Path) -> Path:
    """``path`` if it ends in ``.btlog`` (Groot2 opens nothing else).

    Raises:
        BtlogError: another suffix.
    """
    path = Path(path)
    if path.suffix != SUFFIX:
        raise BtlogError(f"{path}: a Groot2 log must end in {SUFFIX} (Groot2 and BT.CPP's FileLogger2 open nothing else)")
    return path


# -- BT.CPP's callback order -------------------------------------------------------------------------


@dataclass(eq=False)
class _Visit:
    """One tick of one node (py_trees visits a node once it has ticked: children first)."""

    node: MonitoredNode
    index: int  # its how-manyth visit in this tick
    children: list[_Visit]
    parent: _Visit | None = None
    resets: list[tuple[int, NodeStatus]] = field(default_factory=list)  # re-run resets of children, by child


class CallbackOrder(StatusMirror):
    """The mirror's transitions of a tick in the order BT.CPP's status callbacks fire.

    :meth:`tick` takes the behaviours the tick visited in py_trees' visiting order (a node after the
    nodes it ticked) and rebuilds from it which tick of which node ran inside which, then walks
    that as BT.CPP ticks: a control node or decorator sets itself RUNNING as its tick starts, its
    children tick in turn, a decorator that runs a child again (Repeat) resets it in between, a
    node that finishes resets its children (in child order; a RUNNING one is halted first, its
    own children before it) and then takes its status; the root is reset after it. A reactive
    node or a decorator that stays RUNNING resets its other children as its tick ends, and a node
    halted from above (a parent that fails, a reactive node moving on, a ``_while`` turning false)
    goes IDLE after its children. Which transitions each node makes is the mirror's alone: this
    only orders them (each node's own stay in their order), and a transition the walk cannot place
    is put after the placed ones, in uid order.
    """

    def __init__(self, nodes: Sequence[MonitoredNode]) -> None:
        super().__init__(nodes)
        self._by_behaviour = {n.behaviour.id: n for n in self.nodes}
        self._children: dict[int | None, list[MonitoredNode]] = defaultdict(list)
        for n in sorted(self.nodes, key=lambda n: n.uid):
            self._children[n.parent].append(n)
        self._segments: dict[int, list[tuple[list[NodeStatus], list[NodeStatus]]]] = {}
        self._after_visits: dict[int, NodeStatus] = {}

    def tick(self, visits: Sequence[tuple[uuid.UUID, Status]]) -> list[tuple[int, NodeStatus]]:
        """The transitions of a tick, (uid, new status) in BT.CPP's callback order, from its visits:
        every behaviour the tick visited, with its status then, in visiting order."""
        ticked: dict[uuid.UUID, list[Status]] = {}
        for behaviour_id, status in visits:
            ticked.setdefault(behaviour_id, []).append(status)
        self._segments = {}
        changes = self.update(ticked)
        try:
            return self._callback_order(visits, changes)
        except Exception:  # never lose a transition to the ordering: the mirror's uid order then
            log.exception("btlog: could not order a tick's transitions as BT.CPP does; kept in uid order")
            return changes

    def halt(self) -> list[tuple[int, NodeStatus]]:
        """The transitions of a halt of the whole tree between ticks (``MissionRunner.stop``), as
        BT.CPP's ``haltTree``: the running nodes go IDLE, children before their parent."""
        return self.tick(())

    def _visits(self, node: MonitoredNode, old: NodeStatus,
                ticked: Mapping[uuid.UUID, Sequence[Status]]) -> list[NodeStatus]:
        """The mirror's, visit by visit: each visit's changes split into those at its start (a reset
        before it runs again, a control node's RUNNING) and those at its end."""
        ran = node.inner.id in ticked
        segments: list[tuple[list[NodeStatus], list[NodeStatus]]] = []
        changes: list[NodeStatus] = []
        state = old
        for seen in ticked.get(node.behaviour.id, ()):
            one: dict[uuid.UUID, Sequence[Status]] = {node.inner.id: ()} if ran else {}
            one[node.behaviour.id] = (seen,)
            made = StatusMirror._visits(node, state, one)
            split = 0
            for status in made:
                if split == 0 and state in _DONE and status == NodeStatus.IDLE:
                    pass  # run again: reset first
                elif node.control and state == NodeStatus.IDLE and status == NodeStatus.RUNNING:
                    pass  # a control node's tick starts RUNNING
                else:
                    break
                split += 1
                state = status
            segments.append((made[:split], made[split:]))
            changes += made
            if made:
                state = made[-1]
        self._segments[node.uid] = segments
        self._after_visits[node.uid] = state
        return changes

    def _callback_order(self, visits: Sequence[tuple[uuid.UUID, Status]],
                        changes: list[tuple[int, NodeStatus]]) -> list[tuple[int, NodeStatus]]:
        made: dict[int, list[NodeStatus]] = defaultdict(list)
        for uid, status in changes:
            made[uid].append(status)
        finals: dict[int, list[NodeStatus]] = {}
        for uid, statuses in made.items():
            ran = [s for pre, post in self._segments.get(uid, ()) for s in (*pre, *post)]
            if statuses[:len(ran)] != ran:  # pragma: no cover - the mirror's own split
                raise RuntimeError(f"node {uid}: visits {ran} are not the start of {statuses}")
            finals[uid] = statuses[len(ran):]

        # Which visit ran inside which: a node's visit comes after those of the children it ticked.
        pending: dict[int | None, list[_Visit]] = defaultdict(list)
        count: dict[int, int] = defaultdict(int)
        last: dict[int, _Visit] = {}
        for behaviour_id, _status in visits:
            node = self._by_behaviour.get(behaviour_id)
            if node is None:  # a node's own behaviour under its pre-conditions wrapper, or not a BT.CPP node
                continue
            visit = _Visit(node, count[node.uid], pending.pop(node.uid, []))
            for child in visit.children:
                child.parent = visit
            count[node.uid] += 1
            last[node.uid] = visit
            pending[node.parent].append(visit)

        out: list[tuple[int, NodeStatus]] = []
        flushed: set[int] = set()
        previous: dict[int, _Visit] = {}

        def halted_later(node: MonitoredNode) -> bool:
            """RUNNING after its last visit, then reset: halted from above (its children go with it)."""
            return (self._after_visits.get(node.uid) == NodeStatus.RUNNING
                    and NodeStatus.IDLE in finals.get(node.uid, ()))

        def flush(node: MonitoredNode) -> None:
            """The node's resets at the end of the tick: its children's first (a halt), then its own."""
            if node.uid in flushed:
                return
            flushed.add(node.uid)
            for child in self._children[node.uid]:
                flush(child)
            out.extend((node.uid, s) for s in finals.get(node.uid, ()))

        def place_rerun_resets(visit: _Visit) -> None:
            """A node run again in a later tick of its parent was reset when that earlier tick ended."""
            earlier = previous.get(visit.node.uid)
            previous[visit.node.uid] = visit
            pre, _post = self._segments[visit.node.uid][visit.index]
            if (earlier is not None and pre[:1] == [NodeStatus.IDLE] and earlier.parent is not None
                    and earlier.parent is not visit.parent):
                earlier.parent.resets.append((visit.node.uid, pre[0]))
                self._segments[visit.node.uid][visit.index] = (pre[1:], _post)

        def prepare(visit: _Visit) -> None:
            for child in visit.children:
                place_rerun_resets(child)
                prepare(child)

        def walk(visit: _Visit) -> None:
            node = visit.node
            pre, post = self._segments[node.uid][visit.index]
            out.extend((node.uid, s) for s in pre)
            for child in visit.children:
                walk(child)
            if visit.resets:
                order = {c.uid: i for i, c in enumerate(self._children[node.uid])}
                out.extend(sorted(visit.resets, key=lambda r: order.get(r[0], 0)))
            if last.get(node.uid) is visit and not halted_later(node):
                for child in self._children[node.uid]:
                    flush(child)
            out.extend((node.uid, s) for s in post)

        roots = pending.pop(None, [])
        for root in roots:
            place_rerun_resets(root)
            prepare(root)
        for root in roots:
            walk(root)
        for stray in (v for group in pending.values() for v in group):  # a parent that was never visited
            prepare(stray)
            walk(stray)
        for node in self._children[None]:
            flush(node)
        for uid in sorted(finals):  # under a node neither visited nor halted: none in practice
            if uid not in flushed:
                out.extend((uid, s) for s in finals[uid])
        if len(out) != len(changes):  # pragma: no cover - a bug here must not lose transitions
            raise RuntimeError("the ordered transitions are not the mirror's")
        return out


# -- the writer --------------------------------------------------------------------------------------


class BtlogWriter:
    """Write ``tree``'s flight to ``path`` as BT.CPP's FileLogger2 does (module docstring).

    Call :meth:`attach` with the :class:`~chaser_bt.mission.runner.MissionRunner` before its first
    tick (or add :attr:`visitor` to a py_trees ``BehaviourTree`` and give ``clock``); :meth:`close`
    (or ``with``) records a halt the runner made after the last tick (``stop``) and closes the file.

    Args:
        tree: the mission tree (loaded by :func:`chaser_bt.tree.load_tree`).
        path: the file, ``*.btlog``; created or replaced at once, header written.
        clock: mission time in seconds (default: the runner's clock, given at :meth:`attach`).
        registry: the node models the XML lists (default: chaser-bt's, as ``--groot2`` serves).
        start_us: the start time written in the header, µs since the epoch (default: now).
        clock_start: the mission time the transitions count from (default: the clock's reading now,
            or its first reading if it has none yet).

    Raises:
        BtlogError: ``path`` does not end in ``.btlog``.
        OSError: the file cannot be created.
    """

    def __init__(self, tree: MissionTree, path: str | Path, *, clock: Callable[[], float] | None = None,
                 registry: Registry | None = None, start_us: int | None = None,
                 clock_start: float | None = None) -> None:
        self.path = self._first = check_suffix(path)  # path: the file being written (a retask starts another)
        self._registry = registry
        self._clock = clock
        self._t0: float | None = clock_start if clock_start is not None and math.isfinite(clock_start) else None
        self._last_us = 0
        self._faults = 0
        self.transitions = 0
        self.closed = False
        self.description: MonitoredTree = describe_tree(tree, registry)
        self._order = CallbackOrder(self.description.nodes)
        self._fh: BinaryIO = self.path.open("wb")
        self.start_us = time.time_ns() // 1000 if start_us is None else int(start_us)
        self._fh.write(encode_header(self.description.xml, self.start_us))
        self._fh.flush()
        self.visitor = _VisitRecorder(self)
        self._runner: Any = None
        self._files = 1
        if clock is not None:
            self._start_clock()

    def attach(self, runner: Any) -> BtlogWriter:
        """Follow ``runner``'s ticks on its clock (a :class:`~chaser_bt.mission.runner.MissionRunner`).

        A retask (a new tree mid-flight) halts the old tree in this file and goes on in a new one,
        ``NAME-2.btlog`` and so on: a FileLogger2 log holds one tree.
        """
        self._runner = runner
        if self._clock is None:
            self._clock = runner.clock.now
            self._start_clock()
        runner.add_visitor(self.visitor)
        on_retask = getattr(runner, "on_retask", None)
        if on_retask is not None:
            on_retask(lambda retask: self._next_tree(runner.tree) if retask.accepted else None)
        return self

    def _start_clock(self) -> None:
        assert self._clock is not None
        t = self._clock()
        if self._t0 is None and math.isfinite(t):
            self._t0 = t

    def _stamp(self) -> int:
        """Microseconds since the start on the mission clock; never backwards, held while it reads nothing."""
        t = self._clock() if self._clock is not None else math.nan
        if not math.isfinite(t):
            return self._last_us
        if self._t0 is None:
            self._t0 = t
        us = min(max(round((t - self._t0) * 1e6), self._last_us), _MAX_US)
        self._last_us = us
        return us

    def tick_done(self, visits: Sequence[tuple[uuid.UUID, Status]]) -> None:
        """After a tick: its transitions, in BT.CPP's order, to the file (flushed). Never raises: a
        log fault must not end a flight."""
        self._record(lambda: self._order.tick(visits))

    def _record(self, transitions: Callable[[], list[tuple[int, NodeStatus]]]) -> None:
        if self.closed:
            return
        try:
            changes = transitions()
            if not changes:
                return
            us = self._stamp()
            self._fh.write(encode_transitions([Transition(us, uid, int(status)) for uid, status in changes]))
            self._fh.flush()
            self.transitions += len(changes)
        except Exception:
            self._faults += 1
            if self._faults == 1:
                log.exception("btlog %s: recording a tick failed (the flight goes on)", self.path)

    def _next_tree(self, tree: MissionTree) -> None:
        """A retask: the old tree's halt ends this file; the new tree starts the next. Never raises."""
        if self.closed:
            return
        self._record(self._order.halt)
        self._fh.close()
        self._files += 1
        path = self._first.with_name(f"{self._first.stem}-{self._files}{SUFFIX}")
        try:
            self.description = describe_tree(tree, self._registry)
            self._order = CallbackOrder(self.description.nodes)
            self._fh = path.open("wb")
            self._fh.write(encode_header(self.description.xml, time.time_ns() // 1000))
            self._fh.flush()
        except Exception:
            self.closed = True
            log.exception("btlog: cannot go on in %s after the retask: the rest of the flight is not logged", path)
            return
        self._t0, self._last_us = None, 0
        self._start_clock()
        self.path = path
        log.info("btlog: the retasked tree %s goes on in %s", tree.name, path)

    def close(self) -> None:
        """Record a halt the runner made after the last tick (its ``stop``), close the file (idempotent)."""
        if self.closed:
            return
        self._record(self._order.halt)
        self.closed = True
        self._fh.close()

    def __enter__(self) -> BtlogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _VisitRecorder(py_trees.visitors.VisitorBase):
    """Every behaviour a tick visits, with its status then, in order, for the writer after the tick."""

    def __init__(self, writer: BtlogWriter) -> None:
        super().__init__(full=False)
        self._writer = writer
        self._visits: list[tuple[uuid.UUID, Status]] = []

    def initialise(self) -> None:
        self._visits = []

    def run(self, behaviour: py_trees.behaviour.Behaviour) -> None:
        self._visits.append((behaviour.id, behaviour.status))

    def finalise(self) -> None:
        self._writer.tick_done(self._visits)


# -- from a recorded flight ----------------------------------------------------------------------------


@dataclass(frozen=True)
class FlightConversion:
    """What :func:`convert_flight` wrote: ``ticks`` replayed, ``transitions`` written, and whether the
    replayed tree's status changes are exactly the recorded ones (``as_recorded``)."""

    path: Path
    ticks: int
    transitions: int
    as_recorded: bool
    ended: str


def convert_flight(log: Any, tree: MissionTree, path: str | Path, *, registry: Registry | None = None) -> FlightConversion:
    """Write the recorded flight ``log`` (a :class:`~chaser_bt.log.replay.FlightLog`) as a ``.btlog`` of ``tree``.

    The MCAP log keeps py_trees' status changes after each tick, not BT.CPP's transitions (the
    resets py_trees does not make, the order within a tick), so the flight is replayed
    (:func:`~chaser_bt.log.replay.replay`: the recorded telemetry, radar and frames, tick for tick
    on the recorded clock) with a :class:`BtlogWriter` on the replaying runner. The header's start
    is the recording's (``recorded_at_unix_s``), and the transitions count from the mission time of
    its first MAVLink read (the recorder's start). ``as_recorded`` is False when the replay's status
    changes are not the recorded ones (the file then shows the replay, not the flight).

    Raises:
        BtlogError: ``path`` does not end in ``.btlog``.
        LogError: the log cannot be replayed.
    """
    from chaser_bt.log import schemas as S
    from chaser_bt.log.replay import recorded_camera_factory, replay

    check_suffix(path)
    recorded_at = log.meta.get("recorded_at_unix_s")
    start_us = round(float(recorded_at) * 1e6) if recorded_at else None
    reads = log.topic(S.TOPIC_MAVLINK_READ)
    clock_start = reads[0].json().get("t") if reads else None
    writers: list[BtlogWriter] = []

    def on_start(runner: Any, link: Any, resources: Any) -> None:
        writers.append(BtlogWriter(tree, path, registry=registry, start_us=start_us,
                                   clock_start=clock_start).attach(runner))

    try:
        result = replay(log, tree, camera_factory=recorded_camera_factory(log), on_start=on_start)
    finally:
        for writer in writers:
            writer.close()
    return FlightConversion(Path(path), result.ticks, sum(w.transitions for w in writers),
                            _as_recorded(log, result.status_changes), result.ended)


def _as_recorded(log: Any, replayed: Sequence[Any]) -> bool:
    """The replay made the recorded status changes, at the recorded times; but for those of the stop
    after the last tick, which the recorder stamps when it closes (a rehearsal's settle comes first)."""
    from chaser_bt.log import schemas as S

    recorded = []
    for message in log.topic(S.TOPIC_TREE):
        rec = message.json()
        t = rec["t"] if rec.get("tick") is not None else None
        recorded += [(t, c["node"], c["old"], c["new"]) for c in rec["changes"]]
    return len(recorded) == len(replayed) and all(
        (r[1], r[2], r[3]) == (p.node, p.old, p.new) and (r[0] is None or r[0] == p.t) for r, p in zip(recorded, replayed))
