"""Validation: every problem found at once, each at the line of the offending YAML node.

Line numbers in these tests are counted by hand from the YAML text; line 1 is ``version: 1``.
"""

from __future__ import annotations

import textwrap

import pytest

from chaser_bt.tree import Problem, TreeError, load_tree, load_tree_text, validate_tree, validate_tree_text


def problems(text: str, registry) -> list[Problem]:
    return validate_tree_text(textwrap.dedent(text).lstrip("\n"), "t.yaml", registry)


def where(found: list[Problem]) -> list[tuple[int, int]]:
    return [(p.line, p.column) for p in found]


def test_a_valid_tree_has_no_problems(registry):
    assert problems(
        """
        version: 1
        trees:
          T:
            Sequence:
              children:
                - Target: {altitude_m: 20}
                - Probe
        """,
        registry,
    ) == []


def test_yaml_syntax_error_reports_its_position(registry):
    found = problems(
        """
        version: 1
        trees:
          T:
            Target: {altitude_m: [1, 2}
        """,
        registry,
    )
    assert len(found) == 1
    assert found[0].line == 4
    assert "YAML syntax error" in found[0].message


def test_missing_version_is_reported_at_the_top(registry):
    found = problems("trees:\n  T: Probe\n", registry)
    assert [(p.line, p.message) for p in found] == [(1, "missing 'version: 1' (the format version)")]


def test_unsupported_version_is_reported_at_its_value(registry):
    found = problems("version: 2\ntrees:\n  T: Probe\n", registry)
    assert where(found) == [(1, 10)]
    assert "unsupported format version 2" in found[0].message


def test_main_naming_no_tree_lists_the_trees(registry):
    found = problems(
        """
        version: 1
        main: Patro
        trees:
          Patrol: Probe
        """,
        registry,
    )
    assert where(found) == [(2, 7)]
    assert found[0].message == "main 'Patro' names no tree; trees: Patrol"


def test_several_trees_need_a_main(registry):
    found = problems("version: 1\ntrees:\n  A: Probe\n  B: Probe\n", registry)
    assert [p.message for p in found] == ["several trees (A, B): name the one to execute with 'main'"]


def test_unknown_node_lists_known_ids_best_matches_first(registry):
    found = problems(
        """
        version: 1
        trees:
          T:
            Sequence:
              children:
                - Probe
                - Targte: {altitude_m: 3}
        """,
        registry,
    )
    assert where(found) == [(7, 11)]
    # A close match is named alone: the whole list would bury it.
    assert found[0].message == "unknown node 'Targte'; did you mean Target?"


def test_unknown_node_like_no_other_lists_the_known_nodes(registry):
    found = problems("version: 1\ntrees:\n  T:\n    Xyzzy\n", registry)
    known = found[0].message.split("known nodes: ")[1].split(", ")
    assert sorted(known) == registry.ids()


def test_misspelt_port_is_answered_with_the_close_name(registry):
    found = problems("version: 1\ntrees:\n  T:\n    Target: {altitude_m: 5, ofset_m: 1}\n", registry)
    assert [p.message for p in found] == ["Target has no port 'ofset_m'; did you mean offset_m?"]


def test_missing_required_port_is_reported_at_the_node(registry):
    found = problems(
        """
        version: 1
        trees:
          T:
            Sequence:
              children:
                - Target
        """,
        registry,
    )
    # altitude_m has no default; offset_m has a default and state a default_key: neither is missing.
    assert [(p.line, p.message) for p in found] == [
        (6, "Target is missing required port 'altitude_m' (float: target altitude)")
    ]


def test_unknown_port_lists_the_nodes_ports(registry):
    found = problems(
        """
        version: 1
        trees:
          T:
            Target:
              altitude_m: 5
              speed_m_s: 3
        """,
        registry,
    )
    assert where(found) == [(6, 7)]
    assert found[0].message == (
        "Target has no port 'speed_m_s'; its ports: altitude_m, offset_m, count, armed, mode, label, state, reached_m"
    )


