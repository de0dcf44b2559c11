"""Hand-written BT.CPP v4 trees in the style of Nav2's behavior_trees/*.xml, using chaser-bt's behaviour IDs.

Each tree is validated against the real registry (our behaviours' real port declarations), then
ticked with scripted stand-ins registered under the same IDs with the same ports, so the
statuses follow BT.CPP's documented semantics step by step without a vehicle.
"""

from __future__ import annotations

import types

import py_trees
import pytest
from py_trees.common import Status

from chaser_bt.clock import ManualClock
from chaser_bt.tree import (
    Registry,
    default_registry,
    load_tree_text,
    validate_tree_text,
)

S, F, R = Status.SUCCESS, Status.FAILURE, Status.RUNNING
Blackboard = py_trees.blackboard.Blackboard

FLIGHT_IDS = ("ArmAndTakeoff", "GoTo", "Hover", "RTL", "Land", "BatteryAbove", "Airborne", "ModeIs")

# Nav2's navigate_w_replanning_and_recovery.xml, flown: fly to the goal, recovering by hovering
# and retrying (Nav2's RecoveryNode is RetryUntilSuccessful around Fallback(leg, Sequence(recovery,
# AlwaysFailure))); a reactive battery guard around all of it; RTL when the battery runs low.
NAVIGATE_WITH_RECOVERY = """\
<root BTCPP_format="4" main_tree_to_execute="Mission" mission_inputs="goal;recovery_done">
  <BehaviorTree ID="Mission">
    <Sequence name="mission">
      <RetryUntilSuccessful num_attempts="3">
        <ArmAndTakeoff name="takeoff" altitude_m="25"/>
      </RetryUntilSuccessful>
      <ReactiveFallback name="battery guard">
        <Inverter><BatteryAbove name="battery" percent="30"/></Inverter>
        <SubTree ID="FlyToGoal" name="fly" target="{goal}"/>
      </ReactiveFallback>
      <RTL name="home"/>
    </Sequence>
  </BehaviorTree>
  <BehaviorTree ID="FlyToGoal">
    <RetryUntilSuccessful num_attempts="2" name="recoveries">
      <Fallback name="leg or recover">
        <ReactiveSequence name="leg">
          <Airborne name="airborne"/>
          <GoTo name="goto" waypoint="{target}" acceptance_radius_m="3"/>
        </ReactiveSequence>
        <Sequence name="recover">
          <Hover name="recovery hover" duration_s="2" _skipIf="@recovery_done"/>
          <AlwaysFailure name="then retry"/>
        </Sequence>
      </Fallback>
    </RetryUntilSuccessful>
  </BehaviorTree>
</root>
"""


class StandIn(py_trees.ports.BehaviourWithPorts, register=False):
    """Returns the statuses scripted for its name, logs updates and halts."""

    INPUT_PORTS: dict = {}
    OUTPUT_PORTS: dict = {}

    def setup(self, **kwargs):
        self.script = kwargs["script"]

    def update(self):
        self.script.events.append(("update", self.name))
        queue = self.script.statuses.get(self.name, [S])
        return queue.pop(0) if len(queue) > 1 else queue[0]

    def terminate(self, new_status):
        self.script.events.append(("terminate", self.name, new_status.name))


@pytest.fixture
def stand_ins() -> Registry:
    """Control nodes plus, for each flight behaviour, a scripted class with its real ports and kind."""
    real = default_registry()
    registry = Registry.with_control_nodes()
    for node_id in FLIGHT_IDS:
        spec = real.get(node_id)
        body = {"INPUT_PORTS": dict(spec.cls.INPUT_PORTS), "OUTPUT_PORTS": dict(spec.cls.OUTPUT_PORTS), "NODE_KIND": spec.kind}
        cls = types.new_class(node_id, (StandIn,), {"register": False}, lambda ns, body=body: ns.update(body))
        registry.register(cls, node_id)
    return registry


def load(text: str, registry: Registry, script) -> py_trees.behaviour.Behaviour:
    tree = load_tree_text(text, "nav2.xml", registry)
    py_trees.trees.setup(tree.root, clock=ManualClock(0.0), script=script)
    return tree.root


def run(root, ticks: int) -> list[Status]:
    statuses = []
    for _ in range(ticks):
        root.tick_once()
        statuses.append(root.status)
    return statuses


