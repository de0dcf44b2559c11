"""The BT.CPP v4 nodes py_trees lacks, and SKIPPED, against BT.CPP's documented behaviour (behaviortree.dev).

Expected statuses are worked out by hand from BT.CPP 4.x's sources and docs: SequenceWithMemory
resumes at the failed child, IfThenElse does not re-check its condition while a branch runs,
WhileDoElse re-checks it every tick and halts the other branch, RunOnce skips after one run,
KeepRunningUntilFailure turns SUCCESS into RUNNING; a skipped child is passed over.
"""

from __future__ import annotations

import pytest
from py_trees.common import Status

S, F, R, I = Status.SUCCESS, Status.FAILURE, Status.RUNNING, Status.INVALID


def probes(*names: str) -> str:
    return ", ".join(f"Probe: {{name: {n}}}" for n in names)


def test_sequence_with_memory_resumes_at_the_failed_child_not_the_first(build, script, tick):
    script.statuses = {"a": [S], "b": [F, S], "c": [S]}
    tree = build(f"SequenceWithMemory: {{children: [{probes('a', 'b', 'c')}]}}")
    # BT.CPP 4.x gives the tick back (RUNNING) after each child that succeeded at once.
    assert [tick(tree), tick(tree)] == [R, F]
    assert [tick(tree), tick(tree)] == [R, S]
    # a ran once: the second run started at b, where the first failed.
    assert (script.updates("a"), script.updates("b"), script.updates("c")) == (1, 2, 1)


def test_sequence_with_memory_starts_over_after_succeeding(build, script, tick):
    tree = build(f"SequenceWithMemory: {{children: [{probes('a', 'b')}]}}")
    assert [tick(tree) for _ in range(4)] == [R, S, R, S]
    assert script.updates("a") == 2


def test_plain_sequence_restarts_at_the_first_child_where_with_memory_would_not(build, script, tick):
    script.statuses = {"a": [S], "b": [F, S]}
    tree = build(f"Sequence: {{children: [{probes('a', 'b')}]}}")
    assert [tick(tree), tick(tree)] == [F, S]
    assert script.updates("a") == 2


@pytest.mark.parametrize(
    ("condition", "expected", "then_updates", "else_updates"),
    [(S, S, 1, 0), (F, F, 0, 1)],
)
def test_if_then_else_runs_the_branch_the_condition_picks(build, script, tick, condition, expected, then_updates, else_updates):
    script.statuses = {"if": [condition], "then": [S], "else": [F]}
    tree = build(f"IfThenElse: {{children: [{probes('if', 'then', 'else')}]}}")
    assert tick(tree) == expected
    assert (script.updates("then"), script.updates("else")) == (then_updates, else_updates)


def test_if_then_else_without_else_fails_when_the_condition_fails(build, script, tick):
    script.statuses = {"if": [F]}
    tree = build(f"IfThenElse: {{children: [{probes('if', 'then')}]}}")
    assert tick(tree) == F
    assert script.updates("then") == 0


def test_if_then_else_does_not_recheck_the_condition_while_the_branch_runs(build, script, tick):
    script.statuses = {"if": [S, F], "then": [R, R, S]}
    tree = build(f"IfThenElse: {{children: [{probes('if', 'then', 'else')}]}}")
    assert [tick(tree) for _ in range(3)] == [R, R, S]
    assert script.updates("if") == 1
    assert script.updates("else") == 0


def test_if_then_else_rejects_a_wrong_number_of_children(registry):
    from chaser_bt.tree import validate_tree_text

    text = "version: 1\ntrees: {T: {IfThenElse: {children: [AlwaysSuccess, AlwaysSuccess, AlwaysSuccess, AlwaysSuccess]}}}"
    problems = validate_tree_text(text, registry=registry)
    assert [p.message for p in problems] == ["IfThenElse: IfThenElse takes 2 to 3 children, got 4"]


def test_while_do_else_rechecks_the_condition_every_tick_and_halts_the_other_branch(build, script, tick):
    script.statuses = {"while": [S, S, F], "do": [R], "else": [R]}
    tree = build(f"WhileDoElse: {{children: [{probes('while', 'do', 'else')}]}}")
    assert [tick(tree) for _ in range(3)] == [R, R, R]
    assert script.updates("while") == 3
    # The condition turned false on the third tick: the running "do" branch is halted, "else" starts.
    assert script.terminations("do") == ["INVALID"]
    assert script.updates("else") == 1


