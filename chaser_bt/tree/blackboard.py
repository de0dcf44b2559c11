"""Blackboard housekeeping: py_trees' blackboard is one process-wide store, so trees must not share it by accident."""

from __future__ import annotations

import py_trees

from chaser_bt.tree.builder import restore_literals

__all__ = ["reset_blackboard"]


def reset_blackboard() -> None:
    """Forget every key, value and client, for a fresh tree or test.

    The literal port values of trees already loaded are kept: they are those nodes'
    configuration, which the loader stores on the blackboard only so ``get_input`` finds them.
    (``py_trees.blackboard.Blackboard.clear()`` alone would drop them.)
    """
    py_trees.blackboard.Blackboard.clear()
    restore_literals()
