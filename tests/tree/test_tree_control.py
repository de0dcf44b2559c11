"""Control nodes against BehaviorTree.CPP's documented semantics (behaviortree.dev, v4)."""

from __future__ import annotations

import py_trees
import pytest
from py_trees.common import Status

S, F, R = Status.SUCCESS, Status.FAILURE, Status.RUNNING


def test_sequence_resumes_at_the_running_child_without_reticking_earlier_ones(build, script, tick):
    script.statuses = {"a": [S], "b": [R, R, S], "c": [S]}
    tree = build("Sequence: {children: [Probe: {name: a}, Probe: {name: b}, Probe: {name: c}]}")
    assert [tick(tree) for _ in range(3)] == [R, R, S]
    assert (script.updates("a"), script.updates("b"), script.updates("c")) == (1, 3, 1)


def test_sequence_restarts_from_the_first_child_after_a_failure(build, script, tick):
    script.statuses = {"a": [S], "b": [F, S]}
    tree = build("Sequence: {children: [Probe: {name: a}, Probe: {name: b}]}")
    assert tick(tree) == F
    assert tick(tree) == S
    assert script.updates("a") == 2


def test_reactive_sequence_reticks_earlier_conditions_every_tick(build, script, tick):
    script.statuses = {"cond": [S], "act": [R]}
    tree = build("ReactiveSequence: {children: [Probe: {name: cond}, Probe: {name: act}]}")
    for _ in range(3):
        assert tick(tree) == R
    assert script.updates("cond") == 3


def test_reactive_sequence_halts_the_running_child_when_a_condition_fails(build, script, tick):
    script.statuses = {"cond": [S, S, F], "act": [R]}
    tree = build("ReactiveSequence: {children: [Probe: {name: cond}, Probe: {name: act}]}")
    assert [tick(tree) for _ in range(3)] == [R, R, F]
    assert script.terminations("act") == ["INVALID"]
    assert script.updates("act") == 2


def test_fallback_stops_at_the_first_success(build, script, tick):
    script.statuses = {"a": [F], "b": [S], "c": [S]}
    tree = build("Fallback: {children: [Probe: {name: a}, Probe: {name: b}, Probe: {name: c}]}")
    assert tick(tree) == S
    assert script.updates("c") == 0


def test_fallback_resumes_at_the_running_child(build, script, tick):
    script.statuses = {"a": [F], "b": [R, S]}
    tree = build("Fallback: {children: [Probe: {name: a}, Probe: {name: b}]}")
    assert [tick(tree), tick(tree)] == [R, S]
    assert script.updates("a") == 1


def test_reactive_fallback_halts_a_running_lower_child_when_a_higher_one_succeeds(build, script, tick):
    script.statuses = {"guard": [F, S], "act": [R]}
    tree = build("ReactiveFallback: {children: [Probe: {name: guard}, Probe: {name: act}]}")
    assert [tick(tree), tick(tree)] == [R, S]
    assert script.terminations("act") == ["INVALID"]


def test_fallback_fails_only_when_every_child_fails(build, script, tick):
    script.statuses = {"a": [F], "b": [F]}
    tree = build("Fallback: {children: [Probe: {name: a}, Probe: {name: b}]}")
    assert tick(tree) == F


def test_parallel_by_default_needs_all_successes_and_does_not_retick_finished_children(build, script, tick):
    script.statuses = {"a": [S], "b": [R, R, S]}
    tree = build("Parallel: {children: [Probe: {name: a}, Probe: {name: b}]}")
    assert [tick(tree) for _ in range(3)] == [R, R, S]
    assert script.updates("a") == 1


def test_parallel_succeeds_at_success_count_and_halts_the_rest(build, script, tick):
    script.statuses = {"a": [R], "b": [S], "c": [R]}
    tree = build("Parallel: {success_count: 1, children: [Probe: {name: a}, Probe: {name: b}, Probe: {name: c}]}")
    assert tick(tree) == S
    # BT.CPP checks the thresholds after each child: c is never ticked, a is halted.
    assert script.terminations("a") == ["INVALID"]
    assert script.updates("c") == 0


def test_parallel_fails_at_failure_count(build, script, tick):
    script.statuses = {"a": [F], "b": [R], "c": [F]}
    tree = build(
        "Parallel: {success_count: 1, failure_count: 2,"
        " children: [Probe: {name: a}, Probe: {name: b}, Probe: {name: c}]}"
    )
    assert tick(tree) == F
    assert script.terminations("b") == ["INVALID"]


def test_parallel_fails_as_soon_as_success_is_impossible(build, script, tick):
    # success_count 2 of 2, failure_count 3: one failure already makes 2 successes impossible.
    script.statuses = {"a": [F], "b": [R]}
    tree = build("Parallel: {success_count: 2, failure_count: -1, children: [Probe: {name: a}, Probe: {name: b}]}")
    assert tick(tree) == F
    assert script.updates("b") == 0


def test_parallel_negative_thresholds_count_back_from_the_children(build, script, tick):
    # success_count -2 with 3 children = 2 successes.
    script.statuses = {"a": [S], "b": [R], "c": [S]}
    tree = build("Parallel: {success_count: -2, children: [Probe: {name: a}, Probe: {name: b}, Probe: {name: c}]}")
    assert tick(tree) == S
    assert script.terminations("b") == ["INVALID"]


@pytest.mark.parametrize(
    ("decorator", "child", "expected"),
    [
        ("Inverter", S, F),
        ("Inverter", F, S),
        ("Inverter", R, R),
        ("ForceSuccess", F, S),
        ("ForceSuccess", S, S),
        ("ForceSuccess", R, R),
        ("ForceFailure", S, F),
        ("ForceFailure", F, F),
        ("ForceFailure", R, R),
    ],
)
def test_status_decorators_map_the_child_status(build, script, tick, decorator, child, expected):
    script.statuses = {"c": [child]}
    assert tick(build(f"{decorator}: {{child: {{Probe: {{name: c}}}}}}")) == expected


