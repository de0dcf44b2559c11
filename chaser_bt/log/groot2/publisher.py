"""Groot2's live monitor: a ZeroMQ server that answers Groot2 as BT.CPP's ``Groot2Publisher`` does.

A REP socket on PORT answers requests (:mod:`chaser_bt.log.groot2.protocol`) from a background
thread; a PUB socket on PORT + 1 is bound as BT.CPP binds it (it would carry breakpoint notices).
The tick loop only copies the mirrored statuses into the reply buffer (a py_trees visitor), so
nothing it does waits on Groot2; an error in the monitor is logged and the flight goes on.

Differences from BT.CPP 4.10, on purpose: the sockets are bound to loopback unless another
address is asked for (BT.CPP binds every interface); breakpoints and node replacement
(HOOK_INSERT) are refused, since a flying tree must never be paused or have a node's result
replaced from the ground, so the hook requests answer as BT.CPP does with no hooks installed.
BLACKBOARD reads py_trees' blackboard from the server thread (a value being replaced by the tick
is read before or after, never half-written: the blackboard is a dict under the GIL).
"""

from __future__ import annotations

import collections
import logging
import threading
import time
import uuid
from collections.abc import Mapping, Sequence
from typing import Any

import py_trees

from chaser_bt.log.groot2.blackboard import blackboard_reply
from chaser_bt.log.groot2.protocol import (
    DEFAULT_PORT,
    ProtocolError,
    ReplyHeader,
    RequestHeader,
    RequestType,
    Transition,
    decode_request_header,
    encode_reply_header,
    encode_transitions,
    error_reply,
    new_tree_id,
)
from chaser_bt.log.groot2.statuses import StatusMirror
from chaser_bt.log.groot2.tree_xml import MonitoredTree, describe_tree
from chaser_bt.tree import MissionTree, Registry

__all__ = ["Groot2Error", "Groot2Publisher", "LOOPBACK", "MAX_TRANSITIONS"]

log = logging.getLogger(__name__)

LOOPBACK = "127.0.0.1"
#: BT.CPP keeps the last 1000 transitions while recording.
MAX_TRANSITIONS = 1000
_POLL_MS = 100  # BT.CPP's receive timeout: how soon the server thread sees a close
_SEND_TIMEOUT_MS = 1000


class Groot2Error(RuntimeError):
    """The monitor cannot start (the port is taken, pyzmq is missing)."""


