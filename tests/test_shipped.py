"""Shipped trees and scenarios by name (chaser_bt.shipped): a name is the shipped file, a path stays a path,
and a word that is neither is one line naming the shipped ones; the CLI takes names wherever it takes a tree
or a scenario. tests/test_wheel.py does the same from an installed wheel."""

from __future__ import annotations

from pathlib import Path

import pytest

from chaser_bt import shipped
from chaser_bt.cli import main
from chaser_bt.shipped import NotShipped, resolve_scenario, resolve_tree

ROOT = Path(__file__).resolve().parents[1]
TREES = ROOT / "trees"
SCENARIOS = ROOT / "sitl" / "scenarios"


def test_a_checkout_ships_its_own_trees_and_scenarios_folders():
    assert shipped.trees_dir() == TREES
    assert shipped.scenarios_dir() == SCENARIOS


def test_every_tree_and_scenario_file_is_shipped_under_its_stem():
    trees = shipped.shipped_trees()
    assert set(trees) == {p.stem for p in TREES.iterdir() if p.suffix in (".yaml", ".xml")}
    assert trees["chase"] == [TREES / "chase.yaml", TREES / "chase.xml"]  # YAML first: the BT.CPP copy is also chase
    assert trees["takeoff_land"] == [TREES / "takeoff_land.yaml"]
    assert "subtrees" not in trees and "safety" not in trees  # subtrees are parts, not missions
    scenarios = shipped.shipped_scenarios()
    assert set(scenarios) == {p.relative_to(SCENARIOS).with_suffix("").as_posix() for p in SCENARIOS.rglob("*.yaml")}
    assert "README" not in scenarios
    assert [n for n in scenarios if "/" not in n] == sorted(p.stem for p in SCENARIOS.glob("*.yaml"))  # the top first


