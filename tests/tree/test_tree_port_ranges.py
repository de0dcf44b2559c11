"""Port bounds and shapes: what validates flies (issue 20).

Each bad value below once validated and failed in the air; now the validator refuses it at its
file:line and names the allowed range or shape, beside every other problem of the tree.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from chaser_bt.tree import default_registry, input_port, validate_tree, validate_tree_text
from chaser_bt.tree.display import render_node_reference
from chaser_bt.tree.node_model import node_model_xml

ROOT = Path(__file__).resolve().parents[2]


def yaml_problems(leaves: str) -> list[str]:
    """Problems of a one-sequence YAML tree whose children are ``leaves`` (one per line)."""
    children = "\n".join(f"        - {leaf.strip()}" for leaf in leaves.strip().splitlines())
    text = f"version: 1\ntrees:\n  M:\n    Sequence:\n      children:\n{children}\n"
    return [str(p) for p in validate_tree_text(text, "m.yaml", default_registry())]


def xml_problems(body: str) -> list[str]:
    text = textwrap.dedent(body).strip()
    return [str(p) for p in validate_tree_text(text, "m.xml", default_registry())]


@pytest.mark.parametrize(
    ("leaf", "problem"),
    [
        ("GoTo: {waypoint: [20, 0]}", "m.yaml:6:28: port 'waypoint' of GoTo needs 3 items, got 2: [20.0, 0.0]"),
        ("Hover: {duration_s: -1}", "m.yaml:6:31: port 'duration_s' of Hover must be >= 0, got -1"),
        (
            "GoTo: {waypoint: [0, 0, 10], acceptance_radius_m: -0.5}",
            "m.yaml:6:61: port 'acceptance_radius_m' of GoTo must be >= 0, got -0.5",
        ),
        ("ArmAndTakeoff: {altitude_m: -5}", "m.yaml:6:39: port 'altitude_m' of ArmAndTakeoff must be > 0, got -5"),
        ("ArmAndTakeoff: {altitude_m: 0}", "m.yaml:6:39: port 'altitude_m' of ArmAndTakeoff must be > 0, got 0"),
        ("BatteryAbove: {percent: 250}", "m.yaml:6:35: port 'percent' of BatteryAbove must be 0..100, got 250"),
        ("BatteryAbove: {percent: -1}", "m.yaml:6:35: port 'percent' of BatteryAbove must be 0..100, got -1"),
    ],
)
def test_the_issues_bad_values_are_refused_where_written(leaf, problem):
    assert yaml_problems(leaf) == [problem]


def test_every_bad_value_is_reported_together_with_the_other_problems():
    found = yaml_problems(
        """
        GoTo: {waypoint: [20, 0]}
        Hover: {duration_s: -1}
        Hovr
        """
    )
    assert found == [
        "m.yaml:6:28: port 'waypoint' of GoTo needs 3 items, got 2: [20.0, 0.0]",
        "m.yaml:7:31: port 'duration_s' of Hover must be >= 0, got -1",
        "m.yaml:8:11: unknown node 'Hovr'; did you mean Hover?",
    ]


def test_edge_values_inside_the_bounds_pass():
    assert yaml_problems(
        """
        ArmAndTakeoff: {altitude_m: 0.1, tolerance_m: 0}
        GoTo: {waypoint: [-20, 0, 0], acceptance_radius_m: 0, speed_mps: 0, resend_s: 0}
        Hover: {duration_s: 0}
        BatteryAbove: {percent: 0}
        BatteryAbove: {percent: 100}
        """
    ) == []


def test_xml_attribute_text_is_checked_like_yaml():
    found = xml_problems(
        """
        <root BTCPP_format="4">
          <BehaviorTree ID="M">
            <Sequence>
              <GoTo waypoint="20;0"/>
              <BatteryAbove percent="250"/>
            </Sequence>
          </BehaviorTree>
        </root>
        """
    )
    assert found == [
        "m.xml:4:13: port 'waypoint' of GoTo needs 3 items, got 2: [20.0, 0.0]",
        "m.xml:5:21: port 'percent' of BatteryAbove must be 0..100, got 250",
    ]


def test_a_subtree_literal_is_checked_where_it_is_written():
    # The bad number is at the SubTree's port (line 4), not at the GoTo reading {wp} (line 9).
    found = xml_problems(
        """
        <root BTCPP_format="4" main_tree_to_execute="M">
          <BehaviorTree ID="M">
            <Sequence>
              <SubTree ID="Leg" wp="20;0" radius="-2"/>
            </Sequence>
          </BehaviorTree>
          <BehaviorTree ID="Leg">
            <Sequence>
              <GoTo waypoint="{wp}" acceptance_radius_m="{radius}"/>
            </Sequence>
          </BehaviorTree>
        </root>
        """
    )
    assert found == [
        "m.xml:4:25: port 'waypoint' of GoTo needs 3 items, got 2: [20.0, 0.0]",
        "m.xml:4:35: port 'acceptance_radius_m' of GoTo must be >= 0, got -2",
    ]


def test_a_default_outside_its_own_range_is_refused_at_declaration():
    with pytest.raises(ValueError, match=r"must be >= 0, got -1"):
        input_port(float, "Hold this long (s)", default=-1.0, minimum=0)
    with pytest.raises(ValueError, match=r"needs 3 items, got 2"):
        input_port(list[float], "Centre (m)", default=[0.0, 0.0], length=3)


@pytest.mark.parametrize(
    ("bounds", "text"),
    [
        ({"minimum": 0}, ">= 0"),
        ({"above": 0}, "> 0"),
        ({"minimum": 0, "maximum": 100}, "0..100"),
        ({"maximum": 0.5}, "<= 0.5"),
        ({"above": 0, "maximum": 90}, "> 0 and <= 90"),
        ({"length": 3}, "3 items"),
        ({"length": 2, "minimum": 0}, "2 items, each >= 0"),
        ({}, ""),
    ],
)
def test_bounds_read_as_a_person_writes_them(bounds, text):
    assert input_port(list[float] if "length" in bounds else float, "x", **bounds).constraint == text


def test_list_bounds_apply_to_each_item_and_nan_is_outside():
    port = input_port(list[float], "x", minimum=0, length=2)
    assert port.violation([0.0, 3.0]) is None
    assert port.violation([1.0, -2.0]) == "must be 2 items, each >= 0, got [1.0, -2.0]"
    assert input_port(float, "x", minimum=0).violation(float("nan")) == "must be >= 0, got nan"


def test_the_node_reference_and_the_groot2_model_show_the_bounds():
    registry = default_registry()
    reference = render_node_reference(registry)
    assert "    in  percent: float (required) [0..100]  Minimum remaining capacity (%)" in reference
    assert "    in  altitude_m: float = 20.0 [> 0]  Take-off altitude above home (m)" in reference
    assert "<input_port name=\"duration_s\" type=\"float\" default=\"0.0\">Hold this long (s); 0 = until halted [&gt;= 0]" in (
        node_model_xml(registry)
    )


def test_the_node_reference_gives_a_wrapped_summary_whole():
    # FlyToCue's summary wraps in its docstring; the reference once cut it at "(never".
    line = next(x for x in render_node_reference(default_registry()).splitlines() if x.startswith("FlyToCue"))
    assert "(never below ``min_alt_m``), nose on it." in line


@pytest.mark.parametrize(
    "tree", sorted(p for p in (ROOT / "trees").rglob("*") if p.suffix in (".yaml", ".xml")), ids=lambda p: p.name
)
def test_every_shipped_tree_keeps_the_bounds(tree):
    assert validate_tree(tree) == []
