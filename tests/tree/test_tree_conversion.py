"""YAML <-> BT.CPP XML conversion: generated trees round-trip unchanged; `chaser-bt convert`; the Groot2 node model."""

from __future__ import annotations

import argparse
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from chaser_bt.tree import TreeError, default_registry
from chaser_bt.tree.commands import add_command
from chaser_bt.tree.conversion import convert_text, write_document
from chaser_bt.tree.model import Location, NodeSpec, PortArg, SubTreeRef, TreeDocument, TreeSpec
from chaser_bt.tree.node_model import node_model_xml
from chaser_bt.tree.ports import Port
from chaser_bt.tree.yaml_format import parse_yaml

ROOT = Path(__file__).resolve().parents[2]
_here = Location("t.yaml", 1, 1)

# ---- generated trees, made of nodes the test registry knows, each port given a value of its type

_text = st.text(st.characters(blacklist_categories=("C", "Zl", "Zp", "Cs")), max_size=12)
_floats = st.floats(allow_nan=False)
_keys = st.from_regex(r"[a-z][a-z_]{0,6}", fullmatch=True)
_refs = _keys.map(lambda k: "{" + k + "}")
_expressions = st.sampled_from(["ok", "battery > 30", "!done && count >= 2", "mode == 'RTL'", "@root_flag"])

_TARGET_PORTS = {
    "altitude_m": _floats | _refs,
    "offset_m": st.lists(_floats, max_size=4) | _refs,
    "count": st.integers(-(2**40), 2**40),
    "armed": st.booleans(),
    "mode": st.sampled_from(["LOITER", "RTL"]),
    "label": _text,
    "reached_m": _refs,
}


def _arg(value) -> PortArg:
    return PortArg(value, _here)


@st.composite
def _target(draw) -> NodeSpec:
    ports = draw(st.dictionaries(st.sampled_from(sorted(_TARGET_PORTS)), st.just(None), max_size=5))
    values = {port: _arg(draw(_TARGET_PORTS[port])) for port in ports}
    name = draw(st.none() | _text.filter(bool))
    conditions = draw(st.dictionaries(st.sampled_from(["_while", "_skipIf", "_successIf", "_failureIf"]), _expressions.map(_arg), max_size=2))
    return NodeSpec("Target", _here, name, values, [], conditions=conditions)


_leaves = st.one_of(
    _target(),
    st.builds(lambda n: NodeSpec("Probe", _here, n), st.none() | _text.filter(bool)),
    st.builds(lambda v, k: NodeSpec("SetBlackboard", _here, None, {"value": _arg(v), "output_key": _arg("{" + k + "}")}),
              st.one_of(_floats, st.integers(), st.booleans(), _text, st.lists(st.integers(), max_size=3)), _keys),
    st.builds(lambda alt: NodeSpec("SubTree", _here, None, {"alt": _arg(alt)}, subtree=SubTreeRef("Leg")), _floats | _refs),
)


def _composite(children):
    return st.one_of(
        st.builds(lambda i, c: NodeSpec(i, _here, None, {}, c),
                  st.sampled_from(["Sequence", "SequenceWithMemory", "ReactiveSequence", "Fallback", "ReactiveFallback"]),
                  st.lists(children, min_size=1, max_size=3)),
        st.builds(lambda s, c: NodeSpec("Parallel", _here, None, {"success_count": _arg(s)}, c), st.integers(-3, 3), st.lists(children, min_size=1, max_size=3)),
        st.builds(lambda n, c: NodeSpec("Repeat", _here, None, {"num_cycles": _arg(n)}, [c]), st.integers(-1, 5), children),
        st.builds(lambda c: NodeSpec("Inverter", _here, None, {}, [c]), children),
        st.builds(lambda s, c: NodeSpec("RunOnce", _here, None, {"then_skip": _arg(s)}, [c]), st.booleans(), children),
    )


_nodes = st.recursive(_leaves, _composite, max_leaves=10)


@st.composite
def _documents(draw) -> TreeDocument:
    leg = NodeSpec("Target", _here, "leg", {"altitude_m": _arg("{alt}")})
    trees = {"Main": TreeSpec("Main", draw(_nodes), _here), "Leg": TreeSpec("Leg", leg, _here)}
    inputs = [_arg(k) for k in draw(st.lists(_keys, unique=True, max_size=3))]
    return TreeDocument("t.yaml", 1, "Main", None, inputs, trees)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(_documents())
