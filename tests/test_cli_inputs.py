"""Every bad input to every subcommand: exit 2, the subcommand's usage and one ``chaser-bt:`` line naming
the option or file, with a "did you mean" for a near miss, and never a traceback; nothing flies first."""

from __future__ import annotations

import argparse
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from chaser_bt.cli import main

ROOT = Path(__file__).resolve().parents[1]
PATROL = str(ROOT / "trees" / "patrol.yaml")
CHASE = str(ROOT / "trees" / "chase.yaml")
SCENARIO = str(ROOT / "sitl" / "scenarios" / "patrol.yaml")
NO_DIR = "/nonexistent-folder/x"


def _yolo_folder(tmp_path: Path) -> str:
    (tmp_path / "yolo" / "images").mkdir(parents=True)
    return str(tmp_path / "yolo")


def _odd_files(tmp_path: Path) -> None:
    """Files no command can read: binary.bin (not UTF-8), empty ones (empty.txt, .yaml, .mcap, .pt, .zip),
    and a scenario and a radar pose holding an integer of 5000 digits (more than Python's int() reads from
    text), a pose with one of 400 (past a float), and a good pose."""
    (tmp_path / "binary.bin").write_bytes(bytes(range(256)) * 4)
    for name in ("empty.txt", "empty.yaml", "empty.mcap", "empty.pt", "empty.zip"):
        (tmp_path / name).write_bytes(b"")
    (tmp_path / "huge.yaml").write_text(f"name: x\nhome: {{lat_deg: 1, lon_deg: 2, alt_m: {'9' * 5000}}}\n")
    (tmp_path / "huge.json").write_text(f'{{"lat_deg": 1, "lon_deg": 2, "yaw_deg": {"9" * 400}}}')
    (tmp_path / "good_pose.json").write_text('{"lat_deg": 1, "lon_deg": 2, "yaw_deg": 0}')


RUN = ["run", PATROL, "--connect", "tcp:127.0.0.1:9"]
RADAR = ["run", CHASE, "--connect", "tcp:127.0.0.1:9", "--camera", "0", "--radar", "0.0.0.0:4950"]
CAMPAIGN = ["campaign", PATROL, "--scenarios", SCENARIO, "--out", "{tmp}/c"]

