"""Node statuses as BT.CPP's Groot2 publisher reports them, mirrored from a py_trees tree after each tick.

BT.CPP resets a node to IDLE when its parent finishes (``resetChildren``), the root when the
tree finishes (``tickRoot``), and, while a reactive node or a decorator runs, every child of it
that is not running (a decorator resets a finished child and carries on: KeepRunningUntilFailure,
RetryUntilSuccessful, Repeat); the publisher then shows ``10 + the status it had`` (12: idle after
SUCCESS). A skipped node keeps its IDLE (BT.CPP never stores SKIPPED). py_trees leaves finished
nodes at SUCCESS/FAILURE and a skipped one INVALID, so the mirror applies BT.CPP's rules itself:
below a parent that is not RUNNING every node is IDLE, and so is every child of a running reactive
node or decorator that is not RUNNING. Which nodes the tick visited, and their status then (a
py_trees visitor sees them), tells a node that ran and was reset in the same tick from one left
over from an old run, and a node that started and was halted in the same tick (11).

The transitions (for Groot2's recording) are the mirrored changes, stamped at the end of the tick,
in uid order (BT.CPP's are in the order the callbacks fire); a control node or decorator that
starts and finishes within one tick passes through RUNNING first, as BT.CPP's set themselves RUNNING.
A node run more than once in a tick (a Repeat or RetryUntilSuccessful looping over a child that
finishes at once) is seen at each visit, so its resets are recorded too. BT.CPP's re-tick of the
whole tree within one ``tickOnce`` after a wake-up signal has no py_trees counterpart: it shows as
its net change.
"""

from __future__ import annotations

import uuid
from collections.abc import Mapping, Sequence

from py_trees.common import Status

from chaser_bt.log.groot2.protocol import IDLE_FROM, NodeStatus, encode_statuses
from chaser_bt.log.groot2.tree_xml import MonitoredNode

__all__ = ["StatusMirror"]

_FROM_PY = {Status.RUNNING: NodeStatus.RUNNING, Status.SUCCESS: NodeStatus.SUCCESS, Status.FAILURE: NodeStatus.FAILURE}
_DONE = (NodeStatus.SUCCESS, NodeStatus.FAILURE)


class StatusMirror:
    """BT.CPP's status buffer for ``nodes`` (in STATUS order), updated by :meth:`update` after every tick."""

    def __init__(self, nodes: Sequence[MonitoredNode]) -> None:
        self.nodes = tuple(nodes)
        self._order = sorted(self.nodes, key=lambda n: n.uid)  # parents before children
        self._resets = {n.uid for n in self.nodes if n.resets_finished}
        self._state = {n.uid: NodeStatus.IDLE for n in self.nodes}  # BT.CPP's node status
        self._code = {n.uid: int(NodeStatus.IDLE) for n in self.nodes}  # what STATUS reports

    def update(self, ticked: Mapping[uuid.UUID, Sequence[Status]]) -> list[tuple[int, NodeStatus]]:
        """Mirror the statuses after a tick; ``ticked``: each behaviour the tick visited, with its status
        at every visit (a Repeat may run its child more than once in a tick).

        Returns the transitions, (uid, new status), in uid order.
        """
        transitions: list[tuple[int, NodeStatus]] = []
        for node in self._order:
            old = self._state[node.uid]
            changes = self._visits(node, old, ticked)
            state = changes[-1] if changes else old
            py = _FROM_PY.get(node.behaviour.status)
            if node.parent is None:
                reset = py in _DONE  # tickRoot resets a finished root
            else:
                parent = self._state[node.parent]
                reset = parent != NodeStatus.RUNNING or (node.parent in self._resets and py != NodeStatus.RUNNING)
            if py is not None and not reset:
                if py != state:
                    changes.append(py)
            elif state != NodeStatus.IDLE:
                changes.append(NodeStatus.IDLE)
            transitions += [(node.uid, status) for status in changes]
            if changes:
                self._state[node.uid] = changes[-1]
                done = [status for status in (old, *changes) if status != NodeStatus.IDLE]
                self._code[node.uid] = int(changes[-1]) or (IDLE_FROM + int(done[-1]) if done else 0)
        return transitions

    @staticmethod
    def _visits(node: MonitoredNode, old: NodeStatus, ticked: Mapping[uuid.UUID, Sequence[Status]]) -> list[NodeStatus]:
        """The node's transitions during the tick, from its status at each visit."""
        changes: list[NodeStatus] = []
        state = old
        ran = node.inner.id in ticked  # not only its pre-conditions
        for seen in ticked.get(node.behaviour.id, ()):
            status = _FROM_PY.get(seen)  # None: skipped (its pre-conditions, or all its children)
            if state in _DONE:  # run again: its parent reset it first
                changes.append(NodeStatus.IDLE)
                state = NodeStatus.IDLE
            if status is None:
                if state == NodeStatus.RUNNING:  # a _while turned false: halted
                    changes.append(NodeStatus.IDLE)
                    state = NodeStatus.IDLE
                continue
            if node.control and ran and state == NodeStatus.IDLE and status != NodeStatus.RUNNING:
                changes.append(NodeStatus.RUNNING)  # BT.CPP's control nodes set RUNNING as their tick starts
                state = NodeStatus.RUNNING
            if status != state:
                changes.append(status)
                state = status
        return changes

    def codes(self) -> list[tuple[int, int]]:
        """(uid, status code) in STATUS order."""
        return [(n.uid, self._code[n.uid]) for n in self.nodes]

    def payload(self) -> bytes:
        """The STATUS reply's payload."""
        return encode_statuses(self.codes())