def test_generated_trees_survive_yaml_to_xml_to_yaml_unchanged(registry, document):
    yaml_text = write_document(document, "yaml", registry)
    xml_text = convert_text(yaml_text, "t.yaml", "xml", registry)
    back = convert_text(xml_text, "t.xml", "yaml", registry)
    assert back == yaml_text
    first, problems = parse_yaml(yaml_text, "t.yaml")
    assert problems == []
    again, _ = parse_yaml(back, "t.yaml")
    assert again == first


def test_literals_take_bt_cpp_text_forms_in_xml(registry):
    text = "version: 1\ntrees:\n  T:\n    Target: {altitude_m: 20, offset_m: [1, 2.5], armed: true, mode: rtl, count: '4'}\n"
    xml_text = convert_text(text, "t.yaml", "xml", registry)
    assert '<Target altitude_m="20.0" offset_m="1.0;2.5" armed="true" mode="RTL" count="4"/>' in xml_text


def test_a_value_xml_cannot_carry_is_refused_not_mangled(registry):
    text = 'version: 1\ntrees:\n  T:\n    Target: {altitude_m: 1, label: "bell \\a"}\n'
    with pytest.raises(TreeError, match="cannot write as xml"):
        convert_text(text, "t.yaml", "xml", registry)


def test_any_typed_ports_carry_yaml_flow_text_so_values_keep_their_type(registry):
    text = 'version: 1\ntrees:\n  T:\n    SetBlackboard: {value: ["a;b", "20", 20], output_key: "{k}"}\n'
    xml_text = convert_text(text, "t.yaml", "xml", registry)
    assert "value=\"[a;b, &#39;20&#39;, 20]\"" in xml_text or "value=\"[a;b, '20', 20]\"" in xml_text
    assert "value: [a;b, '20', 20]" in convert_text(xml_text, "t.xml", "yaml", registry)


def test_a_typed_list_item_that_text_cannot_hold_is_refused():
    from chaser_bt.tree.ports import LiteralError, literal_text

    with pytest.raises(LiteralError, match="';'-separated"):
        literal_text(["a;b", "c"], list[str])
    assert literal_text(["a", "c"], list[str]) == "a;c"


def test_patrol_converts_both_ways(tmp_path, capsys):
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    xml_path, yaml_path = tmp_path / "patrol.xml", tmp_path / "patrol.yaml"
    for argv in (["convert", str(ROOT / "trees" / "patrol.yaml"), str(xml_path)], ["convert", str(xml_path), str(yaml_path)]):
        args = parser.parse_args(argv)
        assert args.handler(args) == 0
    from chaser_bt.tree import validate_tree

    assert validate_tree(xml_path) == validate_tree(yaml_path) == []


def test_convert_exits_2_with_file_line_and_reason_on_bad_input(tmp_path, capsys):
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    bad = tmp_path / "bad.xml"
    bad.write_text('<root BTCPP_format="4">\n  <BehaviorTree ID="T">\n</root>\n')
    args = parser.parse_args(["convert", str(bad), str(tmp_path / "out.yaml")])
    assert args.handler(args) == 2
    err = capsys.readouterr().err
    assert f"{bad}:3:" in err and "malformed XML" in err
    assert not (tmp_path / "out.yaml").exists()
    args = parser.parse_args(["convert", str(tmp_path / "none.yaml"), str(tmp_path / "out.xml")])
    assert args.handler(args) == 2


# ---- the Groot2 node model


def test_export_model_lists_every_registered_node_with_its_ports(tmp_path):
    registry = default_registry()
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    out = tmp_path / "model.xml"
    args = parser.parse_args(["export-model", "--out", str(out), "--include-builtin"])
    assert args.handler(args) == 0
    root = ET.parse(out).getroot()
    assert (root.tag, root.get("BTCPP_format")) == ("root", "4")
    (model,) = root.findall("TreeNodesModel")
    nodes = {node.get("ID"): node for node in model}
    assert sorted(nodes) == registry.ids()
    for node_id, element in nodes.items():
        spec = registry.get(node_id)
        assert element.tag == spec.kind.value
        listed = {(p.tag, p.get("name")) for p in element if p.tag.endswith("_port")}
        declared = {("input_port", n) for n in spec.input_ports} | {("output_port", n) for n in spec.output_ports}
        assert listed == declared, node_id
    goto = {p.get("name"): p for p in nodes["GoTo"] if p.tag == "input_port"}
    assert goto["waypoint"].get("type") == "list[float]"
    assert goto["waypoint"].get("default") is None
    assert goto["acceptance_radius_m"].get("default") == "2.0"
    assert goto["state"].get("default") == "{@vehicle/state}"
    assert goto["acceptance_radius_m"].text == registry.get("GoTo").input_ports["acceptance_radius_m"].description + " [>= 0]"
    assert goto["waypoint"].text.endswith(" [3 items]")
    assert nodes["Parallel"].find("input_port[@name='success_count']").get("default") == "-1"


