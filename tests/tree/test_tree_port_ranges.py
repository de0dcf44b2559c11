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
        ("Hover: {duration_s: -1}", "m.yaml:6:31: port 'duration_s' of Hover must be 0..86400, got -1"),
        (
            "GoTo: {waypoint: [0, 0, 10], acceptance_radius_m: -0.5}",
            "m.yaml:6:61: port 'acceptance_radius_m' of GoTo must be >= 0, got -0.5",
        ),
        ("ArmAndTakeoff: {altitude_m: -5}", "m.yaml:6:39: port 'altitude_m' of ArmAndTakeoff must be > 0 and <= 500, got -5"),
        ("ArmAndTakeoff: {altitude_m: 0}", "m.yaml:6:39: port 'altitude_m' of ArmAndTakeoff must be > 0 and <= 500, got 0"),
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
        "m.yaml:7:31: port 'duration_s' of Hover must be 0..86400, got -1",
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


INF = "must be a finite number, got inf (a value too large for a float reads as inf)"


@pytest.mark.parametrize(
    ("leaf", "problem"),
    [
        ('ArmAndTakeoff: {altitude_m: "1e400"}', f"m.yaml:6:39: port 'altitude_m' of ArmAndTakeoff {INF}"),
        ("ArmAndTakeoff: {altitude_m: 1.0e400}", f"m.yaml:6:39: port 'altitude_m' of ArmAndTakeoff {INF}"),
        (f"ArmAndTakeoff: {{altitude_m: {'9' * 400}}}", f"m.yaml:6:39: port 'altitude_m' of ArmAndTakeoff {INF}"),
        ('Hover: {duration_s: "inf"}', f"m.yaml:6:31: port 'duration_s' of Hover {INF}"),
        ("Hover: {duration_s: .inf}", f"m.yaml:6:31: port 'duration_s' of Hover {INF}"),
        ("Hover: {duration_s: .nan}", "m.yaml:6:31: port 'duration_s' of Hover must be 0..86400, got nan"),
        ("GoTo: {waypoint: [0, .inf, 10]}", f"m.yaml:6:28: port 'waypoint' of GoTo {INF} (in [0.0, inf, 10.0])"),
        ("GoTo: {waypoint: [0, -.inf, 10]}",
         "m.yaml:6:28: port 'waypoint' of GoTo must be a finite number, got -inf (a value too large for a float reads "
         "as inf) (in [0.0, -inf, 10.0])"),
    ],
)
def test_numbers_on_ports_are_finite(leaf, problem):
    assert yaml_problems(leaf) == [problem]


def test_absurd_magnitudes_are_refused_where_a_leaf_bounds_them():
    assert yaml_problems("ArmAndTakeoff: {altitude_m: 100000}") == [
        "m.yaml:6:39: port 'altitude_m' of ArmAndTakeoff must be > 0 and <= 500, got 100000"]
    assert yaml_problems("RHCSearch: {horizon: 1000}") == ["m.yaml:6:32: port 'horizon' of RHCSearch must be 1..8, got 1000"]
    assert yaml_problems("Hover: {duration_s: 1e12}") == [
        "m.yaml:6:31: port 'duration_s' of Hover must be 0..86400, got 1000000000000"]
    assert yaml_problems("LoiterOverFind: {duration_s: 1e6}") == [
        "m.yaml:6:40: port 'duration_s' of LoiterOverFind must be 0..86400, got 1000000"]
    assert yaml_problems("Hover: {duration_s: 86400}") == []  # a day is the longest hold


def test_a_wait_is_bounded_as_a_hold():
    """Wait's duration_s takes at most a day, as Hover's and LoiterOverFind's do, in YAML and in XML."""
    assert yaml_problems("Wait: {duration_s: 1e12}") == [
        "m.yaml:6:30: port 'duration_s' of Wait must be 0..86400, got 1000000000000"]
    assert yaml_problems("Wait: {duration_s: -1}") == ["m.yaml:6:30: port 'duration_s' of Wait must be 0..86400, got -1"]
    assert yaml_problems("Wait: {duration_s: 86400}\nWait: {duration_s: 0}") == []
    assert xml_problems(
        """
        <root BTCPP_format="4">
          <BehaviorTree ID="M">
            <Wait duration_s="90000"/>
          </BehaviorTree>
        </root>
        """
    ) == ["m.xml:3:11: port 'duration_s' of Wait must be 0..86400, got 90000"]


