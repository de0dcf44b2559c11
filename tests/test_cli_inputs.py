"""Every bad input to every subcommand: exit 2, the subcommand's usage and one ``chaser-bt:`` line naming
the option or file, with a "did you mean" for a near miss, and never a traceback; nothing flies first."""

from __future__ import annotations

import argparse
import socket
from pathlib import Path

import pytest

from chaser_bt.cli import main

ROOT = Path(__file__).resolve().parents[1]
PATROL = str(ROOT / "trees" / "patrol.yaml")
SCENARIO = str(ROOT / "sitl" / "scenarios" / "patrol.yaml")
NO_DIR = "/nonexistent-folder/x"


def _yolo_folder(tmp_path: Path) -> str:
    (tmp_path / "yolo" / "images").mkdir(parents=True)
    return str(tmp_path / "yolo")


# (argv, what the error line must contain); {tmp} is a scratch folder, {yolo} an empty YOLO folder.
BAD_INPUTS = [
    (["rehers", PATROL], "did you mean rehearse"),
    (["validate", PATROL, "--formt", "dot"], "unrecognized option --formt"),
    (["show", PATROL, "--formt", "dot"], "did you mean --format"),
    (["show", PATROL, "--format", "dott"], "did you mean dot"),
    (["validate", "{tmp}/missing.yaml"], "missing.yaml"),
    (["show", "{tmp}/missing.yaml"], "missing.yaml"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--sed", "3"], "did you mean --seed"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--seed", "-1"], "--seed"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--seed", "x"], "--seed"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--rate-hz", "0"], "--rate-hz"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--rate-hz", "nan"], "--rate-hz"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--live", "99999"], "--live"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--trace", NO_DIR + "/t.npz"], "--trace"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--trace", "{tmp}"], "--trace"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--report", "/proc/report"], "--report"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--record", NO_DIR + "/f.mcap"], "--record"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--radar-pose", "calibratd"], "did you mean calibrated"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--camera-size", "640"], "--camera-size"),
    (["rehearse", PATROL, "--scenario", "{tmp}/missing.yaml"], "missing.yaml"),
    (["rehearse", PATROL], "--scenario"),
    (["run", PATROL, "--connect", "tcp:127.0.0.1:9", "--rate-hz", "-5"], "--rate-hz"),
    (["run", PATROL, "--connect", "tcp:127.0.0.1:9", "--record", NO_DIR + "/f.mcap"], "--record"),
    (["run", PATROL, "--connect", "tcp:127.0.0.1:9", "--signing-link-id", "-1"], "--signing-link-id"),
    (["run", PATROL, "--conect", "tcp:127.0.0.1:9"], "did you mean --connect"),
    (["run", PATROL, "--connect", "tcp:127.0.0.1:9", "--origin", "95,0"], "--origin"),
    (["run", PATROL, "--connect", "tcp:127.0.0.1:9", "--origin", "42.5"], "--origin"),
    (["run", PATROL, "--connect", "tcp:127.0.0.1:9", "--radar-pose", "{tmp}/pose.json"], "--radar-pose"),
    (["sitl", "--scenario", SCENARIO, "--speedup", "0"], "--speedup"),
    (["sitl", "--scenario", SCENARIO, "--tcp-port", "99999"], "--tcp-port"),
    (["sitl", "--scenario", SCENARIO, "--udp-port", "-1"], "--udp-port"),
    (["sitl", "--scenario", SCENARIO, "--seed", "-1"], "--seed"),
    (["search-trial", "--seed", "-1"], "--seed"),
    (["search-trial", "--horizn", "3"], "did you mean --horizon"),
    (["search-trial", "--horizon", "0"], "--horizon"),
    (["campaign", PATROL, "--scenarios", SCENARIO, "--out", "/proc/campaign"], "--out"),
    (["campaign", PATROL, "--scenarios", SCENARIO, "--out", "{tmp}/c", "--workers", "0"], "--workers"),
    (["campaign", PATROL, "--scenarios", SCENARIO, "--out", "{tmp}/c", "--seeds", "1,1"], "--seeds"),
    (["campaign", PATROL, "--scenarios", SCENARIO, "--out", "{tmp}/c", "--seeds", "1-3,2"], "--seeds"),
    (["campaign", PATROL, "--scenarios", SCENARIO, "--out", "{tmp}/empty", "--report-only"], "--quick"),
    (["plot", "{tmp}/missing.mcap", "--out", "/proc/plots"], "--out"),
    (["plot", "{tmp}/missing.mcap"], "missing.mcap"),
    (["replay", "{tmp}/missing.mcap", PATROL], "missing.mcap"),
    (["chase-geometry", "--plot", NO_DIR + "/f.png"], "--plot"),
    (["chase-geometry", "--speed-h", "-1"], "--speed-h"),
    (["calibrate", "{tmp}/missing.jsonl"], "missing.jsonl"),
    (["convert", "{tmp}/missing.yaml", "{tmp}/out.xml"], "missing.yaml"),
    (["train-detector", "--data", "{yolo}", "--steps", "0"], "--steps"),
    (["train-detector", "--data", "{yolo}", "--batch", "0"], "--batch"),
    (["train-detector", "--data", "{tmp}/nothing"], "--data"),
    (["train-detector", "--data", "{yolo}", "--out", NO_DIR + "/d.pt"], "--out"),
    (["train-refiner", "--data", "{yolo}", "--out", "r.pt", "--steps", "0"], "--steps"),
    (["train-refiner", "--data", "{yolo}", "--out", "r.pt", "--negatives-from", str(ROOT / "README.md")], "--negatives-from"),
    (["train-refiner", "--data", "{yolo}", "--out", "r.pt", "--negative-conf", "1.5"], "--negative-conf"),
    (["eval-detector", "--data", "{yolo}", "--weights", str(ROOT / "README.md")], "--weights"),
    (["eval-detector", "--data", "{yolo}", "--sizes", "100"], "--sizes"),
    (["quantize-detector", "--calib", "{tmp}/nothing"], "--calib"),
    (["quantize-detector", "--calib", "{yolo}"], "--calib"),
    (["quantize-detector", "--calib", "{yolo}", "--weights", str(ROOT / "README.md")], "--weights"),
    (["quantize-detector", "--calib", "{yolo}", "--size", "100"], "--size"),
    (["quantize-detector", "--calib", "{yolo}", "--out", NO_DIR + "/d.onnx"], "--out"),
]