def test_export_model_leaves_out_btcpp_builtins_by_default(tmp_path):
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    out = tmp_path / "model.xml"
    for option in ("-o", "--output", "--out"):  # -o and --output: the older names
        args = parser.parse_args(["export-model", option, str(out)])
        assert args.out == out and args.handler(args) == 0
    ids = {node.get("ID") for node in ET.parse(out).getroot().find("TreeNodesModel")}
    assert {"GoTo", "ArmAndTakeoff", "Wait"} <= ids  # ours, Wait included (BT.CPP's is Sleep)
    assert not ids & {"Sequence", "Fallback", "Timeout", "AlwaysSuccess", "SetBlackboard"}


def test_the_model_escapes_text_and_round_trips_types(registry):
    model = ET.fromstring(node_model_xml(registry).encode())
    target = model.find("TreeNodesModel/Action[@ID='Target']")
    ports = {p.get("name"): p for p in target}
    assert ports["offset_m"].get("default") == "0.0;0.0;0.0"
    assert ports["mode"].get("default") == "LOITER"
    assert ports["reached_m"].tag == "output_port"
    assert isinstance(registry.get("Target").port("state"), Port)


def test_trees_that_include_subtree_files_convert_exactly(tmp_path):
    # Literals passed to subtrees defined in included files take those subtrees' port types
    # (`3.0` stays a number, not the text '3.0'), so the shipped chase converts both ways.
    from pathlib import Path

    from chaser_bt.tree.conversion import convert_file

    trees = Path(__file__).resolve().parents[2] / "trees"
    convert_file(trees / "chase.yaml", tmp_path / "chase.xml")
    xml_text = (tmp_path / "chase.xml").read_text()
    assert 'link_silence_s="3.0"' in xml_text and "subtrees/safety.xml" in xml_text
    assert '<include path="' + os.path.relpath(trees / "subtrees" / "safety.xml", tmp_path) + '"/>' in xml_text
    back = convert_text(xml_text, str(tmp_path / "chase.xml"), "yaml", base_dir=tmp_path)
    assert "link_silence_s: 3.0" in back
    with pytest.raises(TreeError, match="does not survive conversion"):  # without the includes the types are unknown
        convert_text((trees / "chase.yaml").read_text(), "chase.yaml", "xml")


# ---- includes, validation and comments when converting files


