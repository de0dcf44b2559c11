"""Groot2's live monitor (BehaviorTree.CPP's Groot2 publisher protocol): Groot2 attaches to a running tree;
and flights Groot2's log player opens (:mod:`~chaser_bt.log.groot2.btlog`, BT.CPP's FileLogger2 format).

:mod:`~chaser_bt.log.groot2.protocol` is the wire format, :mod:`~chaser_bt.log.groot2.tree_xml`
numbers the nodes and writes the tree as BT.CPP does, :mod:`~chaser_bt.log.groot2.statuses`
mirrors py_trees statuses into BT.CPP's, :mod:`~chaser_bt.log.groot2.blackboard` writes the
blackboard reply, :mod:`~chaser_bt.log.groot2.publisher` serves them (docs/logs.md, "Attaching Groot2").
"""

from chaser_bt.log.groot2.protocol import DEFAULT_PORT
from chaser_bt.log.groot2.publisher import LOOPBACK, Groot2Error, Groot2Publisher

__all__ = ["DEFAULT_PORT", "LOOPBACK", "Groot2Error", "Groot2Publisher"]
