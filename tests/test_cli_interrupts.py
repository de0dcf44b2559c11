"""Ctrl-C and SIGTERM: ``rehearse`` writes the report of the flight so far and exits 130; ``campaign``
stops within 5 s, keeping every finished run."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PATROL = str(ROOT / "trees" / "patrol.yaml")
SCENARIO = str(ROOT / "sitl" / "scenarios" / "patrol.yaml")


def _cli(*args: str) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT), MAVLINK20="1")
    # A shell that starts the suite in the background ignores SIGINT, and Python keeps an inherited
    # "ignore": give the command the default disposition, as in a terminal.
    return subprocess.Popen([sys.executable, "-m", "chaser_bt.cli", *args], cwd=ROOT, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _wait_for_line(stream, needle: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = stream.readline()
        if needle in line:
            return
        if not line:
            break
    raise AssertionError(f"no line with {needle!r} within {timeout_s} s")


# Long enough in simulated time to be still flying when the signal comes, even on a loaded machine:
# without a camera a rehearsal runs hundreds of times faster than real time, so the whole patrol
# takes under a second of wall time. Flown in a scenario whose time limit allows it (_long_scenario).
HOLD = """\
<root BTCPP_format="4">
  <BehaviorTree ID="Hold">
    <Sequence name="hold">
      <Wait name="wait" duration_s="7000"/>
      <AlwaysSuccess name="done"/>
    </Sequence>
  </BehaviorTree>
