"""The command line: exit codes and error messages for bad input (file, line, problem; all at once)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from chaser_bt.cli import main

ROOT = Path(__file__).resolve().parents[1]
PATROL = ROOT / "trees" / "patrol.yaml"
SCENARIO = ROOT / "sitl" / "scenarios" / "patrol.yaml"

# Line numbers below are counted by hand in this text.
BROKEN_TREE = """\
version: 1
trees:
  Broken:
    Sequence:
      children:
        - ArmAndTakof: {altitude_m: 20}
        - GoTo: {waypoint: [1, 2, 3], speeed_mps: 4}
        - BatteryAbove: {}
        - Hover: {duration_s: true}
"""


@pytest.fixture
def broken(tmp_path) -> Path:
    path = tmp_path / "broken.yaml"
    path.write_text(BROKEN_TREE)
    return path


def test_validate_accepts_the_patrol_tree(capsys):
    assert main(["validate", str(PATROL)]) == 0
    assert "ok" in capsys.readouterr().out


def test_validate_reports_every_problem_with_file_and_line(broken, capsys):
    assert main(["validate", str(broken)]) == 2
    err = capsys.readouterr().err
    assert f"{broken}:6:" in err and "ArmAndTakof" in err  # unknown node
    assert "ArmAndTakeoff" in err  # ... with the closest known id suggested
    assert f"{broken}:7:" in err and "speeed_mps" in err  # unknown port
    assert f"{broken}:8:" in err and "percent" in err  # missing required port
    assert f"{broken}:9:" in err and "duration_s" in err  # wrong literal type
    assert "4 problem" in err


def test_unknown_behaviour_lists_the_known_ones(tmp_path, capsys):
    path = tmp_path / "unknown.yaml"
    path.write_text("version: 1\ntrees:\n  T:\n    Fly: {}\n")
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    for known in ("ArmAndTakeoff", "GoTo", "Hover", "RTL", "Land", "Sequence"):
        assert known in err


def test_malformed_yaml_names_the_position(tmp_path, capsys):
    path = tmp_path / "malformed.yaml"
    path.write_text("version: 1\ntrees:\n  T:\n    Sequence: {children: [\n")
    assert main(["validate", str(path)]) == 2
    assert f"{path}:" in capsys.readouterr().err


def test_run_and_rehearse_refuse_an_invalid_tree(broken, capsys):
    assert main(["run", str(broken), "--connect", "tcp:127.0.0.1:9"]) == 2
    assert main(["rehearse", str(broken), "--scenario", str(SCENARIO)]) == 2
    err = capsys.readouterr().err
    assert err.count(f"{broken}:6:") == 2


def test_malformed_connection_string_is_bad_input(capsys):
    assert main(["run", str(PATROL), "--connect", "tcp:nowhere"]) == 2
    assert "tcp:nowhere" in capsys.readouterr().err


def test_missing_files_are_bad_input(tmp_path, capsys):
    assert main(["validate", str(tmp_path / "nope.yaml")]) == 2
    assert main(["rehearse", str(PATROL), "--scenario", str(tmp_path / "nope.yaml")]) == 2


def test_validate_refuses_infinities_and_numbers_no_float_holds(tmp_path, capsys):
    path = tmp_path / "big.yaml"
    path.write_text("version: 1\ntrees:\n  T:\n    Sequence:\n      children:\n"
                    "        - ArmAndTakeoff: {altitude_m: 1e400}\n"
                    "        - Hover: {duration_s: inf}\n"
                    f"        - Hover: {{duration_s: {'9' * 5000}}}\n")
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}:6:39: port 'altitude_m' of ArmAndTakeoff must be a finite number, got inf" in err
    assert f"{path}:7:31: port 'duration_s' of Hover must be a finite number, got inf" in err
    assert f"{path}:8:31: cannot read value: Exceeds the limit (4300 digits)" in err
    assert "3 problem(s)" in err and "Traceback" not in err


def test_validate_a_folder_says_it_is_a_folder(tmp_path, capsys):
    assert main(["validate", str(tmp_path)]) == 2
    assert capsys.readouterr().err == f"chaser-bt: {tmp_path}: is a folder, not a tree file\n"


def test_version_prints_the_installed_packages_version(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out == f"chaser-bt {version('chaser-bt')}\n"


def test_show_prints_the_outline_with_port_values(capsys):
    assert main(["show", str(PATROL)]) == 0
    out = capsys.readouterr().out
    assert "east corner" in out and "100" in out and "RTL" in out


def test_show_as_dot_is_a_graphviz_digraph(capsys):
    assert main(["show", str(PATROL), "--format", "dot"]) == 0
    out = capsys.readouterr().out
    assert out.lstrip().startswith("digraph") and "east corner" in out


def test_convert_yaml_to_xml_and_back_round_trips(tmp_path, capsys):
    xml, back = tmp_path / "patrol.xml", tmp_path / "patrol.yaml"
    assert main(["convert", str(PATROL), str(xml)]) == 0
    assert 'BTCPP_format="4"' in xml.read_text()
    assert main(["convert", str(xml), str(back)]) == 0
    assert main(["validate", str(back)]) == 0


def test_unreachable_vehicle_is_a_clear_error_within_ten_seconds(capsys):
    start = time.monotonic()
    code = main(["run", str(PATROL), "--connect", "tcp:127.0.0.1:9"])
    elapsed = time.monotonic() - start
    assert code == 1
    assert "127.0.0.1:9" in capsys.readouterr().err
    assert elapsed < 10.0 + 4.0  # the link's 10 s bound, plus loading the tree and its behaviours on a busy machine


@pytest.mark.slow
def test_rehearse_show_ticks_prints_the_tree_at_each_change(capsys):
    assert main(["rehearse", str(PATROL), "--scenario", str(SCENARIO), "--seed", "1", "--show-ticks"]) == 0
    out = capsys.readouterr().out
    assert "east corner RUNNING->SUCCESS" in out
    assert out.count("--- t = ") >= 6  # take-off, four legs, RTL at least
    assert "[*]" in out and "[✓]" in out  # statuses drawn in the tree


def test_rehearse_time_limit_cuts_the_flight_short(capsys):
    # still on the ground at 12.5 s (the patrol's vehicle is ready to arm later): a timeout, exit 1
    assert main(["rehearse", str(PATROL), "--scenario", str(SCENARIO), "--no-camera", "--json", "--time-limit", "12.5"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report["sim_time_s"] == pytest.approx(12.5, abs=0.05)
    assert report["outcome"] == "timeout" and report["message"] == "time limit of 12 s reached"
    with pytest.raises(SystemExit) as exc:  # argparse: bad input
        main(["rehearse", str(PATROL), "--scenario", str(SCENARIO), "--time-limit", "0"])
    assert exc.value.code == 2 and "--time-limit" in capsys.readouterr().err


def test_bad_signing_key_file_is_bad_input(tmp_path, capsys):
    key = tmp_path / "key"
    key.write_text("")
    assert main(["run", str(PATROL), "--connect", "tcp:127.0.0.1:9", "--signing-key", str(key)]) == 2
    assert "--signing-key" in capsys.readouterr().err
    assert main(["sitl", "--scenario", str(SCENARIO), "--signing-key", str(tmp_path / "missing")]) == 2


def test_simulator_commands_are_listed_but_loaded_only_when_named(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "campaign" in out and "search-trial" in out
    with pytest.raises(SystemExit) as exc:
        main(["search-trial", "--help"])
    assert exc.value.code == 0
    assert "--planner" in capsys.readouterr().out


@pytest.mark.parametrize("tree, needs", [("chase.yaml", ("--radar", "--camera")), ("chase.xml", ("--radar", "--camera")),
                                         ("sar.yaml", ("--camera",))])
def test_run_refuses_a_tree_needing_a_sensor_it_was_not_given_before_connecting(tree, needs, capsys):
    # Nothing listens on port 9: a run that tried to connect would say "cannot connect" and exit 1.
    assert main(["run", str(ROOT / "trees" / tree), "--connect", "tcp:127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert "cannot connect" not in err and "Traceback" not in err and "KeyError" not in err
    for flag in needs:
        assert flag in err
    assert ("--radar" in err) == ("--radar" in needs)
