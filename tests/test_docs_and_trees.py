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


def _subtree_calls(node) -> list[dict]:
    """Every ``SubTree`` call's attributes in a YAML tree, as written."""
    if isinstance(node, dict):
        found = [node["SubTree"]] if isinstance(node.get("SubTree"), dict) else []
        return found + [c for v in node.values() for c in _subtree_calls(v)]
    if isinstance(node, list):
        return [c for v in node for c in _subtree_calls(v)]
    return []


@pytest.mark.parametrize("tree", sorted((ROOT / "trees").glob("*.yaml")), ids=lambda p: p.name)
def test_no_shipped_search_plans_a_set_point_at_its_own_geofence_ceiling(tree):
    """A search grid reaching the fence's ceiling sends the aircraft into the fence (and home on RTL):
    its top (the grid centre's height plus ``z_max_m``) stays 10 m under ``fence_max_alt_m``."""
    import yaml

    calls = _subtree_calls(yaml.safe_load(tree.read_text()))
    fences = [float(c["fence_max_alt_m"]) for c in calls if c.get("ID") == "Safety" and float(c.get("fence_max_alt_m", 0))]
    searches = [c for c in calls if "z_max_m" in c]
    if not fences or not searches:
        pytest.skip(f"{tree.name}: no fence ceiling and search together")
    for s in searches:
        top = float(s.get("grid_center", [0.0, 0.0, 0.0])[2]) + float(s["z_max_m"])
        assert top <= min(fences) - 10.0, f"{tree.name}: {s['ID']} plans up to {top:g} m, fence at {min(fences):g} m"