@pytest.mark.parametrize(
    ("port", "value", "expected"),
    [
        ("altitude_m", "true", "expected float, got bool True"),
        ("altitude_m", "high", "expected float, got str 'high'"),
        ("count", "2.5", "expected int, got float 2.5"),
        ("offset_m", "[1, 2, false]", "item 2: expected float, got bool False"),
        ("mode", "FLY", "expected Mode, got str 'FLY' (one of LOITER, RTL)"),
        ("label", "7", "expected str, got int 7"),
        ("state", "ok", "no literal form: wire it with a {key} reference"),
        ("altitude_m", "null", "null is not a value"),
    ],
)
def test_literal_of_the_wrong_type_says_expected_and_got(registry, port, value, expected):
    text = f"version: 1\ntrees:\n  T:\n    Target:\n      altitude_m: 1\n      {port}: {value}\n"
    if port == "altitude_m":
        text = text.replace("      altitude_m: 1\n", "")
    found = validate_tree_text(text, "t.yaml", registry)
    assert len(found) == 1
    assert found[0].line == (5 if port == "altitude_m" else 6)
    assert found[0].message.startswith(f"port '{port}' of Target: ")
    assert expected in found[0].message


@pytest.mark.parametrize("reference", ["{alt", "{a b}", "{}", "x{alt}", "{{alt}}"])
def test_malformed_reference_is_reported_at_its_value(registry, reference):
    found = problems(
        f"""
        version: 1
        trees:
          T:
            Target: {{altitude_m: "{reference}"}}
        """,
        registry,
    )
    assert where(found) == [(4, 26)]
    assert "malformed blackboard reference" in found[0].message


def test_output_port_needs_a_reference(registry):
    found = problems(
        """
        version: 1
        trees:
          T:
            Target: {altitude_m: 1, reached_m: 4}
        """,
        registry,
    )
    assert [p.message for p in found] == ["output port 'reached_m' of Target takes a {key} reference, got 4"]


def test_structure_problems_composite_decorator_and_leaf(registry):
    found = problems(
        """
        version: 1
        trees:
          T:
            Sequence:
              children:
                - Fallback
                - Inverter:
                    children: [Probe, Probe]
                - Timeout: {msec: 100}
                - Probe:
                    child: Probe
        """,
        registry,
    )
    assert [(p.line, p.message) for p in found] == [
        (6, "Fallback is a composite: give it 'children: [...]'"),
        (7, "Inverter is a decorator: give it exactly one 'child', got 2"),
        (9, "Timeout is a decorator: give it exactly one 'child', got 0"),
        (10, "Probe is a leaf (Action): it takes no children"),
    ]


def test_duplicate_tree_ids_are_reported_at_the_second(registry):
    found = problems(
        """
        version: 1
        main: A
        trees:
          A: Probe
          B: Probe
          A: Probe
        """,
        registry,
    )
    assert [(p.line, p.message) for p in found] == [
        (6, "duplicate key 'A' in trees (tree ids must be unique) (first at line 4)")
    ]


def test_unknown_subtree_is_reported(registry):
    found = problems(
        """
        version: 1
        main: Main
        trees:
          Main:
            SubTree: {ID: Lanch}
          Launch: Probe
        """,
        registry,
    )
    assert [(p.line, p.message) for p in found] == [
        (5, "SubTree ID 'Lanch' names no tree in this file; trees: Main, Launch")
    ]


def test_recursive_subtree_is_reported_with_its_cycle(registry):
    found = problems(
        """
        version: 1
        main: Main
        trees:
          Main:
            SubTree: {ID: A}
          A:
            Sequence:
              children:
                - Probe
                - SubTree: {ID: Main}
        """,
        registry,
    )
    assert [(p.line, p.message) for p in found] == [(10, "SubTree 'Main' is recursive: Main -> A -> Main")]