def test_while_do_else_with_two_children_fails_when_the_condition_fails(build, script, tick):
    script.statuses = {"while": [S, F], "do": [R]}
    tree = build(f"WhileDoElse: {{children: [{probes('while', 'do')}]}}")
    assert [tick(tree), tick(tree)] == [R, F]
    assert script.terminations("do") == ["INVALID"]


def test_run_once_runs_its_child_to_completion_once_then_skips(build, script, tick):
    script.statuses = {"once": [R, S], "after": [S]}
    tree = build(f"Sequence: {{children: [RunOnce: {{child: {{Probe: {{name: once}}}}}}, Probe: {{name: after}}]}}")
    assert [tick(tree) for _ in range(4)] == [R, S, S, S]
    assert script.updates("once") == 2  # ran to completion once, over two ticks
    assert script.updates("after") == 3


def test_run_once_without_skip_repeats_the_first_result(build, script, tick):
    script.statuses = {"once": [F, S]}
    tree = build("RunOnce: {then_skip: false, child: {Probe: {name: once}}}")
    assert [tick(tree) for _ in range(3)] == [F, F, F]
    assert script.updates("once") == 1


def test_run_once_alone_is_skipped_after_its_run(build, script, tick):
    tree = build("RunOnce: {child: {Probe: {name: once}}}")
    assert [tick(tree), tick(tree)] == [S, I]


def test_keep_running_until_failure_turns_success_into_running(build, script, tick):
    script.statuses = {"c": [S, S, R, F]}
    tree = build("KeepRunningUntilFailure: {child: {Probe: {name: c}}}")
    assert [tick(tree) for _ in range(4)] == [R, R, R, F]
    assert script.updates("c") == 4


# ---- SKIPPED: a pre-condition that skips, seen by every kind of parent


def skip(name: str) -> str:
    return f'Probe: {{name: {name}, _skipIf: "true"}}'


def test_sequence_passes_over_a_skipped_child(build, script, tick):
    tree = build(f"Sequence: {{children: [{skip('a')}, Probe: {{name: b}}]}}")
    assert tick(tree) == S
    assert (script.updates("a"), script.updates("b")) == (0, 1)


def test_fallback_passes_over_a_skipped_child(build, script, tick):
    script.statuses = {"b": [F]}
    tree = build(f"Fallback: {{children: [{skip('a')}, Probe: {{name: b}}]}}")
    assert tick(tree) == F
    assert script.updates("a") == 0


@pytest.mark.parametrize("composite", ["Sequence", "SequenceWithMemory", "ReactiveSequence", "Fallback", "ReactiveFallback"])
def test_a_composite_whose_children_were_all_skipped_is_skipped(build, script, tick, composite):
    tree = build(f"Fallback: {{children: [{composite}: {{children: [{skip('a')}, {skip('b')}]}}, Probe: {{name: c}}]}}")
    # Skipped, not succeeded: the enclosing Fallback moves on to c (a SUCCESS would have stopped it).
    assert tick(tree) == S
    assert tree.root.children[0].status == I
    assert script.updates("c") == 1


@pytest.mark.parametrize("decorator", ["Inverter", "ForceSuccess", "ForceFailure", "Repeat: {num_cycles: 2,", "RetryUntilSuccessful: {num_attempts: 2,"])
def test_decorators_pass_a_skipped_child_through(build, script, tick, decorator):
    node = f"{decorator} child: {{{skip('a')}}}}}" if decorator.endswith(",") else f"{decorator}: {{child: {{{skip('a')}}}}}"
    tree = build(f"Sequence: {{children: [{node}, Probe: {{name: b}}]}}")
    assert tick(tree) == S
    assert tree.root.children[0].status == I
    assert script.updates("a") == 0


def test_parallel_counts_skipped_children_towards_a_negative_success_count(build, script, tick):
    # BT.CPP: with success_count -1 (all), skipped children count as done, so all skipped = SUCCESS.
    tree = build(f"Parallel: {{children: [{skip('a')}, {skip('b')}]}}")
    assert tick(tree) == S


def test_parallel_with_a_positive_success_count_is_skipped_when_every_child_is(build, script, tick):
    tree = build(f"Fallback: {{children: [Parallel: {{success_count: 1, children: [{skip('a')}, {skip('b')}]}}, Probe: {{name: c}}]}}")
    assert tick(tree) == S
    assert tree.root.children[0].status == I
    assert script.updates("c") == 1