def test_a_file_in_a_folder_is_named_by_its_path_there(tmp_path, monkeypatch):
    for name in ("b.yaml", "a.yaml", "a.xml", "set/x.yaml", "set/deeper/y.yml", "subtrees/part.xml", "notes.md"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("")
    found = shipped.shipped_files(tmp_path, shipped.TREE_SUFFIXES, parts="subtrees")
    assert list(found) == ["a", "b", "set/deeper/y", "set/x"]
    assert found["a"] == [tmp_path / "a.yaml", tmp_path / "a.xml"]
    monkeypatch.setattr(shipped, "scenarios_dir", lambda: tmp_path)
    monkeypatch.chdir(tmp_path / "set")
    assert resolve_scenario("set/x") == tmp_path / "set" / "x.yaml"
    assert resolve_scenario("set/deeper/y.yml") == tmp_path / "set" / "deeper" / "y.yml"
    assert resolve_scenario("x.yaml") == Path("x.yaml")  # the current folder's file
    assert resolve_scenario("set/z") == Path("set/z")  # written as a path: left to the reader to call missing
    with pytest.raises(NotShipped, match=r"named 'z' \(did you mean set/x\?\)|named 'z'; shipped scenarios: a, b, set/"):
        resolve_scenario("z")


def test_a_name_is_the_shipped_file():
    assert resolve_tree("chase") == TREES / "chase.yaml"
    assert resolve_tree("chase.xml") == TREES / "chase.xml"
    assert resolve_tree("patrol.yaml") == TREES / "patrol.yaml"
    assert resolve_scenario("chase") == SCENARIOS / "chase.yaml"
    assert resolve_scenario("sar_lying.yaml") == SCENARIOS / "sar_lying.yaml"


def test_a_path_passes_through_as_given(tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    assert resolve_tree("trees/chase.yaml") == Path("trees/chase.yaml")
    assert resolve_scenario("sitl/scenarios/patrol.yaml") == Path("sitl/scenarios/patrol.yaml")
    assert resolve_tree(TREES / "sar.yaml") == TREES / "sar.yaml"
    missing = tmp_path / "nope" / "chase.yaml"  # written as a path: whoever reads it says it is missing
    assert resolve_tree(str(missing)) == missing
    assert resolve_scenario("./patrol") == Path("./patrol")


def test_a_file_in_the_current_folder_wins_over_a_shipped_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "chase.yaml").write_text("version: 1\n")
    (tmp_path / "patrol").mkdir()  # a folder too: validate then says it is a folder
    assert resolve_tree("chase.yaml") == Path("chase.yaml")
    assert resolve_tree("patrol") == Path("patrol")
    assert resolve_tree("chase") == TREES / "chase.yaml"


def test_an_unknown_name_is_one_line_listing_the_shipped_names():
    with pytest.raises(NotShipped) as exc:
        resolve_tree("chse")
    message = str(exc.value)
    assert "\n" not in message
    assert message.startswith("no tree file or shipped tree named 'chse' (did you mean chase?); shipped trees: ")
    assert message.endswith(", ".join(shipped.shipped_trees()))
    with pytest.raises(NotShipped, match=r"named 'mytree.yaml'; shipped trees: chase, "):
        resolve_tree("mytree.yaml")
    with pytest.raises(NotShipped, match=r"no scenario file or shipped scenario named 'patrl' \(did you mean patrol\?\); "
                                         r"shipped scenarios: chase, chase_radar_off, "):
        resolve_scenario("patrl")
    with pytest.raises(NotShipped, match="shipped scenarios: "):
        resolve_scenario("takeoff_land")  # a tree's name is not a scenario's


def test_an_installed_layout_reads_the_trees_inside_the_package(tmp_path, monkeypatch):
    package = tmp_path / "site-packages" / "chaser_bt" / "shipped"
    (package / "trees").mkdir(parents=True)
    (package / "trees" / "mine.xml").write_text("<root/>")
    (package / "trees" / "mine.yaml").write_text("version: 1\n")
    monkeypatch.setattr(shipped, "_HERE", package)
    assert shipped.trees_dir() == package / "trees"
    assert resolve_tree("mine") == package / "trees" / "mine.yaml"
    (package / "trees" / "mine.yaml").unlink()
    assert resolve_tree("mine") == package / "trees" / "mine.xml"


def test_no_trees_anywhere_is_said(tmp_path, monkeypatch):
    monkeypatch.setattr(shipped, "_HERE", tmp_path / "site-packages" / "chaser_bt" / "shipped")
    assert shipped.trees_dir() is None
    assert shipped.shipped_trees() == {}
    with pytest.raises(NotShipped, match="shipped trees: none found$"):
        resolve_tree("chase")


# -- the command line --------------------------------------------------------------------------------


def test_list_names_the_shipped_trees_and_scenarios_with_their_files(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    trees, scenarios = out.split("shipped scenarios")
    assert trees.startswith("shipped trees")
    for name in shipped.shipped_trees():
        assert f"  {name} " in trees
    assert f"{TREES / 'chase.yaml'} (also chase.xml)" in trees
    for name, files in shipped.shipped_scenarios().items():
        assert f"  {name} " in scenarios and str(files[0]) in scenarios


def test_validate_and_show_take_a_name(capsys):
    assert main(["validate", "patrol"]) == 0
    assert capsys.readouterr().out == f"{TREES / 'patrol.yaml'}: ok\n"
    assert main(["show", "patrol.xml"]) == 0
    assert "RTL" in capsys.readouterr().out


@pytest.mark.parametrize("argv,line", [
    (["validate", "chse"], "chaser-bt: argument TREE: no tree file or shipped tree named 'chse' (did you mean chase?); "
                           "shipped trees: chase, chase_telemetry, "),
    (["rehearse", "patrol", "--scenario", "patrl"], "chaser-bt: argument --scenario: no scenario file or shipped scenario "
                                                    "named 'patrl' (did you mean patrol?); shipped scenarios: chase, "),
    (["sitl", "--scenario", "nowhere"], "chaser-bt: argument --scenario: no scenario file or shipped scenario named 'nowhere'; "),
    (["run", "nothing", "--connect", "tcp:127.0.0.1:9"], "chaser-bt: argument TREE: no tree file or shipped tree named 'nothing'; "),
])
def test_an_unknown_name_on_the_command_line_is_one_line_and_exit_2(argv, line, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    lines = [entry for entry in err.splitlines() if entry.startswith("chaser-bt: ")]
    assert len(lines) == 1 and lines[0].startswith(line), err
    assert err.startswith(f"usage: chaser-bt {argv[0]}")


def test_rehearse_reads_a_shipped_tree_and_scenario_by_name(monkeypatch):
    """Both names reach the rehearsal as the shipped files (nothing is flown: rehearse itself is stubbed)."""
    import chaser_bt.cli as cli

    seen = {}
    monkeypatch.setattr(cli, "_rehearse", lambda args: seen.update(tree=args.tree, scenario=args.scenario) or 0)
    parser = cli._parser(["rehearse"])
    args = parser.parse_args(["rehearse", "takeoff_land", "--scenario", "patrol"])
    assert (args.tree, args.scenario) == (TREES / "takeoff_land.yaml", SCENARIOS / "patrol.yaml")
    args = parser.parse_args(["sitl", "--scenario", "chase_radar_off"])
    assert args.scenario == SCENARIOS / "chase_radar_off.yaml"


def test_a_campaign_takes_a_shipped_tree_and_a_shipped_scenario_or_folder_by_name(tmp_path, monkeypatch):
    """``campaign chase --scenarios hard``: the tree's file, the shipped folder; a path still wins, an unknown name
    is refused naming the shipped ones."""
    import chaser_bt.cli as cli

    parser = cli._parser(["campaign"])
    args = parser.parse_args(["campaign", "chase", "--scenarios", "hard", "--out", str(tmp_path / "c")])
    assert (args.tree, args.scenarios) == (TREES / "chase.yaml", SCENARIOS / "hard")
    args = parser.parse_args(["campaign", "chase", "--scenarios", "retask/chase_then_sar", "--out", str(tmp_path / "c")])
    assert args.scenarios == SCENARIOS / "retask" / "chase_then_sar.yaml"
    monkeypatch.chdir(tmp_path)
    (tmp_path / "hard").mkdir()  # a folder of the user's own: the path, not the shipped folder
    assert shipped.resolve_scenarios("hard") == Path("hard")
    with pytest.raises(NotShipped, match="shipped scenarios: chase, "):
        shipped.resolve_scenarios("soft")


@pytest.mark.parametrize("name", list(shipped.shipped_scenarios()))
def test_every_shipped_scenario_loads(name):
    """Each scenario a user can name loads: its keys, its retasks' trees (files or shipped names) exist."""
    from sitl.world.scenario import load_scenario

    scenario = load_scenario(resolve_scenario(name))
    for retask in scenario.retasks:
        assert retask.tree.is_file()