class Groot2Publisher:
    """Serve ``tree`` to Groot2 on ``host``:``port`` (requests) and ``port + 1`` (publisher).

    Call :meth:`attach` with the :class:`~chaser_bt.mission.runner.MissionRunner` (or add
    :attr:`visitor` to a py_trees ``BehaviourTree``) so statuses follow the ticks; :meth:`close`
    (or ``with``) stops the server.

    Raises:
        Groot2Error: a port cannot be bound.
    """

    def __init__(
        self, tree: MissionTree, port: int = DEFAULT_PORT, *, host: str = LOOPBACK, registry: Registry | None = None
    ) -> None:
        try:
            import zmq
        except ImportError as exc:  # pragma: no cover - pyzmq is a dependency
            raise Groot2Error("the Groot2 monitor needs pyzmq (pip install pyzmq)") from exc
        self._registry = registry
        self.description: MonitoredTree = describe_tree(tree, registry)
        self.port, self.host = port, host
        self.tree_id = new_tree_id()
        self._mirror = StatusMirror(self.description.nodes)
        self._lock = threading.Lock()
        self._status = self._mirror.payload()
        self._recording = False
        self._record_start_us = 0
        self._transitions: collections.deque[Transition] = collections.deque(maxlen=MAX_TRANSITIONS)
        self._stop = threading.Event()
        self._faults = 0
        self._zmq = zmq
        self._context = zmq.Context()
        self._server = self._socket(zmq.REP)
        self._publisher = self._socket(zmq.PUB)
        try:
            self._server.bind(f"tcp://{host}:{port}")
            self._publisher.bind(f"tcp://{host}:{port + 1}")
        except zmq.ZMQError as exc:
            self._close_sockets()
            raise Groot2Error(f"cannot serve Groot2 on {host}:{port} and {port + 1}: {exc}") from None
        #: The bound server and publisher endpoints (``tcp://127.0.0.1:1667``, ...).
        self.endpoints = tuple(s.getsockopt_string(zmq.LAST_ENDPOINT) for s in (self._server, self._publisher))
        self.visitor = _TickVisitor(self)
        self._thread = threading.Thread(target=self._serve, name=f"groot2-{port}", daemon=True)
        self._thread.start()
        log.info("Groot2 monitor on tcp://%s:%d (publisher %d), %d nodes", host, port, port + 1,
                 len(self.description.nodes))

    # -- the tick side ----------------------------------------------------------------------

    def attach(self, runner: Any) -> None:
        """Follow ``runner``'s ticks (a :class:`~chaser_bt.mission.runner.MissionRunner`), and its tree
        when a retask replaces it."""
        runner.add_visitor(self.visitor)
        runner.on_retask(lambda retask: self.serve_tree(runner.tree) if retask.accepted else None)

    def serve_tree(self, tree: MissionTree) -> None:
        """Serve ``tree`` from now on (a retask): a new tree id, so Groot2 asks for the new FULLTREE."""
        description = describe_tree(tree, self._registry)
        with self._lock:
            self.description = description
            self.tree_id = new_tree_id()
            self._mirror = StatusMirror(description.nodes)
            self._status = self._mirror.payload()
            self._transitions.clear()
        log.info("Groot2 monitor: now serving tree %s (%d nodes)", tree.name, len(description.nodes))

    def tick_done(self, ticked: Mapping[uuid.UUID, Sequence[py_trees.common.Status]]) -> None:
        """After a tick: mirror the statuses, store the STATUS payload and, if recording, the transitions.

        Never raises: a monitor fault must not end a flight.
        """
        try:
            changes = self._mirror.update(ticked)
            payload = self._mirror.payload()
            now_us = time.time_ns() // 1000
            with self._lock:
                self._status = payload
                if self._recording:
                    since = now_us - self._record_start_us
                    self._transitions.extend(Transition(since, uid, int(status)) for uid, status in changes)
        except Exception:
            self._faults += 1
            if self._faults == 1:  # once with the traceback, not at every tick
                log.exception("Groot2 monitor: status update failed (the flight goes on; Groot2's view stops)")
            else:
                log.debug("Groot2 monitor: status update failed again (%d times)", self._faults)

    def status_payload(self) -> bytes:
        """The current STATUS payload (what a STATUS request would get)."""
        with self._lock:
            return self._status

    # -- the server side --------------------------------------------------------------------

    def handle(self, parts: Sequence[bytes]) -> list[bytes]:
        """The reply to one request, as BT.CPP's ``serverLoop`` builds it."""
        if not parts:
            return error_reply("wrong request header")
        try:
            request = decode_request_header(parts[0])
        except ProtocolError:
            return error_reply("wrong request header")
        header = encode_reply_header(ReplyHeader(RequestHeader(request.type, request.unique_id), self.tree_id))
        kind = request.type
        if kind == RequestType.FULLTREE:
            return [header, self.description.xml.encode("utf-8")]
        if kind == RequestType.STATUS:
            return [header, self.status_payload()]
        if kind in (RequestType.HOOK_INSERT, RequestType.HOOK_REMOVE, RequestType.BREAKPOINT_UNLOCK,
                    RequestType.TOGGLE_RECORDING, RequestType.BLACKBOARD) and len(parts) != 2:
            return error_reply("must be 2 parts message")
        if kind == RequestType.BLACKBOARD:
            names = bytes(parts[1]).decode("utf-8", errors="replace").split(";")
            storage = py_trees.blackboard.Blackboard.storage
            try:
                return [header, blackboard_reply(names, self.description.scopes, storage, self.description.main)]
            except ValueError as exc:
                return error_reply(str(exc))
        if kind == RequestType.HOOK_INSERT:
            return error_reply("breakpoints are not supported: chaser-bt never pauses a flying tree")
        if kind in (RequestType.HOOK_REMOVE, RequestType.BREAKPOINT_UNLOCK):
            return error_reply("Node ID not found")  # BT.CPP's answer when no such hook is installed
        if kind in (RequestType.REMOVE_ALL_HOOKS, RequestType.DISABLE_ALL_HOOKS):
            return [header]
        if kind == RequestType.HOOKS_DUMP:
            return [header, b"[]"]
        if kind == RequestType.TOGGLE_RECORDING:
            return [header, *self._toggle_recording(bytes(parts[1]))]
        if kind == RequestType.GET_TRANSITIONS:
            with self._lock:
                transitions, self._transitions = list(self._transitions), collections.deque(maxlen=MAX_TRANSITIONS)
            return [header, encode_transitions(transitions)]
        return error_reply("Request not recognized")

    def _toggle_recording(self, command: bytes) -> list[bytes]:
        with self._lock:
            if command == b"start":
                self._record_start_us = time.time_ns() // 1000
                self._transitions.clear()
                self._recording = True
                return [str(time.time_ns() // 1000).encode()]
            if command == b"stop":
                self._recording = False
        return []

    def _serve(self) -> None:
        zmq = self._zmq
        while not self._stop.is_set():
            try:
                parts = self._server.recv_multipart()
            except zmq.Again:
                continue
            except zmq.ZMQError as exc:
                if not self._stop.is_set():
                    log.error("Groot2 monitor: receive failed: %s", exc)
                break
            try:
                reply = self.handle(parts)
            except Exception as exc:
                log.exception("Groot2 monitor: request failed")
                reply = error_reply(str(exc) or type(exc).__name__)
            try:
                self._server.send_multipart(reply)
            except zmq.ZMQError as exc:  # the client went away: the REP socket must be made anew
                log.warning("Groot2 monitor: reply not sent: %s", exc)
                if not self._renew_server():
                    break

    def _renew_server(self) -> bool:
        try:
            self._server.close(linger=0)
            self._server = self._socket(self._zmq.REP)
            self._server.bind(f"tcp://{self.host}:{self.port}")
            return True
        except self._zmq.ZMQError as exc:
            log.error("Groot2 monitor: cannot serve again on port %d: %s", self.port, exc)
            return False

    # -- lifecycle --------------------------------------------------------------------------

    def close(self) -> None:
        """Stop the server thread and release the ports (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._thread.join(timeout=5.0)
        if self._thread.is_alive():
            log.warning("Groot2 monitor: the server thread did not stop in time")
            return
        self._close_sockets()
        log.info("Groot2 monitor on port %d closed", self.port)

    def _socket(self, kind: int) -> Any:
        socket = self._context.socket(kind)
        socket.setsockopt(self._zmq.LINGER, 0)
        socket.setsockopt(self._zmq.RCVTIMEO, _POLL_MS)
        socket.setsockopt(self._zmq.SNDTIMEO, _SEND_TIMEOUT_MS)
        return socket

    def _close_sockets(self) -> None:
        self._server.close(linger=0)
        self._publisher.close(linger=0)
        self._context.term()

    def __enter__(self) -> Groot2Publisher:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _TickVisitor(py_trees.visitors.VisitorBase):
    """Collects the behaviours a tick visits, with their status at each visit, for the publisher after the tick."""

    def __init__(self, publisher: Groot2Publisher) -> None:
        super().__init__(full=False)
        self._publisher = publisher
        self._ticked: dict[uuid.UUID, list[py_trees.common.Status]] = {}

    def initialise(self) -> None:
        self._ticked = {}

    def run(self, behaviour: py_trees.behaviour.Behaviour) -> None:
        self._ticked.setdefault(behaviour.id, []).append(behaviour.status)

    def finalise(self) -> None:
        self._publisher.tick_done(self._ticked)
