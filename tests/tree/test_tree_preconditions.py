"""BT.CPP v4 pre-conditions (_failureIf, _successIf, _skipIf, _while) and their blackboard expressions.

Semantics from behaviortree.dev "Pre and post conditions" / TreeNode::checkPreConditions: checked
in the order _failureIf, _successIf, _skipIf, _while while the node is idle; only _while while it
runs, where false halts it; a node stopped by a pre-condition is not ticked.
"""

from __future__ import annotations

import enum

import py_trees
import pytest
from hypothesis import given
from hypothesis import strategies as st
from py_trees.common import Status

from chaser_bt.tree import validate_tree_text
from chaser_bt.tree.expressions import ExpressionError, parse_expression

S, F, R, I = Status.SUCCESS, Status.FAILURE, Status.RUNNING, Status.INVALID
Blackboard = py_trees.blackboard.Blackboard


# ---- expressions


@pytest.mark.parametrize(
    ("text", "values", "expected"),
    [
        ("battery > 30", {"battery": 31.0}, True),
        ("battery > 30", {"battery": 30}, False),
        ("battery >= 30 && !rtl", {"battery": 30.0, "rtl": False}, True),
        ("a || b && c", {"a": False, "b": True, "c": False}, False),  # && binds tighter: a || (b && c)
        ("(a || b) && c", {"a": False, "b": True, "c": False}, False),
        ("(a || b) && !c", {"a": False, "b": True, "c": False}, True),
        ("x * 2 + 1 == 7", {"x": 3}, True),
        ("1 + x * 2 == 7", {"x": 3}, True),  # * before +
        ("10 - 4 - 3 == 3", {}, True),  # left-associative
        ("-x < 0", {"x": 2.5}, True),
        ("mode == 'RTL'", {"mode": "RTL"}, True),
        ('mode != "RTL"', {"mode": "LOITER"}, True),
        ("count", {"count": 0}, False),
        ("true && !false", {}, True),
        ("1.5e1 == 15", {}, True),
    ],
)
def test_expressions_evaluate_like_bt_cpp_scripts(text, values, expected):
    assert parse_expression(text).evaluate_with(values) is expected


def test_an_enum_on_the_blackboard_compares_with_its_member_name():
    Mode = enum.Enum("Mode", {"RTL": "RTL", "LOITER": "LOITER"})
    assert parse_expression("mode == 'RTL'").evaluate_with({"mode": Mode.RTL})


def test_variables_are_listed_once_in_order_of_appearance():
    assert parse_expression("b > a && @root_key || b").variables == ("b", "a", "@root_key")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("battery >", "ends where a value was expected"),
        ("battery >> 3", "unexpected '>' at column 10"),
        ("x :=", "ends where a value was expected"),
        ("3 := x", "needs a blackboard entry on its left"),
        ("(a && b", "never closed"),
        ("a $ b", "cannot read"),
        ("", "empty"),
        ("a b", "unexpected 'b' at column 3"),
    ],
)
def test_malformed_expressions_are_refused_with_the_position(text, message):
    with pytest.raises(ExpressionError, match=message):
        parse_expression(text)


@pytest.mark.parametrize(
    ("text", "values", "message"),
    [
        ("missing > 1", {}, "no value yet"),
        ("name > 1", {"name": "abc"}, "cannot order"),
        ("name == 1", {"name": "abc"}, "cannot compare"),
        ("name - 1", {"name": "abc"}, "not permitted"),
    ],
)
def test_expressions_that_cannot_be_evaluated_raise_expression_error(text, values, message):
    with pytest.raises(ExpressionError, match=message):
        parse_expression(text).evaluate_with(values)


@given(st.floats(-1e6, 1e6), st.floats(-1e6, 1e6))
def test_comparisons_agree_with_python(a, b):
    for op in ("<", "<=", ">", ">=", "==", "!="):
        # BT.CPP's == between numbers allows a float epsilon (scripting/operators.hpp, IsSame).
        close = abs(a - b) <= 1.1920928955078125e-07
        expected = {"==": close, "!=": not close}.get(op, eval(f"a {op} b"))
        assert parse_expression(f"a {op} b").evaluate_with({"a": a, "b": b}) is expected


# ---- pre-conditions on nodes


def test_failure_if_fails_without_ticking_the_node(build, script, tick):
    Blackboard.set("/low", True)
    tree = build('Probe: {name: p, _failureIf: "low"}', inputs=("low",))
    assert tick(tree) == F
    assert script.updates("p") == 0


def test_success_if_succeeds_without_ticking_the_node(build, script, tick):
    Blackboard.set("/done", True)
    tree = build('Probe: {name: p, _successIf: "done"}', inputs=("done",))
    assert tick(tree) == S
    assert script.updates("p") == 0