</root>
"""


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_rehearse_interrupted_writes_a_partial_report_and_exits_130(sig, tmp_path):
    tree = tmp_path / "hold.xml"
    tree.write_text(HOLD)
    scenario = tmp_path / "long.yaml"
    scenario.write_text(Path(SCENARIO).read_text().replace("time_limit_s: 600", "time_limit_s: 7200"))
    assert "time_limit_s: 7200" in scenario.read_text()
    proc = _cli("rehearse", str(tree), "--scenario", str(scenario), "--no-camera", "--json", "--show-ticks",
                "--report", str(tmp_path / "report"))
    try:
        _wait_for_line(proc.stderr, "hold (Sequence)", 120)  # the first tick's tree: the vehicle is being flown
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    report = json.loads(out)
    assert report["outcome"] == "interrupted" and report["ticks"] > 0
    assert (tmp_path / "report" / "report.md").is_file()
    assert json.loads((tmp_path / "report" / "report.json").read_text())["outcome"] == "interrupted"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_sitl_interrupted_exits_130_saying_so(sig):
    sim = _cli("sitl", "--scenario", SCENARIO, "--tcp-port", "0", "--udp-port", "0")
    try:
        _wait_for_line(sim.stdout, "connect with", 60)
        sim.send_signal(sig)
        _, err = sim.communicate(timeout=30)
    finally:
        sim.kill()
    assert sim.returncode == 130, err
    assert "Traceback" not in err
    assert [line for line in err.splitlines() if line.startswith("chaser-bt: ")] == ["chaser-bt: sitl: interrupted"]


@pytest.mark.slow
def test_campaign_stops_within_5_s_of_ctrl_c_with_workers(tmp_path):
    proc = _cli("campaign", PATROL, "--scenarios", SCENARIO, "--seeds", "1-60", "--workers", "2", "--quick",
                "--no-camera", "--out", str(tmp_path / "c"))
    try:
        deadline = time.monotonic() + 120
        while not list((tmp_path / "c").rglob("seed_*.json")) and time.monotonic() < deadline:
            time.sleep(0.2)  # until a run is finished; the workers are flying the next ones
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        sent = time.monotonic()
        _, err = proc.communicate(timeout=30)
        took = time.monotonic() - sent
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert took < 5.0, err
    assert "Traceback" not in err and "run the same command again to resume" in err
    kept = list((tmp_path / "c").rglob("seed_*.json"))
    assert 0 < len(kept) < 60 and f"{len(kept)} finished run(s) kept" in err


@contextlib.contextmanager
def _sitl(speedup: str, port: int):
    """``chaser-bt sitl`` flying the patrol scenario at ``speedup``, on TCP ``port``, for the with-block."""
    sim = _cli("sitl", "--scenario", SCENARIO, "--speedup", speedup, "--tcp-port", str(port), "--udp-port", str(port - 210))
    try:
        _wait_for_line(sim.stdout, "connect with", 60)
        yield
    finally:
        sim.send_signal(signal.SIGTERM)
        sim.communicate(timeout=30)


def _sigterm_run(port: int, run_args: list[str], started: str, timeout_s: float,
                 delay_s: float) -> tuple[subprocess.Popen, str, str]:
    """Fly the patrol with ``run``, SIGTERM it ``delay_s`` after the line ``started``; the finished
    ``run`` process and its output."""
    run = _cli("run", PATROL, "--connect", f"tcp:127.0.0.1:{port}", *run_args)
    try:
        _wait_for_line(run.stdout, started, timeout_s)
        time.sleep(delay_s)
        run.send_signal(signal.SIGTERM)
        out, err = run.communicate(timeout=60)
    finally:
        run.kill()
    return run, out, err


def _sigterm_mid_flight(speedup: str, port: int, run_args: list[str], started: str, timeout_s: float,
                        delay_s: float) -> tuple[subprocess.Popen, str, str]:
    """:func:`_sigterm_run` against a simulator of its own."""
    with _sitl(speedup, port):
        return _sigterm_run(port, run_args, started, timeout_s, delay_s)


@pytest.mark.slow
def test_run_on_sigterm_halts_the_tree_finishes_the_log_and_exits_130(tmp_path):
    # 2x: the vehicle's 5 s GCS failsafe is then 2.5 s of wall time, more than a loaded machine starves a process
    run, out, err = _sigterm_mid_flight("2", 15761, ["--record", str(tmp_path / "f.mcap")], "flying", 60, 3.0)
    assert run.returncode == 130, err
    assert "interrupted" in out and "Traceback" not in err
    from chaser_bt.log.replay import read_log

    assert not read_log(tmp_path / "f.mcap").truncated  # the recorder finished the file


@pytest.mark.slow
@pytest.mark.parametrize("speedup", ["1", "10"])
def test_run_on_sigterm_mid_leg_confirms_the_hold_at_any_speed(speedup):
    """SIGTERM while the patrol flies its first leg: the exit line says the hold took, at 1x as at 10x."""
    # the first leg is under way once the take-off succeeds; a few seconds more at 1x for it to pick up speed
    run, out, err = _sigterm_mid_flight(speedup, 15763, ["--show-ticks"], "ArmAndTakeoff RUNNING->SUCCESS",
                                        600 / float(speedup) + 60, 3.0 / float(speedup))
    assert run.returncode == 130, err
    last = out.strip().splitlines()[-1]
    assert last.startswith("interrupted: ") and "hold confirmed: GUIDED at" in last, last


@pytest.mark.slow
def test_run_again_on_the_aircraft_an_interrupted_run_left_flying_joins_it_and_completes():
    """Rejoin: a second ``run`` on the vehicle the first left holding mid-leg (or already under its GCS
    failsafe's RTL) takes home from the vehicle, flies the whole patrol and lands: exit 0, no traceback."""
    port, speedup = 15765, "4"
    with _sitl(speedup, port):
        first, out, err = _sigterm_run(port, ["--show-ticks"], "ArmAndTakeoff RUNNING->SUCCESS", 200, 1.0)
        assert first.returncode == 130, err
        again = _cli("run", PATROL, "--connect", f"tcp:127.0.0.1:{port}", "--show-ticks")
        try:
            out, err = again.communicate(timeout=300)
        finally:
            again.kill()
    assert again.returncode == 0 and "Traceback" not in err, err
    assert "ArmAndTakeoff RUNNING->SUCCESS" in out
    assert out.strip().splitlines()[-1].startswith("completed: "), out[-2000:]