# (argv, what the error line must contain); {tmp} is a scratch folder (with the files of _odd_files),
# {yolo} an empty YOLO folder.
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
    (["rehearse", CHASE, "--scenario", SCENARIO, "--camera-size", "100000x100000"],
     "--camera-size: camera size 100000x100000 is too large (at most 8192x8192)"),
    (["rehearse", CHASE, "--scenario", SCENARIO, "--camera-size", "8x8"], "--camera-size: camera size 8x8 is too small"),
    ([*RUN, "--camera-size", "8193x480"], "--camera-size: camera size 8193x480 is too large"),
    ([*RUN, "--camera-mount", "gimbal"], "--camera-mount: invalid choice"),
    ([*RUN, "--camera-tilt", "90"], "--camera-tilt: expected a number in (-90, 90)"),
    ([*RUN, "--camera-tilt", "nan"], "--camera-tilt: expected a number in (-90, 90)"),
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
    (["sitl", "--scenario", SCENARIO, "--speedup", "1e300"], "--speedup: expected a number in [0.01, 1000]"),
    (["sitl", "--scenario", SCENARIO, "--speedup", "inf"], "--speedup: expected a number in [0.01, 1000]"),
    (["sitl", "--scenario", SCENARIO, "--speedup", "1e-9"], "--speedup: expected a number in [0.01, 1000]"),
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
    # files that are binary, empty, folders or hold numbers no parser reads
    (["rehearse", PATROL, "--scenario", "{tmp}/binary.bin"], "binary.bin: not a scenario: byte 128 is not UTF-8"),
    (["rehearse", PATROL, "--scenario", "{tmp}/empty.txt"], "empty.txt"),
    (["rehearse", PATROL, "--scenario", "{tmp}"], "cannot read scenario"),
    (["rehearse", PATROL, "--scenario", "{tmp}/huge.yaml"], "huge.yaml: not a scenario"),
    (["campaign", PATROL, "--scenarios", "{tmp}/binary.bin", "--out", "{tmp}/c"], "binary.bin: not a scenario"),
    (["campaign", "{tmp}", "--scenarios", SCENARIO, "--out", "{tmp}/c"], "is a folder, not a tree file"),
    (["sitl", "--scenario", "{tmp}/binary.bin"], "binary.bin: not a scenario"),
    (["sitl", "--scenario", "{tmp}/huge.yaml"], "huge.yaml: not a scenario"),
    (["show", "{tmp}/binary.bin"], "binary.bin: invalid tree"),
    (["validate", "{tmp}"], "is a folder, not a tree file"),
    (["convert", "{tmp}", "{tmp}/out.xml"], "is a folder, not a tree file"),
    (["replay", "{tmp}", PATROL], "is a folder, not a log file"),
    (["plot", "{tmp}/binary.bin"], "binary.bin"),
    (["calibrate", "{tmp}/binary.bin"], "binary.bin"),
    ([*RUN, "--signing-key", "{tmp}"], "--signing-key: {tmp} is a folder"),
    ([*RUN, "--signing-key", "{tmp}/binary.bin"], "--signing-key"),
    (["sitl", "--scenario", SCENARIO, "--signing-key", "{tmp}/empty.txt"], "--signing-key"),
    ([*RADAR, "--radar-pose", "{tmp}/binary.bin"], "binary.bin"),
    ([*RUN, "--camera", "{tmp}/binary.bin"], "--camera {tmp}/binary.bin: not a video or image OpenCV can read"),
    ([*RUN, "--camera", "{tmp}/empty.txt"], "--camera {tmp}/empty.txt: the file is empty"),
    ([*RUN, "--camera", "{tmp}"], "--camera {tmp}: is a folder"),
    ([*RADAR, "--radar-pose", "{tmp}/huge.json"], "yaw_deg"),
    ([*RADAR, "--radar-pose", "{tmp}"], "--radar-pose"),
    ([*RADAR, "--radar-pose", "{tmp}/good_pose.json", "--radar-key", "{tmp}/binary.bin"], "--radar-key"),
    ([*RUN, "--uplink", "127.0.0.1:14650"], "--uplink needs --uplink-key FILE"),
    (["sitl", "--scenario", SCENARIO, "--radar-key", "{tmp}/good_pose.json"], "sends no radar datagrams"),
    ([*RUN, "--uplink", "127.0.0.1:14650", "--uplink-key", "{tmp}/binary.bin"], "--uplink-key"),
    ([*RUN, "--uplink", "127.0.0.1:99999", "--uplink-key", "{tmp}/good_pose.json"], "port 99999 out of range"),
    (["designate", "5", "--to", "127.0.0.1:14650", "--key", "{tmp}/binary.bin"], "designate"),
    # empty files wherever a file is read
    (["show", "{tmp}/empty.yaml"], "{tmp}/empty.yaml: invalid tree"),
    (["rehearse", "{tmp}/empty.yaml", "--scenario", SCENARIO], "{tmp}/empty.yaml: invalid tree"),
    (["convert", "{tmp}/empty.yaml", "{tmp}/out.xml"], "{tmp}/empty.yaml: not converted"),
    (["replay", "{tmp}/empty.mcap", PATROL], "{tmp}/empty.mcap: empty file, not an MCAP log"),
    (["plot", "{tmp}/empty.mcap"], "{tmp}/empty.mcap: empty file, not an MCAP log"),
    (["btlog", "{tmp}/empty.mcap", PATROL], "{tmp}/empty.mcap: empty file, not an MCAP log"),
    (["calibrate", "{tmp}/empty.txt"], "empty.txt: empty file"),
    ([*RADAR, "--radar-pose", "{tmp}/empty.txt"], "empty.txt:1: not JSON"),
    ([*RADAR, "--radar-pose", "{tmp}/good_pose.json", "--radar-key", "{tmp}/empty.txt"], "--radar-key: {tmp}/empty.txt: empty"),
    ([*RUN, "--signing-key", "{tmp}/empty.txt"], "--signing-key: {tmp}/empty.txt: empty"),
    ([*RUN, "--uplink", "127.0.0.1:14650", "--uplink-key", "{tmp}/empty.txt"], "--uplink-key: {tmp}/empty.txt: empty"),
    (["designate", "5", "--to", "127.0.0.1:14650", "--key", "{tmp}/empty.txt"], "designate: {tmp}/empty.txt: empty"),
    (["retask", PATROL, "--to", "127.0.0.1:14650", "--key", "{tmp}/empty.txt", "--sysid", "1"], "retask: {tmp}/empty.txt: empty"),
    (["retask", "{tmp}/empty.yaml", "--to", "127.0.0.1:14650", "--key", "{tmp}/good_pose.json", "--sysid", "1"], "empty.yaml"),
    (["eval-detector", "--data", "{yolo}", "--weights", "{tmp}/empty.pt"], "--weights {tmp}/empty.pt: empty file, not detector weights"),
    (["train-detector", "--data", "{yolo}", "--init", "{tmp}/empty.pt"], "--init {tmp}/empty.pt: empty file, not detector weights"),
    (["train-refiner", "--data", "{yolo}", "--out", "r.pt", "--negatives-from", "{tmp}/empty.pt"],
     "--negatives-from {tmp}/empty.pt: empty file, not detector weights"),
    (["quantize-detector", "--calib", "{yolo}", "--weights", "{tmp}/empty.pt"],
     "--weights {tmp}/empty.pt: empty file, not detector weights"),
    (["import-footage", "{tmp}/empty.zip", "--out", "{tmp}/footage"], "empty.zip: not a zip archive"),
    (["designate", "-1", "--to", "127.0.0.1:14650", "--key", "{tmp}/good_pose.json"], "track id -1"),
    (["retask", "{tmp}/binary.bin", "--to", "127.0.0.1:14650", "--key", "{tmp}/good_pose.json", "--sysid", "1"], "binary.bin"),
    (["retask", PATROL, "--to", "127.0.0.1:14650", "--key", "{tmp}/good_pose.json", "--sysid", "300"], "--sysid 300"),
    (["retask", PATROL, "--to", "127.0.0.1:99999", "--key", "{tmp}/good_pose.json", "--sysid", "1"], "out of range"),
    (["retask", PATROL, "--to", "127.0.0.1:14650", "--key", "{tmp}/good_pose.json", "--sysid", "1", "--subtree", "a b"],
     "subtree 'a b': expected a tree ID"),
    (["retask", "{tmp}/binary.bin", "--to", "127.0.0.1:14650", "--key", "{tmp}/good_pose.json", "--sysid", "1",
      "--subtree", "Leg"], "binary.bin"),
    ([*RUN, "--designation-compid", "abc"], "--designation-compid: expected a component id in 2-255, or 0 or off"),
    ([*RUN, "--designation-compid", "256"], "--designation-compid: expected a component id in 2-255, or 0 or off"),
    ([*RUN, "--designation-compid", "-3"], "--designation-compid: expected a component id in 2-255"),
    ([*RUN, "--designation-compid", "1"], "--designation-compid: 1 is the autopilot's component"),
    ([*RUN, "--designation-compid", "off", "--designation-unsigned"],
     "--designation-unsigned: MAVLink designation is off (--designation-compid off)"),
    ([*RUN, "--reload-subtree", "Leg"], "--reload-subtree Leg: give the file it is reloaded from with --reload-from"),
    ([*RUN, "--reload-from", "{tmp}/next.yaml", "--reload-subtree", "Leg"], "has no subtree Leg; its subtrees: none"),
    (["train-detector", "--data", "{yolo}", "--init", "{tmp}/binary.bin"], "--init {tmp}/binary.bin: not detector weights"),
    (["train-detector", "--data", "{yolo}", "--init", "{tmp}"], "--init {tmp}: is a folder"),
    (["eval-detector", "--data", "{yolo}", "--weights", "{tmp}"], "--weights {tmp}: is a folder"),
    # numbers past what can be computed or meant
    (["search-trial", "--horizon", "1000"], "search-trial --horizon 1000: at most 8"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--rate-hz", "1e9"], "--rate-hz: expected a number in (0, 1000]"),
    ([*RUN, "--rate-hz", "1001"], "--rate-hz"),
    ([*RUN, "--radar-time-offset", "-1e-3"], "--radar-time-offset=-1e-3"),
    (["chase-geometry", "--target-size-m", "0", "0", "0"], "chaser-bt: --target-size-m: expected three sizes > 0 m"),
    (["chase-geometry", "--hfov-deg", "180"], "chaser-bt: --hfov-deg: expected a field of view in (0, 180) deg"),
    (["chase-geometry", "--width-px", "0"], "chaser-bt: --width-px: expected a width >= 1 px"),
    # ports
    (["rehearse", PATROL, "--scenario", SCENARIO, "--groot2", "70000"], "--groot2: expected an integer in 1-65534"),
    (["rehearse", PATROL, "--scenario", SCENARIO, "--groot2", "-5"], "--groot2: expected an integer in 1-65534"),
    ([*RUN, "--groot2", "0"], "--groot2"),
    ([*RUN, "--live", "65536"], "--live"),
    (["sitl", "--scenario", SCENARIO, "--tcp-port", "65536"], "--tcp-port"),
    (["run", PATROL, "--connect", "tcp:127.0.0.1:99999"], "--connect: tcp:127.0.0.1:99999: port 99999 out of range"),
    (["run", PATROL, "--connect", "udpout:127.0.0.1:0"], "port 0 out of range"),
    ([*RUN, "--radar", "0.0.0.0:70000"], "--radar: 0.0.0.0:70000: port 70000 out of range"),
    # campaign seeds
    ([*CAMPAIGN, "--seeds", "1-100000000"], "--seeds: '1-100000000' names more than 100000 seeds"),
    ([*CAMPAIGN, "--seeds", "-3-2"], "--seeds: seeds are integers >= 0: '-3-2'"),
    ([*CAMPAIGN, "--seeds=-3-2"], "--seeds: seeds are integers >= 0: '-3-2'"),
    ([*CAMPAIGN, "--seeds", "4294967296"], "seeds are integers in [0, 2^32)"),
]