def test_repeat_gives_the_tick_back_after_each_instant_cycle(build, script, tick):
    # BT.CPP 4.x (repeat_node.cpp): RUNNING (and a wake-up) after a child that finished at once.
    tree = build("Repeat: {num_cycles: 3, child: {Probe: {name: c}}}")
    assert [tick(tree) for _ in range(3)] == [R, R, S]
    assert script.updates("c") == 3


def test_repeat_counts_running_cycles_across_ticks(build, script, tick):
    script.statuses = {"c": [R, S, R, S]}
    tree = build("Repeat: {num_cycles: 2, child: {Probe: {name: c}}}")
    assert [tick(tree) for _ in range(3)] == [R, R, S]
    assert script.updates("c") == 4


def test_repeat_fails_when_the_child_fails(build, script, tick):
    script.statuses = {"c": [S, F]}
    tree = build("Repeat: {num_cycles: 5, child: {Probe: {name: c}}}")
    assert [tick(tree), tick(tree)] == [R, F]
    assert script.updates("c") == 2


def test_repeat_forever_yields_after_each_cycle(build, script, tick):
    tree = build("Repeat: {num_cycles: -1, child: {Probe: {name: c}}}")
    assert [tick(tree) for _ in range(4)] == [R] * 4
    assert script.updates("c") == 4


def test_retry_gives_up_after_num_attempts_failures(build, script, tick):
    script.statuses = {"c": [F]}
    tree = build("RetryUntilSuccessful: {num_attempts: 3, child: {Probe: {name: c}}}")
    assert [tick(tree) for _ in range(3)] == [R, R, F]
    assert script.updates("c") == 3


def test_retry_succeeds_on_the_attempt_that_succeeds(build, script, tick):
    script.statuses = {"c": [F, R, S]}
    tree = build("RetryUntilSuccessful: {num_attempts: 3, child: {Probe: {name: c}}}")
    assert [tick(tree), tick(tree), tick(tree)] == [R, R, S]
    assert script.updates("c") == 3


def test_retry_starts_counting_afresh_after_finishing(build, script, tick):
    script.statuses = {"c": [F, F, F, S]}
    tree = build("RetryUntilSuccessful: {num_attempts: 2, child: {Probe: {name: c}}}")
    assert [tick(tree), tick(tree)] == [R, F]
    # A fresh run gets two attempts again: the third fails, the fourth succeeds.
    assert [tick(tree), tick(tree)] == [R, S]
    assert script.updates("c") == 4


def test_timeout_fails_and_halts_the_child_at_the_deadline_on_the_mission_clock(build, script, tick, clock):
    script.statuses = {"c": [R]}
    tree = build("Timeout: {msec: 1500, child: {Probe: {name: c}}}")
    assert tick(tree) == R
    clock.advance(1.499)
    assert tick(tree) == R
    clock.advance(0.001)
    assert tick(tree) == F
    assert script.terminations("c") == ["INVALID"]
    assert script.updates("c") == 2


def test_timeout_passes_through_a_child_that_finishes_in_time(build, script, tick, clock):
    script.statuses = {"c": [R, S]}
    tree = build("Timeout: {msec: 1000, child: {Probe: {name: c}}}")
    assert tick(tree) == R
    clock.advance(0.5)
    assert tick(tree) == S


def test_timeout_restarts_its_deadline_each_run(build, script, tick, clock):
    script.statuses = {"c": [S, R]}
    tree = build("Timeout: {msec: 1000, child: {Probe: {name: c}}}")
    assert tick(tree) == S
    clock.advance(5.0)
    assert tick(tree) == R


def test_delay_keeps_the_child_untouched_until_the_delay_has_passed(build, script, tick, clock):
    tree = build("Delay: {delay_msec: 2000, child: {Probe: {name: c}}}")
    assert tick(tree) == R
    clock.advance(1.0)
    assert tick(tree) == R
    assert script.updates("c") == 0
    clock.advance(1.0)
    assert tick(tree) == S
    assert script.updates("c") == 1


def test_wait_runs_for_its_duration_on_the_mission_clock(build, tick, clock):
    tree = build("Wait: {duration_s: 2}")
    assert tick(tree) == R
    clock.advance(1.9)
    assert tick(tree) == R
    clock.advance(0.1)
    assert tick(tree) == S


def test_clocked_nodes_refuse_setup_without_a_clock(registry):
    from chaser_bt.tree import load_tree_text

    tree = load_tree_text("version: 1\ntrees: {T: {Wait: {duration_s: 1}}}", registry=registry)
    with pytest.raises(RuntimeError, match="Clock"):
        py_trees.trees.setup(tree.root)


def test_always_success_and_always_failure(build, tick):
    assert tick(build("AlwaysSuccess")) == S
    assert tick(build("AlwaysFailure")) == F


def test_set_blackboard_writes_the_value_to_the_wired_key(build, tick):
    tree = build('SetBlackboard: {value: [1, 2], output_key: "{target}"}')
    assert tick(tree) == S
    assert py_trees.blackboard.Blackboard.get("/target") == [1, 2]


def test_halting_a_tree_terminates_its_running_leaf_with_invalid(build, script, tick):
    script.statuses = {"deep": [R]}
    tree = build(
        """
        Sequence:
          children:
            - Timeout:
                msec: 10000
                child:
                  Parallel:
                    children: [Probe: {name: deep}, Probe: {name: other}]
        """
    )
    assert tick(tree) == R
    tree.root.stop(Status.INVALID)
    assert script.terminations("deep") == ["INVALID"]
