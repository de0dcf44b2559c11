"""BehaviorTree.CPP v4 XML: the format, includes, bad input, and patrol.xml flying exactly like patrol.yaml."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest
from py_trees.common import Status

from chaser_bt.cli import main as cli_main
from chaser_bt.tree import TreeError, load_tree, validate_tree, validate_tree_text
from chaser_bt.tree.conversion import typed_document
from chaser_bt.tree.documents import read_document
from chaser_bt.tree.xml_format import parse_xml

ROOT = Path(__file__).resolve().parents[2]
S, F, R = Status.SUCCESS, Status.FAILURE, Status.RUNNING


def xml(body: str, root_attrs: str = 'BTCPP_format="4" main_tree_to_execute="T"') -> str:
    return f"<root {root_attrs}>\n{textwrap.dedent(body).strip()}\n</root>\n"


def messages(problems) -> list[str]:
    return [p.message for p in problems]


# ---- the format


def test_patrol_xml_and_patrol_yaml_are_the_same_tree(registry):
    from chaser_bt.tree import default_registry

    reg = default_registry()
    a, pa = read_document(ROOT / "trees" / "patrol.xml")
    b, pb = read_document(ROOT / "trees" / "patrol.yaml")
    assert pa == pb == []
    ta, tb = typed_document(a, reg), typed_document(b, reg)
    assert (ta.main, ta.trees) == (tb.main, tb.trees)
    assert validate_tree(ROOT / "trees" / "patrol.xml") == []


def test_compact_and_explicit_node_forms_are_the_same_node():
    compact, _ = parse_xml(xml('<BehaviorTree ID="T"><Probe name="p" _while="ok"/></BehaviorTree>'))
    explicit, _ = parse_xml(xml('<BehaviorTree ID="T"><Action ID="Probe" name="p" _while="ok"/></BehaviorTree>'))
    assert compact.trees == explicit.trees
    assert compact.trees["T"].root.conditions["_while"].value == "ok"


def test_port_text_is_typed_by_the_port_declaration(build_xml, script, tick):
    tree = build_xml('<Target name="t" altitude_m="20" offset_m="1;2.5;3" count="4" armed="true" mode="RTL" label="hi there"/>')
    assert tick(tree) == S
    reads = script.reads["t"]
    assert (reads["altitude_m"], reads["offset_m"], reads["count"], reads["armed"], reads["label"]) == (
        20.0,
        [1.0, 2.5, 3.0],
        4,
        True,
        "hi there",
    )
    assert reads["mode"].name == "RTL"


def test_subtrees_get_their_own_scope_remapping_and_autoremap(build_xml, script, tick):
    import py_trees

    tree = build_xml(
        """
        <BehaviorTree ID="T">
          <Sequence>
            <SetBlackboard value="7.5" output_key="{alt}"/>
            <SubTree ID="Climb" name="first" target="{alt}"/>
            <SubTree ID="Climb" name="second" target="9"/>
            <SubTree ID="Shared" _autoremap="true"/>
          </Sequence>
        </BehaviorTree>
        <BehaviorTree ID="Climb">
          <Target name="climb" altitude_m="{target}" reached_m="{reached}"/>
        </BehaviorTree>
        <BehaviorTree ID="Shared">
          <Target name="shared" altitude_m="{alt}" reached_m="{shared_out}"/>
        </BehaviorTree>
        """,
        trees=True,
    )
    assert tick(tree) == S
    bb = py_trees.blackboard.Blackboard
    assert bb.get("/first/reached") == 7.5  # a key of the subtree's own scope
    assert bb.get("/second/reached") == 9.0  # the literal, typed by the port that reads it
    assert bb.get("/shared_out") == 7.5  # _autoremap: the parent's keys pass through
    assert script.reads["shared"]["altitude_m"] == 7.5


def test_mission_inputs_are_a_root_attribute():
    document, problems = parse_xml(xml('<BehaviorTree ID="T"><AlwaysSuccess/></BehaviorTree>', 'BTCPP_format="4" mission_inputs="cue; battery"'))
    assert problems == []
    assert [arg.value for arg in document.inputs] == ["cue", "battery"]


def test_groot2_editor_attributes_and_a_saved_node_model_are_ignored(registry):
    text = xml(
        """
        <BehaviorTree ID="T" _fullpath="">
          <Probe name="p" _uid="3" _description="drawn in Groot2"/>
        </BehaviorTree>
        <TreeNodesModel><Action ID="Probe"/></TreeNodesModel>
        """
    )
    assert validate_tree_text(text, "t.xml", registry) == []


def test_unknown_ids_are_rejected_never_replaced(registry):
    text = xml('<BehaviorTree ID="T"><Sequence><Probe/><Prob/><Action ID="NotANode"/></Sequence></BehaviorTree>')
    problems = validate_tree_text(text, "t.xml", registry)
    assert [(p.line, p.column) for p in problems] == [(2, 40), (2, 47)]
    assert problems[0].message.startswith("unknown node 'Prob'; did you mean Probe?")
    assert problems[1].message.startswith("unknown node 'NotANode'")
    with pytest.raises(TreeError):
        from chaser_bt.tree import load_tree_text

        load_tree_text(text, "t.xml", registry)


def test_every_problem_is_reported_with_its_line_and_column(registry):
    text = xml(
        """
        <BehaviorTree ID="T">
          <Sequence>
            <Target altitude_m="high"
                    speed="3"/>
            <SubTree ID="Missing"/>
            <Repeat num_cycles="2"><Probe/><Probe/></Repeat>
          </Sequence>
        </BehaviorTree>
        <BehaviorTree ID="T"><Probe/></BehaviorTree>
        """
    )
    problems = validate_tree_text(text, "t.xml", registry)
    found = [(p.line, p.column, p.message.split(":")[0][:40]) for p in problems]
    assert found == [
        (4, 13, "port 'altitude_m' of Target"),
        (5, 13, "Target has no port 'speed'; its ports"),
        (6, 5, "SubTree ID 'Missing' names no tree in th"),
        (7, 5, "Repeat is a decorator"),
        (10, 1, "duplicate tree ID 'T' (first at line 2)"),
    ]


# ---- includes


def test_includes_merge_trees_from_xml_and_yaml_files_relative_to_the_including_file(tmp_path, registry):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "leg.yaml").write_text("version: 1\ninputs: [alt]\ntrees:\n  Leg:\n    Target: {altitude_m: '{alt}'}\n")
    (tmp_path / "sub" / "more.xml").write_text(xml('<include path="leg.yaml"/><BehaviorTree ID="More"><Probe/></BehaviorTree>', 'BTCPP_format="4"'))
    main = tmp_path / "main.xml"
    main.write_text(xml('<include path="sub/more.xml"/><BehaviorTree ID="T"><Sequence><SubTree ID="Leg" _autoremap="true"/><SubTree ID="More"/></Sequence></BehaviorTree>'))
    tree = load_tree(main, registry)
    assert tree.inputs == ("/alt",)
    leg, more = tree.root.children
    assert (leg.name, leg.children[0].name, more.name, more.children[0].name) == ("Leg", "Target", "More", "Probe")


def test_a_missing_include_is_reported_at_the_include(tmp_path, registry):
    main = tmp_path / "main.xml"
    main.write_text(xml('<include path="nope.xml"/>\n<BehaviorTree ID="T"><Probe/></BehaviorTree>'))
    problems = validate_tree(main, registry)
    assert [(p.file, p.line, p.column) for p in problems] == [(str(main), 2, 10)]
    assert "included file 'nope.xml' not found" in problems[0].message


def test_include_cycles_and_trees_defined_twice_across_files_are_problems(tmp_path, registry):
    (tmp_path / "a.xml").write_text(xml('<include path="b.xml"/><BehaviorTree ID="T"><Probe/></BehaviorTree>'))
    (tmp_path / "b.xml").write_text(xml('<include path="a.xml"/><BehaviorTree ID="T"><Probe/></BehaviorTree>', 'BTCPP_format="4"'))
    problems = messages(validate_tree(tmp_path / "a.xml", registry))
    assert any(m.startswith("include cycle: a.xml -> b.xml -> a.xml") for m in problems)
    assert any(m.startswith("duplicate tree ID 'T'") for m in problems)


def test_yaml_includes_too(tmp_path, registry):
    (tmp_path / "leg.xml").write_text(xml('<BehaviorTree ID="Leg"><Probe name="leg"/></BehaviorTree>', 'BTCPP_format="4"'))
    main = tmp_path / "main.yaml"
    main.write_text("version: 1\nmain: T\nincludes: [leg.xml]\ntrees:\n  T:\n    SubTree: {ID: Leg}\n")
    assert validate_tree(main, registry) == []


# ---- bad input: exit 2 with file, line and reason


@pytest.mark.parametrize(
    ("text", "line", "reason"),
    [
        ('<root BTCPP_format="4">\n  <BehaviorTree ID="T">\n    <Probe>\n  </BehaviorTree>\n</root>', 4, "malformed XML: mismatched tag"),
        ('<root BTCPP_format="3" main_tree_to_execute="T">\n<BehaviorTree ID="T"><Probe/></BehaviorTree></root>', 1, "unsupported BTCPP_format '3'"),
        ('<root main_tree_to_execute="T">\n<BehaviorTree ID="T"><Probe/></BehaviorTree></root>', 1, 'missing BTCPP_format="4"'),
        ('<root BTCPP_format="4">\n<include path="missing/sub.xml"/>\n<BehaviorTree ID="T"><Probe/></BehaviorTree></root>', 2, "included file 'missing/sub.xml' not found"),
        ('<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY a "aaaa"><!ENTITY b "&a;&a;&a;">]>\n<root/>', 2, "a DOCTYPE is not allowed"),
        ('<root BTCPP_format="4"><BehaviorTree ID="T"><Probe x="&ext;"/></BehaviorTree></root>', 1, "malformed XML: undefined entity"),
        ("", 1, "malformed XML: no element found"),
    ],
)
def test_bad_xml_exits_2_naming_file_line_and_reason(tmp_path, capsys, text, line, reason):
    path = tmp_path / "bad.xml"
    path.write_text(text)
    assert cli_main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}:{line}:" in err
    assert reason in err


def test_a_billion_laughs_is_refused_before_any_expansion():
    laughs = '<?xml version="1.0"?>\n<!DOCTYPE lolz [\n' + "".join(
        f'<!ENTITY l{i} "{("&l%d;" % (i - 1)) * 10 if i else "lol"}">' for i in range(10)
    ) + ']>\n<root BTCPP_format="4">&l9;</root>'
    document, problems = parse_xml(laughs, "lolz.xml")
    assert messages(problems) == ["a DOCTYPE is not allowed in a tree file (entities could expand without bound)"]
    assert document.trees == {}


# ---- the acceptance test: the same mission in both formats sends the same commands


@pytest.mark.parametrize("seed", [3])
def test_patrol_xml_rehearses_exactly_like_patrol_yaml(seed):
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    from sitl.bench.rehearsal import rehearse

    def fly(tree: str) -> tuple[bytes, object]:
        chunks: list[bytes] = []
        report = rehearse(ROOT / "trees" / tree, ROOT / "sitl" / "scenarios" / "patrol.yaml", seed, ground_tap=chunks.append)
        return b"".join(chunks), report

    yaml_bytes, yaml_report = fly("patrol.yaml")
    xml_bytes, xml_report = fly("patrol.xml")
    assert yaml_report.outcome == xml_report.outcome == "landed"

    def commands(data: bytes) -> list[tuple]:
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True
        decoded = parser.parse_buffer(data) or []
        return [(m.get_type(), tuple(sorted(m.to_dict().items()))) for m in decoded if m.get_type() != "BAD_DATA"]

    yaml_cmds, xml_cmds = commands(yaml_bytes), commands(xml_bytes)
    kinds = {kind for kind, _ in yaml_cmds}
    # The comparison means something: the mission armed, took off, flew set-points and returned.
    assert {"COMMAND_LONG", "SET_POSITION_TARGET_GLOBAL_INT"} <= kinds
    assert sum(1 for kind, _ in yaml_cmds if kind == "SET_POSITION_TARGET_GLOBAL_INT") >= 4
    assert xml_cmds == yaml_cmds
    assert xml_bytes == yaml_bytes


def test_show_as_graphviz_dot_has_one_node_per_behaviour_and_one_edge_per_child(registry):
    import re

    from chaser_bt.tree import load_tree_text
    from chaser_bt.tree.display import render_dot

    tree = load_tree_text(
        xml('<BehaviorTree ID="T"><Sequence name="say &quot;hi&quot;"><Probe _while="true"/><Target altitude_m="3"/></Sequence></BehaviorTree>'),
        "t.xml",
        registry,
    )
    dot = render_dot(tree)
    behaviours = list(tree.root.iterate())
    assert len(re.findall(r"^  n\d+ \[label=", dot, re.M)) == len(behaviours) == 4  # the wrapper counts
    assert len(re.findall(r"^  n\d+ -> n\d+;$", dot, re.M)) == len(behaviours) - 1
    assert 'label="say \\"hi\\"\\n(Sequence)"' in dot
    assert "altitude_m=3.0" in dot
    assert dot.startswith('digraph "T" {') and dot.endswith("}\n")
