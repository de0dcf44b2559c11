"""Loading trees: typed literals, blackboard wiring, subtree scopes, display, the registry."""

from __future__ import annotations

import textwrap

import py_trees
import pytest
from py_trees.common import Status

from chaser_bt.clock import ManualClock
from chaser_bt.tree import (
    Registry,
    TreeError,
    UnknownNode,
    input_port,
    load_tree,
    load_tree_text,
    render_tree,
)
from chaser_bt.tree import registry as registry_module
from chaser_bt.tree.documents import tree_files
from chaser_bt.tree.yaml_format import dump_yaml, parse_yaml

Blackboard = py_trees.blackboard.Blackboard

PATROL = """\
version: 1
main: Patrol
inputs: [cue_alt]
trees:
  Patrol:
    Sequence:
      name: patrol
      children:
        - Target: {name: climb, altitude_m: 20, reached_m: "{climbed}"}
        - Wait: {duration_s: 5}
        - Fallback:
            children:
              - Probe: {name: check}
              - SubTree: {ID: Approach, alt: "{cue_alt}"}
  Approach:
    Target: {name: approach, altitude_m: "{alt}", offset_m: [100, 0, 20], mode: RTL}
"""


def load(text: str, registry) -> object:
    return load_tree_text(textwrap.dedent(text).lstrip("\n"), registry=registry)


def setup(tree, script, clock=None) -> None:
    py_trees.trees.setup(tree.root, clock=clock or ManualClock(0.0), script=script)


def test_a_valid_file_loads_and_ticks_to_success(tmp_path, registry, script, tick):
    path = tmp_path / "patrol.yaml"
    path.write_text(PATROL)
    tree = load_tree(path, registry)
    assert (tree.name, tree.source, tree.inputs) == ("Patrol", path, ("/cue_alt",))
    clock = ManualClock(0.0)
    setup(tree, script, clock)
    Blackboard.set("/cue_alt", 42.0)
    script.statuses = {"check": [Status.FAILURE]}
    assert tick(tree) == Status.RUNNING
    clock.advance(5.0)
    assert tick(tree) == Status.SUCCESS
    assert script.reads["climb"]["altitude_m"] == 20.0
    assert script.reads["approach"]["altitude_m"] == 42.0
    assert Blackboard.get("/climbed") == 20.0


def test_literals_are_typed_by_their_ports(registry, script, tick):
    tree = load(
        """
        version: 1
        trees:
          T:
            Target: {altitude_m: 20, offset_m: [1, 2.5, 3], count: "4", armed: true, mode: rtl, label: hi}
        """,
        registry,
    )
    setup(tree, script)
    tick(tree)
    reads = script.reads["Target"]
    assert reads["altitude_m"] == 20.0 and type(reads["altitude_m"]) is float
    assert reads["offset_m"] == [1.0, 2.5, 3.0] and all(type(v) is float for v in reads["offset_m"])
    assert reads["count"] == 4 and reads["armed"] is True
    assert reads["mode"].name == "RTL" and reads["label"] == "hi"


def test_unwired_ports_fall_back_to_declared_defaults(registry, script, tick):
    tree = load("version: 1\ntrees: {T: {Target: {altitude_m: 1}}}", registry)
    setup(tree, script)
    tick(tree)
    reads = script.reads["Target"]
    assert reads["offset_m"] == [0.0, 0.0, 0.0]
    assert (reads["count"], reads["armed"], reads["mode"].name) == (1, False, "LOITER")
    assert reads["label"] is None


def test_a_reference_is_remapped_to_the_absolute_key_and_read_back(registry, script, tick):
    tree = load(
        """
        version: 1
        inputs: [mission/alt]
        trees:
          T: {Target: {altitude_m: "{mission/alt}"}}
        """,
        registry,
    )
    setup(tree, script)
    Blackboard.set("/mission/alt", 12.5)
    tick(tree)
    assert script.reads["Target"]["altitude_m"] == 12.5


def test_default_key_wires_an_unwired_port_and_an_explicit_reference_overrides_it(registry, script, tick):
    tree = load(
        """
        version: 1
        inputs: [other_state]
        trees:
          T:
            Sequence:
              children:
                - Target: {name: default, altitude_m: 1}
                - Target: {name: explicit, altitude_m: 1, state: "{other_state}"}
        """,
        registry,
    )
    setup(tree, script)
    state_type = registry.get("Target").input_ports["state"].data_type
    vehicle, other = state_type(), state_type()
    Blackboard.set("/vehicle/state", vehicle)
    Blackboard.set("/other_state", other)
    tick(tree)
    assert script.reads["default"]["state"] is vehicle
    assert script.reads["explicit"]["state"] is other


