"""Trees shipped in trees/ and the example in docs/trees.md stay valid as behaviours change."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from chaser_bt.cli import main
from chaser_bt.tree import validate_tree, validate_tree_text

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("tree", sorted((ROOT / "trees").rglob("*.yaml")), ids=lambda p: p.name)
def test_shipped_tree_validates(tree):
    assert validate_tree(tree) == []


def test_the_complete_example_in_the_tree_docs_validates():
    doc = (ROOT / "docs" / "trees.md").read_text()
    example = re.search(r"## A complete example\s+```yaml\n(.*?)```", doc, re.S)
    assert example, "docs/trees.md lost its complete example"
    assert validate_tree_text(example.group(1), source="docs/trees.md") == []


def test_node_reference_lists_every_behaviour_with_its_ports(capsys):
    assert main(["nodes"]) == 0
    out = capsys.readouterr().out
    assert "GoTo (action)" in out and "waypoint: list[float] (required)" in out
    assert "BatteryAbove (condition)" in out and "Timeout (decorator)" in out