@pytest.mark.parametrize("argv,named", BAD_INPUTS, ids=lambda v: " ".join(v[:3]) if isinstance(v, list) else None)
def test_bad_input_is_one_line_naming_it_and_exit_2(argv, named, tmp_path, capsys):
    argv = [a.format(tmp=tmp_path, yolo=_yolo_folder(tmp_path) if "{yolo}" in a else "") for a in argv]
    named = named.format(tmp=tmp_path)
    (tmp_path / "empty").mkdir()
    _odd_files(tmp_path)
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


@pytest.mark.parametrize("options, compid, unsigned", [
    ([], 191, False),  # MAV_COMP_ID_ONBOARD_COMPUTER
    (["--designation-compid", "200"], 200, False),
    (["--designation-compid", "255"], 255, False),
    (["--designation-compid", "off"], None, False),
    (["--designation-compid", "OFF"], None, False),
    (["--designation-compid", "0"], None, False),
    (["--designation-unsigned"], 191, True),
    (["--designation-unsigned", "--designation-compid", "2"], 2, True),
])
def test_the_designation_options_reach_the_link_config(options, compid, unsigned, monkeypatch, capsys):
    """``run`` up to connecting, where a stand-in for the vehicle link records the LinkConfig it was given."""
    from chaser_bt.vehicle import VehicleLink
    from chaser_bt.vehicle.designation import DEFAULT_COMPID
    from chaser_bt.vehicle.errors import VehicleUnreachable

    given = []

    def connect(url, config):
        given.append((url, config))
        raise VehicleUnreachable("no vehicle here")

    monkeypatch.setattr(VehicleLink, "connect", staticmethod(connect))
    code = main([*RUN, *options])
    err = capsys.readouterr().err
    assert code == 1 and "no vehicle here" in err, err
    ((url, config),) = given
    assert url == "tcp:127.0.0.1:9"
    assert (config.designation_compid, config.designation_unsigned) == (compid, unsigned)
    assert DEFAULT_COMPID == 191  # the command line's default is the link's
    warning = "chaser-bt: run: WARNING: --designation-unsigned: UNSIGNED MAVLink designations are believed"
    assert (warning in err) is unsigned
    if unsigned:  # said at start, before the vehicle is tried
        assert err.index(warning) < err.index("no vehicle here")