def test_a_sleep_is_bounded_as_a_wait_in_milliseconds():
    """BT.CPP's Sleep takes 0 to a day's 86,400,000 ms; a negative one is named as before."""
    assert xml_problems(
        """
        <root BTCPP_format="4">
          <BehaviorTree ID="M">
            <Sequence><Sleep msec="86400000"/><Sleep msec="0"/></Sequence>
          </BehaviorTree>
        </root>
        """
    ) == []
    assert xml_problems(
        """
        <root BTCPP_format="4">
          <BehaviorTree ID="M">
            <Sequence><Sleep msec="86400001"/><Sleep msec="-5"/></Sequence>
          </BehaviorTree>
        </root>
        """
    ) == ["m.xml:3:22: port 'msec' of Sleep must be 0..86400000, got 86400001",
          "m.xml:3:46: port 'msec' of Sleep must be 0..86400000, got -5"]


@pytest.mark.parametrize(
    ("leaf", "problem"),
    [
        ("ArmAndTakeoff: {altitude_m: -1e308}", "must be > 0 and <= 500, got -1e+308"),
        ("ArmAndTakeoff: {altitude_m: 1.5e300}", "must be > 0 and <= 500, got 1.5e+300"),
        (f"RHCSearch: {{horizon: {'9' * 400}}}", "must be 1..8, got an integer of 400 digits"),
        (f"RHCSearch: {{horizon: {'9' * 19}}}", f"must be 1..8, got {'9' * 19}"),
    ],
)
def test_a_huge_value_is_named_in_a_few_characters(leaf, problem):
    """Not the 309 digits of -1e308 as an integer, nor an OverflowError for an integer past a float."""
    (found,) = yaml_problems(leaf)
    assert found.endswith(problem), found


def test_numbers_in_xml_are_finite_on_every_port_and_in_scripts():
    found = xml_problems(
        """
        <root BTCPP_format="4" main_tree_to_execute="M">
          <BehaviorTree ID="M">
            <Sequence>
              <ArmAndTakeoff altitude_m="1e400"/>
              <Hover duration_s="inf"/>
              <SetBlackboard output_key="x" value=".inf"/>
              <Script code="y := 1e400"/>
              <SubTree ID="Up" altitude_m="-1e999"/>
            </Sequence>
          </BehaviorTree>
          <BehaviorTree ID="Up">
            <ArmAndTakeoff altitude_m="{altitude_m}"/>
          </BehaviorTree>
        </root>
        """
    )
    assert found == [
        f"m.xml:4:22: port 'altitude_m' of ArmAndTakeoff {INF}",
        f"m.xml:5:14: port 'duration_s' of Hover {INF}",
        f"m.xml:6:37: port 'value' of SetBlackboard {INF}",
        "m.xml:7:15: port 'code' of Script: number '1e400' at column 6 is too large for a float in 'y := 1e400'",
        "m.xml:8:24: port 'altitude_m' of ArmAndTakeoff must be a finite number, got -inf (a value too large for a "
        "float reads as inf)",
    ]


def test_a_script_refuses_numbers_no_float_holds():
    from chaser_bt.tree.expressions import ExpressionError, parse_expression

    with pytest.raises(ExpressionError, match="'1e400' at column 6 is too large for a float"):
        parse_expression("x := 1e400")
    with pytest.raises(ExpressionError, match="number at column 6 has 5000 digits: too large"):
        parse_expression("x := " + "9" * 5000)  # int() would raise ValueError past 4300 digits
    parse_expression("x := 1e300")


def test_a_port_may_take_inf_if_it_says_so_but_never_nan():
    port = input_port(float, "Wait at most this long (s); inf = for ever", minimum=0, infinite=True)
    assert port.violation(float("inf")) is None
    assert port.violation(float("nan")) == "must be >= 0, got nan"
    assert input_port(float, "x", infinite=True).violation(float("nan")) == "must be a number, got nan"
    assert input_port(float, "x").violation(float("-inf")) == "must be a finite number, got -inf (a value too large for a float reads as inf)"
    with pytest.raises(ValueError, match="finite"):
        input_port(float, "x", default=float("inf"))


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
    assert "    in  altitude_m: float = 20.0 [> 0 and <= 500]  Take-off altitude above home (m)" in reference
    assert "<input_port name=\"duration_s\" type=\"float\" default=\"0.0\">Hold this long (s); 0 = until halted [0..86400]" in (
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
