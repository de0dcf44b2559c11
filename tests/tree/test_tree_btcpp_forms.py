"""The forms BehaviorTree.CPP 4.10 reads: SetBlackboard's entry name, compact tags under a ReactiveSequence."""

from __future__ import annotations

import logging

import py_trees
import pytest

from chaser_bt.tree import load_tree_text, validate_tree_text
from chaser_bt.tree.conversion import convert_text

SET_OLD = """<root BTCPP_format="4" main_tree_to_execute="T">
  <BehaviorTree ID="T">
    <SetBlackboard value="go" output_key="{@phase}"/>
  </BehaviorTree>
</root>
"""


def test_set_blackboard_output_key_names_the_entry(registry, script, clock):
    text = SET_OLD.replace("{@phase}", "@phase")
    tree = load_tree_text(text, source="t.xml", registry=registry)
    py_trees.trees.setup(tree.root, clock=clock, script=script)
    tree.root.tick_once()
    assert py_trees.blackboard.Blackboard.get("/phase") == "go"


def test_the_old_braced_form_still_loads_with_a_warning_that_says_how_to_fix_it(registry, script, clock, caplog):
    with caplog.at_level(logging.WARNING):
        tree = load_tree_text(SET_OLD, source="t.xml", registry=registry)
    assert any("t.xml:3:" in r.getMessage() and "output_key='@phase'" in r.getMessage() for r in caplog.records)
    py_trees.trees.setup(tree.root, clock=clock, script=script)
    tree.root.tick_once()
    assert py_trees.blackboard.Blackboard.get("/phase") == "go"


@pytest.mark.parametrize("target", ["xml", "yaml"])
def test_convert_writes_the_btcpp_form(registry, target):
    output = convert_text(SET_OLD, "t.xml", target, registry)
    assert "{@phase}" not in output and "@phase" in output


def test_an_explicit_tag_directly_under_a_reactive_sequence_is_refused_as_btcpp_does(registry):
    text = """<root BTCPP_format="4" main_tree_to_execute="T">
  <BehaviorTree ID="T">
    <ReactiveSequence>
      <Condition ID="Probe"/>
      <Probe/>
    </ReactiveSequence>
  </BehaviorTree>
</root>
"""
    problems = validate_tree_text(text, source="t.xml", registry=registry)
    assert [(p.line, "write <Probe .../>" in p.message) for p in problems] == [(4, True)]