def test_a_campaign_refuses_an_output_folder_another_campaign_is_writing(tmp_path, capsys):
    """Two campaigns into one --out would both fly every run: the second is refused, naming the first's pid."""
    out = tmp_path / "c"
    out.mkdir()
    holder = _hold(out, "--out", "campaign")
    try:
        code = main(["campaign", PATROL, "--scenarios", SCENARIO, "--seeds", "1", "--workers", "1", "--quick",
                     "--no-camera", "--out", str(out)])
    finally:
        holder.communicate("", timeout=30)
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"chaser-bt: --out {out} is in use by another campaign (pid {holder.pid})" in err
    assert not (out / "runs").exists()  # nothing flown
    from sitl.bench.campaign import lock_out_dir

    with lock_out_dir(out):  # the holder has ended: the folder is free again
        pass


def _hold(folder: Path, option: str, command: str) -> subprocess.Popen:
    """Another process holding ``folder`` (as ``command`` would) until its stdin closes."""
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys; from pathlib import Path; from sitl.bench.out_lock import lock_out_dir\n"
                               "with lock_out_dir(Path(sys.argv[1]), sys.argv[2], sys.argv[3]):\n"
                               "    print('held', flush=True); sys.stdin.read()",
         str(folder), option, command], cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    return holder