@pytest.mark.parametrize("argv,named", BAD_INPUTS, ids=lambda v: " ".join(v[:3]) if isinstance(v, list) else None)
def test_bad_input_is_one_line_naming_it_and_exit_2(argv, named, tmp_path, capsys):
    argv = [a.format(tmp=tmp_path, yolo=_yolo_folder(tmp_path) if "{yolo}" in a else "") for a in argv]
    (tmp_path / "empty").mkdir()
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own checks
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.startswith("chaser-bt: ")]
    assert len(lines) == 1, err
    assert named in lines[0], err


def test_an_unknown_option_shows_the_subcommands_usage(capsys):
    with pytest.raises(SystemExit):
        main(["rehearse", PATROL, "--scenario", SCENARIO, "--sed", "3"])
    assert capsys.readouterr().err.startswith("usage: chaser-bt rehearse")


def test_a_port_in_use_is_bad_input_naming_the_ports(capsys):
    taken = socket.socket()
    taken.bind(("127.0.0.1", 0))
    taken.listen()
    try:
        code = main(["sitl", "--scenario", SCENARIO, "--tcp-port", str(taken.getsockname()[1]), "--udp-port", "14999"])
    finally:
        taken.close()
    err = capsys.readouterr().err
    assert code == 2 and "--tcp-port" in err and "Traceback" not in err


def test_verbose_is_accepted_after_the_subcommand(capsys):
    assert main(["validate", PATROL, "-v"]) == 0
    assert main(["-v", "validate", PATROL]) == 0


def _subcommand_parsers():
    from chaser_bt.cli import _SIM_COMMANDS, _parser

    names = list(_parser()._subparsers._group_actions[0].choices)
    for name in names:  # the simulator commands' real parsers are built when they are named
        parser = _parser([name]) if name in _SIM_COMMANDS else _parser()
        yield name, parser._subparsers._group_actions[0].choices[name]


@pytest.mark.parametrize("name,parser", list(_subcommand_parsers()), ids=lambda v: v if isinstance(v, str) else "")
def test_help_describes_every_argument_with_its_default(name, parser):
    assert parser.description, f"{name} has no description line"
    for action in parser._actions:
        if action.help == argparse.SUPPRESS or isinstance(action, argparse._HelpAction):
            continue
        what = action.option_strings[0] if action.option_strings else action.dest
        assert action.help, f"{name} {what}: no help text"
        has_default = action.default not in (None, False, argparse.SUPPRESS) and not action.required
        if has_default and action.option_strings:
            assert "default" in action.help, f"{name} {what}: help does not give the default {action.default!r}"