def test_reading_a_value_of_the_wrong_type_at_runtime_is_refused(registry, script):
    tree = load("version: 1\ninputs: [alt]\ntrees: {T: {Target: {altitude_m: '{alt}'}}}", registry)
    setup(tree, script)
    Blackboard.set("/alt", "high")
    with pytest.raises(TypeError):
        tree.root.tick_once()


SUBTREES = """
version: 1
main: Main
trees:
  Main:
    Sequence:
      children:
        - SetBlackboard: {value: 7.5, output_key: "{alt}"}
        - SubTree: {name: first, ID: Climb, altitude_m: "{alt}"}
        - SubTree: {name: second, ID: Climb, altitude_m: 30}
        - SubTree: {ID: Shared, _autoremap: true}
  Climb:
    Sequence:
      children:
        - Target: {altitude_m: "{altitude_m}", reached_m: "{scratch}"}
        - SetBlackboard: {value: done, output_key: "{@climb_status}"}
  Shared:
    Target: {name: shared, altitude_m: "{alt}", reached_m: "{scratch}"}
"""


def test_subtrees_get_their_own_scope_with_remapped_literal_and_root_keys(registry, script, tick):
    tree = load(SUBTREES, registry)
    setup(tree, script)
    assert tick(tree) == Status.SUCCESS
    # Port remapping reaches the parent's key; a literal is typed by the port that reads it.
    first, second = [n for n in tree.root.iterate() if isinstance(n, registry.get("Target").cls)][:2]
    assert first.get_input("altitude_m") == 7.5
    assert second.get_input("altitude_m") == 30.0
    # Unmapped keys stay inside each instance's own scope; {@key} is the root blackboard.
    assert Blackboard.get("/first/scratch") == 7.5
    assert Blackboard.get("/second/scratch") == 30.0
    assert Blackboard.get("/climb_status") == "done"
    # _autoremap passes every key through to the parent scope.
    assert script.reads["shared"]["altitude_m"] == 7.5
    assert Blackboard.get("/scratch") == 7.5


def test_two_unnamed_instances_of_one_subtree_get_distinct_scopes(registry, script, tick):
    tree = load(
        """
        version: 1
        main: Main
        trees:
          Main:
            Sequence:
              children:
                - SubTree: {ID: Climb}
                - SubTree: {ID: Climb}
          Climb:
            Target: {altitude_m: 3, reached_m: "{scratch}"}
        """,
        registry,
    )
    setup(tree, script)
    tick(tree)
    assert Blackboard.exists("/Climb/scratch") and Blackboard.exists("/Climb_2/scratch")


def test_render_tree_shows_names_ids_and_port_values(registry):
    text = render_tree(load(PATROL, registry))
    lines = text.splitlines()
    assert lines[0] == "{-} patrol (Sequence)"
    assert lines[1].startswith("    --> climb (Target)  altitude_m=20.0 reached_m={/climbed} state={/vehicle/state}")
    assert "    --> Wait  duration_s=5.0" in lines
    assert "        -^- Approach (SubTree)  alt={/cue_alt}" in lines
    assert any(line.strip().startswith("--> approach (Target)") and "offset_m=[100.0, 0.0, 20.0]" in line
               and "mode=RTL" in line for line in lines)


def test_render_tree_can_show_statuses(registry, script, tick):
    tree = load("version: 1\ntrees: {T: {Inverter: {child: Probe}}}", registry)
    setup(tree, script)
    tick(tree)
    assert render_tree(tree, show_status=True).splitlines() == [
        "-^- Inverter [✕] -- success -> failure",
        "    --> Probe [✓]",
    ]


def test_dump_yaml_round_trips_the_model():
    document, problems = parse_yaml(PATROL + SUBTREES.split("trees:\n", 1)[1].replace("  Main:", "  Main2:"), "a.yaml")
    assert problems == []
    again, problems = parse_yaml(dump_yaml(document, frozenset({"Inverter"})), "a.yaml")
    assert problems == []
    assert again == document


def test_registry_rejects_a_second_class_under_the_same_id(registry):
    class Probe(py_trees.ports.BehaviourWithPorts, register=False):
        INPUT_PORTS: dict = {}
        OUTPUT_PORTS: dict = {}

    with pytest.raises(ValueError, match="already registered"):
        registry.register(Probe)