def _convert_command(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    args = parser.parse_args(["convert", *argv])
    return args.handler(args)


def test_an_include_is_rewritten_to_name_the_same_file_from_the_output_folder():
    from chaser_bt.tree.conversion import rebased_include

    assert rebased_include("subtrees/a.xml", Path("/m/trees"), Path("/m/out")) == "../trees/subtrees/a.xml"
    assert rebased_include("../shared/b.yaml", Path("/m/trees"), Path("/m/trees/x/y")) == "../../../shared/b.yaml"
    assert rebased_include("./a.xml", Path("/m/trees"), Path("/m/trees/")) == "./a.xml"  # same folder: as written
    assert rebased_include("/opt/c.xml", Path("/m/trees"), Path("/m/out")) == "/opt/c.xml"


def test_a_tree_with_nested_includes_converts_into_another_folder_and_loads_the_same(tmp_path, capsys):
    from chaser_bt.tree import load_tree, render_tree, validate_tree

    (tmp_path / "src" / "legs").mkdir(parents=True)
    (tmp_path / "src" / "common").mkdir()
    (tmp_path / "abs").mkdir()
    land = tmp_path / "abs" / "land.yaml"
    land.write_text("version: 1\ntrees:\n  GoHome:\n    RTL: {wait_landed: true}\n")
    (tmp_path / "src" / "common" / "home.yaml").write_text("version: 1\ntrees:\n  Home:\n    Airborne\n")
    (tmp_path / "src" / "legs" / "leg.xml").write_text(  # includes a file of its own, relative to itself
        '<root BTCPP_format="4">\n  <include path="../common/home.yaml"/>\n'
        '  <BehaviorTree ID="Leg">\n    <Sequence>\n      <GoTo waypoint="{wp}"/>\n      <SubTree ID="Home"/>\n'
        "    </Sequence>\n  </BehaviorTree>\n</root>\n"
    )
    source = tmp_path / "src" / "main.yaml"
    source.write_text(
        f"version: 1\nmain: Main\nincludes: [legs/leg.xml, {land}]\ntrees:\n  Main:\n    Sequence:\n      children:\n"
        "        - SubTree: {ID: Leg, wp: [100.0, 0.0, 20.0]}\n        - SubTree: {ID: GoHome}\n"
    )
    xml_out, yaml_out = tmp_path / "out" / "deep" / "main.xml", tmp_path / "out" / "main.yaml"
    xml_out.parent.mkdir(parents=True)
    assert _convert_command([str(source), str(xml_out)]) == 0
    assert _convert_command([str(xml_out), str(yaml_out)]) == 0
    xml_text = xml_out.read_text()
    assert '<include path="../../src/legs/leg.xml"/>' in xml_text and f'<include path="{land}"/>' in xml_text
    assert f"includes: [../src/legs/leg.xml, {land}]" in yaml_out.read_text()
    assert validate_tree(xml_out) == validate_tree(yaml_out) == []
    assert render_tree(load_tree(yaml_out)) == render_tree(load_tree(source))  # XML shows SubTree literals as text
    assert "waypoint" in render_tree(load_tree(source)) and "Airborne" in render_tree(load_tree(source))


def test_the_shipped_chase_converts_into_another_folder_and_loads_the_same(tmp_path, capsys):
    from chaser_bt.tree import load_tree, render_tree, validate_tree

    for i, (name, out_name) in enumerate((("chase.xml", "chase.yaml"), ("chase.xml", "chase.xml"), ("chase.yaml", "chase.yaml"))):
        out = tmp_path / str(i) / out_name
        out.parent.mkdir()
        assert _convert_command([str(ROOT / "trees" / name), str(out)]) == 0
        assert validate_tree(out) == []
        if out.suffix == Path(name).suffix == ".xml":  # (YAML writes a SubTree enum literal by name: guided -> GUIDED)
            assert render_tree(load_tree(out)) == render_tree(load_tree(ROOT / "trees" / name))


def test_convert_reports_an_invalid_tree_as_validate_does(tmp_path, capsys):
    from chaser_bt.cli import main

    bad = tmp_path / "bad.yaml"
    bad.write_text("version: 1\ntrees:\n  T:\n    Sequence:\n      children:\n"
                   "        - Airborne\n        - GoTo: {waypoint: [1, 2, 3], speed: 3}\n")
    assert main(["validate", str(bad)]) == 2
    validated = capsys.readouterr().err
    assert _convert_command([str(bad), str(tmp_path / "bad.xml")]) == 2
    assert capsys.readouterr().err == validated + f"chaser-bt: {bad}: not converted\n"
    assert validated.startswith(f"{bad}:7:") and f"{bad}: 1 problem(s)" in validated
    assert not (tmp_path / "bad.xml").exists()


def test_comment_lines_counts_lines_holding_a_comment():
    from chaser_bt.tree.conversion import comment_lines

    # a '#' in a quoted string, in a block scalar or inside a plain scalar is not a comment
    assert comment_lines('a: "x # y"  # one\nb: |\n  # text\n  more\n# two\nd: e#f\n', "yaml") == 2
    # a two-line comment, then one beside an element; escaped text in an attribute is not one
    assert comment_lines('<root>\n<!-- a\n b -->\n<x v="&lt;!-- no --&gt;"/><!--c--></root>', "xml") == 3
    assert comment_lines((ROOT / "trees" / "patrol.yaml").read_text(), "yaml") == 11


def test_convert_warns_of_lost_comments_and_rewrites_its_source_only_with_force(tmp_path, capsys):
    source = tmp_path / "t.yaml"
    text = "# take off\nversion: 1\ntrees:\n  T:\n    ArmAndTakeoff: {altitude_m: 20}  # metres\n"
    source.write_text(text)
    assert _convert_command([str(source), str(source)]) == 2
    assert "is the source" in capsys.readouterr().err and source.read_text() == text
    assert _convert_command([str(source), str(tmp_path / "t.xml")]) == 0
    warning = f"chaser-bt: warning: {source}: 2 comment line(s) not carried over to {tmp_path / 't.xml'}\n"
    assert capsys.readouterr().err == warning
    assert _convert_command([str(source), str(tmp_path / "." / "t.yaml"), "--force"]) == 0
    assert "2 comment line(s)" in capsys.readouterr().err
    assert source.read_text() == "version: 1\ntrees:\n  T:\n    ArmAndTakeoff: {altitude_m: 20.0}\n"
    assert _convert_command([str(tmp_path / "t.xml"), str(tmp_path / "u.yaml")]) == 0
    assert capsys.readouterr().err == ""  # nothing to lose