@pytest.mark.parametrize("command", ["rehearsal", "campaign"])
def test_a_rehearsal_refuses_a_report_folder_another_command_is_writing(command, tmp_path, capsys):
    """Two ``rehearse --report DIR`` at once would both exit 0, the last writer's report winning: the second
    is refused before it flies, naming the first's pid; a campaign's --out and a report folder share the lock."""
    out = tmp_path / "report"
    out.mkdir()
    holder = _hold(out, "--out" if command == "campaign" else "--report", command)
    try:
        code = main(["rehearse", PATROL, "--scenario", SCENARIO, "--no-camera", "--no-radar", "--progress", "never",
                     "--report", str(out)])
    finally:
        holder.communicate("", timeout=30)
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"chaser-bt: --report {out} is in use by another {command} (pid {holder.pid}); wait for it" in err
    assert not (out / "report.json").exists()  # nothing flown, nothing written


@pytest.mark.parametrize("name, problem", [("empty.yaml", "empty tree file"), ("empty.xml", "malformed XML")])
def test_validate_reports_an_empty_tree_file_as_its_problem(name, problem, tmp_path, capsys):
    """``validate`` lists problems as FILE:LINE:COL lines (no ``chaser-bt:`` line): an empty file is one."""
    path = tmp_path / name
    path.write_bytes(b"")
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [err.splitlines()[0], f"{path}: 1 problem(s)"], err
    assert err.startswith(f"{path}:1:1: {problem}"), err


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