def test_registry_rejects_ports_named_like_tree_attributes():
    class Named(py_trees.ports.BehaviourWithPorts, register=False):
        INPUT_PORTS = {"name": input_port(str, "clashes with the instance name")}
        OUTPUT_PORTS: dict = {}

    with pytest.raises(ValueError, match="reserved attribute names as ports: name"):
        Registry().register(Named)


def test_registry_rejects_classes_without_ports():
    with pytest.raises(TypeError):
        Registry().register(py_trees.behaviours.Success)


def test_unknown_node_error_suggests_close_ids(registry):
    with pytest.raises(UnknownNode) as caught:
        registry.get("Fallbak")
    assert caught.value.suggestions[0] == "Fallback"
    assert caught.value.known[0] == "Fallback"


def test_default_registry_imports_entry_point_plugins_once(monkeypatch):
    fresh = Registry.with_control_nodes()
    loads = []

    class Plugin(py_trees.ports.BehaviourWithPorts, register=False):
        INPUT_PORTS: dict = {}
        OUTPUT_PORTS: dict = {}

    class EntryPoint:
        name, value = "test", "tests.plugin"

        def load(self):
            loads.append(1)
            registry_module.register_behaviour(Plugin)

    monkeypatch.setattr(registry_module, "_default", fresh)
    monkeypatch.setattr(registry_module, "_plugins_loaded", False)
    monkeypatch.setattr(registry_module.importlib.metadata, "entry_points", lambda group: [EntryPoint()])
    assert registry_module.default_registry().get("Plugin").cls is Plugin
    assert registry_module.default_registry() is fresh
    assert loads == [1]
    assert "Sequence" in fresh


def test_a_broken_plugin_names_itself(monkeypatch):
    class EntryPoint:
        name, value = "broken", "nowhere"

        def load(self):
            raise ModuleNotFoundError("No module named 'nowhere'")

    monkeypatch.setattr(registry_module, "_default", Registry.with_control_nodes())
    monkeypatch.setattr(registry_module, "_plugins_loaded", False)
    monkeypatch.setattr(registry_module.importlib.metadata, "entry_points", lambda group: [EntryPoint()])
    with pytest.raises(ImportError, match="behaviour plug-in 'broken' \\(nowhere\\)"):
        registry_module.default_registry()


def test_load_tree_raises_for_problems_instead_of_building(registry):
    with pytest.raises(TreeError):
        load("version: 1\ntrees: {T: {Target: {}}}", registry)


def test_reset_blackboard_keeps_the_literals_of_loaded_trees_but_forgets_data(registry, script, tick):
    from chaser_bt.tree import reset_blackboard

    tree = load("version: 1\ninputs: [cue]\ntrees: {T: {Target: {altitude_m: 7, offset_m: [1, 2, 3]}}}", registry)
    Blackboard.set("/cue", 1.0)
    reset_blackboard()
    assert not Blackboard.exists("/cue")
    setup(tree, script)
    tick(tree)
    assert script.reads["Target"]["altitude_m"] == 7.0


def test_a_behaviour_mutating_a_literal_it_read_does_not_change_the_tree(registry, script, tick):
    from chaser_bt.tree import reset_blackboard

    tree = load("version: 1\ntrees: {T: {Target: {altitude_m: 7, offset_m: [1, 2, 3]}}}", registry)
    setup(tree, script)
    tick(tree)
    script.reads["Target"]["offset_m"].append(99.0)
    reset_blackboard()
    tick(tree)
    assert script.reads["Target"]["offset_m"] == [1.0, 2.0, 3.0]


def test_tree_files_lists_the_tree_and_every_file_it_includes_once(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "main.yaml").write_text("version: 1\nincludes: [sub/a.yaml, b.xml]\nmain: M\ntrees:\n  M:\n    SubTree: {ID: A}\n")
    (tmp_path / "sub/a.yaml").write_text("version: 1\nincludes: [../b.xml, missing.yaml]\ntrees:\n  A:\n    SubTree: {ID: B}\n")
    (tmp_path / "b.xml").write_text('<root BTCPP_format="4"><BehaviorTree ID="B"><AlwaysSuccess/></BehaviorTree></root>\n')
    assert tree_files(tmp_path / "main.yaml") == [(tmp_path / p).resolve() for p in ("main.yaml", "sub/a.yaml", "b.xml")]