def test_the_tree_is_valid_against_the_real_behaviour_declarations():
    assert validate_tree_text(NAVIGATE_WITH_RECOVERY, "nav2.xml", default_registry()) == []


def test_a_clean_flight_takes_off_flies_and_returns(stand_ins, script):
    Blackboard.set("/goal", [100.0, 0.0, 25.0])
    Blackboard.set("/recovery_done", False)
    script.statuses = {"takeoff": [R, S], "battery": [S], "goto": [R, R, S], "home": [R, S]}
    root = load(NAVIGATE_WITH_RECOVERY, stand_ins, script)
    assert run(root, 5) == [R, R, R, R, S]
    assert script.updates("recovery hover") == 0


def test_the_battery_guard_halts_the_leg_and_goes_home(stand_ins, script):
    Blackboard.set("/goal", [100.0, 0.0, 25.0])
    Blackboard.set("/recovery_done", False)
    # Battery fine for two ticks of the leg, then low: Inverter(BatteryAbove) succeeds, halting the subtree.
    script.statuses = {"battery": [S, S, F], "goto": [R], "home": [R]}
    root = load(NAVIGATE_WITH_RECOVERY, stand_ins, script)
    assert run(root, 4) == [R, R, R, R]
    assert script.terminations("goto") == ["INVALID"]
    assert script.updates("goto") == 2
    assert script.updates("home") == 2  # started on the third tick, still running on the fourth


def test_a_failed_leg_recovers_by_hovering_and_retries(stand_ins, script):
    Blackboard.set("/goal", [100.0, 0.0, 25.0])
    Blackboard.set("/recovery_done", False)
    # Tick 1: goto fails -> recovery hover RUNNING. Tick 2: hover succeeds -> AlwaysFailure -> the
    # attempt failed -> retried within the tick: goto succeeds -> home succeeds.
    script.statuses = {"goto": [F, S], "recovery hover": [R, S], "home": [S]}
    root = load(NAVIGATE_WITH_RECOVERY, stand_ins, script)
    assert run(root, 2) == [R, S]
    assert script.updates("goto") == 2
    assert script.updates("recovery hover") == 2


def test_skip_if_skips_the_recovery_so_the_retry_comes_at_once(stand_ins, script):
    Blackboard.set("/goal", [100.0, 0.0, 25.0])
    Blackboard.set("/recovery_done", True)
    script.statuses = {"goto": [F, S], "home": [S]}
    root = load(NAVIGATE_WITH_RECOVERY, stand_ins, script)
    # The failed attempt gives the tick back (BT.CPP 4.x's retry); the next tick retries at once.
    assert run(root, 2) == [R, S]
    assert script.updates("recovery hover") == 0
    assert script.updates("goto") == 2


def test_takeoff_is_retried_up_to_num_attempts_then_the_mission_fails(stand_ins, script):
    Blackboard.set("/goal", [100.0, 0.0, 25.0])
    Blackboard.set("/recovery_done", False)
    script.statuses = {"takeoff": [F]}
    root = load(NAVIGATE_WITH_RECOVERY, stand_ins, script)
    assert run(root, 3) == [R, R, F]
    assert script.updates("takeoff") == 3
    assert script.updates("goto") == 0


def test_the_subtree_port_remapping_feeds_the_parent_key_to_goto(stand_ins, script):
    root = load(NAVIGATE_WITH_RECOVERY, stand_ins, script)
    goto = next(n for n in root.iterate() if n.name == "goto")
    Blackboard.set("/goal", [1.0, 2.0, 3.0])
    assert goto.get_input("waypoint") == [1.0, 2.0, 3.0]
    assert goto.get_input("acceptance_radius_m") == 3.0


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ('<GoTo name="goto"', '<GoToo name="goto"'),
        ('<Airborne name="airborne"/>', '<Action ID="Flying"/>'),
        ('<RTL name="home"/>', '<SubTreePlus ID="X"/>'),
    ],
)
def test_unknown_ids_are_rejected_with_a_clear_error_never_replaced(old, new):
    text = NAVIGATE_WITH_RECOVERY.replace(old, new)
    assert text != NAVIGATE_WITH_RECOVERY
    problems = validate_tree_text(text, "nav2.xml", default_registry())
    unknown = [p for p in problems if p.message.startswith("unknown node")]
    assert len(unknown) == 1
    assert "did you mean" in unknown[0].message or "known nodes:" in unknown[0].message
