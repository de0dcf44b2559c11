"""Flying a behaviour inside a tiny tree built around it (imported by this folder's tests)."""

from __future__ import annotations

import py_trees

from chaser_bt.mission.runner import MissionRunner
from chaser_bt.tree import load_tree_text
from sitl.bench.in_process import InProcessVehicle


def runner_for(vehicle: InProcessVehicle, body: str) -> MissionRunner:
    """A runner for a one-tree YAML document whose root node is ``body`` (YAML, indented 4)."""
    text = "version: 1\ntrees:\n  Test:\n" + "\n".join("    " + line for line in body.strip().splitlines()) + "\n"
    return MissionRunner(load_tree_text(text, source="<test>"), vehicle.link, vehicle.clock, rate_hz=10.0)


def fly(vehicle: InProcessVehicle, body: str, timeout_s: float) -> tuple[py_trees.common.Status, MissionRunner]:
    """Tick the tree until its root finishes (or ``timeout_s`` of sim time); (status, runner)."""
    runner = runner_for(vehicle, body)
    return vehicle.fly(runner, timeout_s), runner


def take_off(vehicle: InProcessVehicle, altitude_m: float = 15.0) -> None:
    """Get airborne at ``altitude_m`` through the ArmAndTakeoff behaviour itself."""
    status, runner = fly(vehicle, f"ArmAndTakeoff: {{altitude_m: {altitude_m}}}", timeout_s=150)
    assert status == py_trees.common.Status.SUCCESS, runner.tip_message()
