"""Node statuses as BT.CPP's Groot2 publisher reports them, mirrored from a py_trees tree after each tick.

BT.CPP resets a node to IDLE when its parent finishes (``resetChildren``), the root when the
tree finishes (``tickRoot``), and, while a reactive node runs, every child of it but the running
one; the publisher then shows ``10 + the status it had`` (12: idle after SUCCESS). A skipped node
keeps its IDLE (BT.CPP never stores SKIPPED). py_trees leaves finished nodes at SUCCESS/FAILURE
and a skipped one INVALID, so the mirror applies BT.CPP's rules itself: below a parent that is not
RUNNING every node is IDLE, and so is every child of a running reactive node that is not RUNNING.
Which nodes were ticked (a py_trees visitor sees them) tells a node that ran and was reset in the
same tick from one left over from an old run.

The transitions (for Groot2's recording) are the mirrored changes, stamped at the end of the tick,
in uid order (BT.CPP's are in the order the callbacks fire); a control node or decorator that
starts and finishes within one tick passes through RUNNING first, as BT.CPP's set themselves RUNNING.
What BT.CPP re-runs within one tick (a Repeat or RetryUntilSuccessful looping over a child that
finishes at once, the re-tick after a wake-up signal) shows only as its net change.
"""

from __future__ import annotations

import uuid
from collections.abc import Collection, Sequence

from py_trees.common import Status

from chaser_bt.log.groot2.protocol import IDLE_FROM, NodeStatus, encode_statuses
from chaser_bt.log.groot2.tree_xml import MonitoredNode

__all__ = ["StatusMirror"]

_FROM_PY = {Status.RUNNING: NodeStatus.RUNNING, Status.SUCCESS: NodeStatus.SUCCESS, Status.FAILURE: NodeStatus.FAILURE}


class StatusMirror:
    """BT.CPP's status buffer for ``nodes`` (in STATUS order), updated by :meth:`update` after every tick."""

    def __init__(self, nodes: Sequence[MonitoredNode]) -> None:
        self.nodes = tuple(nodes)
        self._order = sorted(self.nodes, key=lambda n: n.uid)  # parents before children
        self._reactive = {n.uid for n in self.nodes if n.reactive}
        self._state = {n.uid: NodeStatus.IDLE for n in self.nodes}  # BT.CPP's node status
        self._code = {n.uid: int(NodeStatus.IDLE) for n in self.nodes}  # what STATUS reports

    def update(self, ticked: Collection[uuid.UUID]) -> list[tuple[int, NodeStatus]]:
        """Mirror the statuses after a tick; ``ticked``: ids of the behaviours the tick visited.

        Returns the transitions, (uid, new status), in uid order.
        """
        transitions: list[tuple[int, NodeStatus]] = []
        for node in self._order:
            py = _FROM_PY.get(node.behaviour.status)
            if node.parent is None:
                reset = py in (NodeStatus.SUCCESS, NodeStatus.FAILURE)  # tickRoot resets a finished root
            else:
                parent = self._state[node.parent]
                reset = parent != NodeStatus.RUNNING or (node.parent in self._reactive and py != NodeStatus.RUNNING)
            old = self._state[node.uid]
            done = py in (NodeStatus.SUCCESS, NodeStatus.FAILURE)
            if node.control and done and old == NodeStatus.IDLE and node.inner.id in ticked:
                transitions.append((node.uid, NodeStatus.RUNNING))
                old = NodeStatus.RUNNING
            if py is not None and not reset:
                if py != old:
                    transitions.append((node.uid, py))
                self._state[node.uid] = py
                self._code[node.uid] = int(py)
                continue
            ran = done and (old != NodeStatus.IDLE or node.behaviour.id in ticked)
            if ran and py != old:
                transitions.append((node.uid, py))
                last = py
            elif old != NodeStatus.IDLE:
                last = old
            else:
                continue
            transitions.append((node.uid, NodeStatus.IDLE))
            self._state[node.uid] = NodeStatus.IDLE
            self._code[node.uid] = IDLE_FROM + int(last)
        return transitions

    def codes(self) -> list[tuple[int, int]]:
        """(uid, status code) in STATUS order."""
        return [(n.uid, self._code[n.uid]) for n in self.nodes]

    def payload(self) -> bytes:
        """The STATUS reply's payload."""
        return encode_statuses(self.codes())
