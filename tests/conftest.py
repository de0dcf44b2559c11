"""Suite-wide set-up: MAVLink 2 before pymavlink loads, and a clean py_trees blackboard per test."""

import os

os.environ["MAVLINK20"] = "1"

import py_trees  # noqa: E402
import pytest  # noqa: E402


@pytest.fixture(autouse=True)
def _clean_blackboard():
    """py_trees' blackboard is process-global; no test may see another's keys."""
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()