def test_subtree_port_the_subtree_never_uses_is_reported(registry):
    found = problems(
        """
        version: 1
        main: Main
        trees:
          Main:
            SubTree: {ID: Climb, altitud_m: 5}
          Climb:
            Target: {altitude_m: "{altitude_m}"}
        """,
        registry,
    )
    assert [(p.line, p.message) for p in found] == [
        (5, "SubTree 'Climb' uses no key 'altitud_m'; its keys: altitude_m"),
        (7, "port 'altitude_m' of Target reads '/Climb/altitude_m', which no node writes and 'inputs' does not list"),
    ]


def test_a_subtree_literal_is_typed_by_the_port_that_reads_it(registry):
    found = problems(
        """
        version: 1
        main: Main
        trees:
          Main:
            SubTree: {ID: Climb, altitude_m: yes}
          Climb:
            Target: {altitude_m: "{altitude_m}"}
        """,
        registry,
    )
    assert [(p.line, p.message) for p in found] == [(5, "port 'altitude_m' of Target: expected float, got bool True")]


def test_reading_a_key_nothing_writes_is_reported_unless_it_is_an_input(registry):
    text = """
        version: 1
        trees:
          T:
            Target: {altitude_m: "{cue_alt}"}
        """
    found = problems(text, registry)
    assert [(p.line, p.message) for p in found] == [
        (4, "port 'altitude_m' of Target reads '/cue_alt', which no node writes and 'inputs' does not list")
    ]
    assert problems(text.replace("version: 1\n", "version: 1\n        inputs: [cue_alt]\n"), registry) == []


def test_a_key_written_by_an_output_port_satisfies_a_reader(registry):
    assert problems(
        """
        version: 1
        trees:
          T:
            Sequence:
              children:
                - Target: {altitude_m: 1, reached_m: "{alt}"}
                - Target: {altitude_m: "{alt}"}
        """,
        registry,
    ) == []


def test_attributes_not_indented_under_the_node_are_explained(registry):
    found = problems(
        """
        version: 1
        trees:
          T:
            Sequence:
              children:
                - Target:
                  altitude_m: 5
        """,
        registry,
    )
    assert where(found) == [(6, 11)]
    assert "indent the attributes under the node id" in found[0].message


def test_every_problem_is_reported_at_once_in_line_order(registry):
    found = problems(
        """
        version: 1
        bogus: 1
        trees:
          T:
            Sequence:
              children:
                - Target: {altitude_m: false}
                - Probe: {colour: red}
                - Hoover
                - Inverter
        """,
        registry,
    )
    assert where(found) == [(2, 1), (7, 32), (8, 19), (9, 11), (10, 11)]


def test_tree_error_lists_every_problem_one_per_line(registry):
    with pytest.raises(TreeError) as caught:
        load_tree_text("version: 3\ntrees:\n  T:\n    Nope\n", source="m.yaml", registry=registry)
    assert str(caught.value).splitlines() == [
        "m.yaml:1:10: unsupported format version 3: this loader reads version 1",
        str(caught.value.problems[1]),
    ]
    assert caught.value.problems[1].line == 4


def test_a_tree_with_problems_builds_nothing(registry, monkeypatch):
    built = []
    monkeypatch.setattr(registry.get("Probe").cls, "__init__", lambda self, *a, **k: built.append(self))
    with pytest.raises(TreeError):
        load_tree_text("version: 1\ntrees:\n  T:\n    Sequence: {children: [Probe, Nope]}\n", registry=registry)
    assert built == []


def test_validate_tree_reads_a_file_and_names_it(tmp_path, registry):
    path = tmp_path / "bad.yaml"
    path.write_text("version: 1\ntrees:\n  T: Nope\n")
    found = validate_tree(path, registry)
    assert [(p.file, p.line, p.column) for p in found] == [(str(path), 3, 6)]
    assert str(found[0]).startswith(f"{path}:3:6: unknown node 'Nope'")


def test_load_tree_of_a_missing_file_is_a_tree_error(tmp_path, registry):
    with pytest.raises(TreeError, match="cannot read tree file"):
        load_tree(tmp_path / "missing.yaml", registry)