def test_false_conditions_let_the_node_run(build, script, tick):
    for key in ("/low", "/done", "/skip"):
        Blackboard.set(key, False)
    script.statuses = {"p": [F]}
    tree = build(
        'Probe: {name: p, _failureIf: "low", _successIf: "done", _skipIf: "skip", _while: "!skip"}',
        inputs=("low", "done", "skip"),
    )
    assert tick(tree) == F
    assert script.updates("p") == 1


def test_failure_if_is_checked_before_success_if(build, script, tick):
    Blackboard.set("/x", 1.0)
    tree = build('Probe: {name: p, _successIf: "x > 0", _failureIf: "x > 0"}', inputs=("x",))
    assert tick(tree) == F


def test_while_halts_a_running_node_when_it_turns_false_and_skips_it(build, script, tick):
    Blackboard.set("/ok", True)
    script.statuses = {"p": [R]}
    tree = build('Sequence: {children: [Probe: {name: p, _while: "ok"}, Probe: {name: after}]}', inputs=("ok",))
    assert [tick(tree), tick(tree)] == [R, R]
    Blackboard.set("/ok", False)
    # Halted and skipped: the Sequence passes over it to the next child.
    assert tick(tree) == S
    assert script.terminations("p") == ["INVALID"]
    assert script.updates("p") == 2
    assert script.updates("after") == 1


def test_while_false_at_the_start_skips_the_node(build, script, tick):
    Blackboard.set("/ok", False)
    tree = build('Fallback: {children: [Probe: {name: p, _while: "ok"}, AlwaysFailure]}', inputs=("ok",))
    assert tick(tree) == F
    assert script.updates("p") == 0


def test_skip_if_is_not_rechecked_while_the_node_runs(build, script, tick):
    Blackboard.set("/skip", False)
    script.statuses = {"p": [R, R, S]}
    tree = build('Probe: {name: p, _skipIf: "skip"}', inputs=("skip",))
    assert tick(tree) == R
    Blackboard.set("/skip", True)
    assert [tick(tree), tick(tree)] == [R, S]


def test_a_condition_that_cannot_be_evaluated_fails_the_node_without_running_it(build, script, tick):
    Blackboard.set("/label", "text")
    tree = build('Probe: {name: p, _skipIf: "label > 3"}', inputs=("label",))
    assert tick(tree) == F
    assert script.updates("p") == 0
    assert "pre-condition error" in tree.root.feedback_message


def test_conditions_read_the_subtree_scope_through_remapping(build_xml, script, tick):
    Blackboard.set("/battery", 20.0)
    tree = build_xml(
        """
        <BehaviorTree ID="T">
          <SubTree ID="Leg" level="{battery}"/>
        </BehaviorTree>
        <BehaviorTree ID="Leg">
          <Probe name="p" _failureIf="level &lt; 30"/>
        </BehaviorTree>
        """,
        trees=True,
        inputs="battery",
    )
    assert tick(tree) == F
    Blackboard.set("/battery", 50.0)
    assert tick(tree) == S


def test_a_subtree_literal_reaches_a_condition_as_a_constant(build_xml, script, tick):
    tree = build_xml(
        """
        <BehaviorTree ID="T"><SubTree ID="Leg" limit="3"/></BehaviorTree>
        <BehaviorTree ID="Leg"><Probe name="p" _successIf="limit == 3"/></BehaviorTree>
        """,
        trees=True,
    )
    assert tick(tree) == S
    assert script.updates("p") == 0


def test_validation_reports_malformed_conditions_and_unwritten_keys_at_their_value(registry):
    text = 'version: 1\ntrees:\n  T:\n    Sequence:\n      children:\n        - Probe: {_while: "a >"}\n        - Probe: {_skipIf: "never_written"}\n'
    problems = validate_tree_text(text, registry=registry)
    assert [(p.line, p.column) for p in problems] == [(6, 27), (7, 28)]
    assert "ends where a value was expected" in problems[0].message
    assert "reads '/never_written', which no node writes" in problems[1].message


def test_post_conditions_run_by_the_result_then_post(build, script, tick):
    script.statuses = {"p": [F]}
    tree = build('Probe: {name: p, _onSuccess: "r := 1", _onFailure: "r := 2", _post: "n := 7"}')
    assert tick(tree) == F
    assert (Blackboard.get("/r"), Blackboard.get("/n")) == (2, 7)


def test_on_halted_runs_when_a_running_node_is_halted(build, script, tick):
    script.statuses = {"guard": [S, F], "p": [R]}
    tree = build('ReactiveSequence: {children: [Probe: {name: guard}, Probe: {name: p, _onHalted: "halted := true"}]}')
    assert [tick(tree), tick(tree)] == [R, F]
    assert Blackboard.get("/halted") == 1.0
