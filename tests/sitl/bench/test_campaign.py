"""Campaigns: seeds, success, aggregates against hand-worked values, resume after a stop, the CLI, the report."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Iterator

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from chaser_bt.log.trace import FlightTrace, TraceEvent
from sitl.bench import campaign as cm
from sitl.bench.campaign import (
    CampaignConfig,
    CampaignError,
    RunSpec,
    SuccessRule,
    aggregate,
    followed_s,
    parse_seeds,
    summarise,
)
from sitl.bench.report import write_rehearsal_report

ROOT = Path(__file__).resolve().parents[3]
PATROL_SCENARIO = ROOT / "sitl" / "scenarios" / "patrol.yaml"


# -- seeds ----------------------------------------------------------------------------------------


def test_seed_syntax_examples():
    assert parse_seeds("1-5") == [1, 2, 3, 4, 5]
    assert parse_seeds("1,3,7") == [1, 3, 7]
    assert parse_seeds("1-3,20") == [1, 2, 3, 20]
    assert parse_seeds(" 7 , 2-3 ") == [2, 3, 7]
    assert parse_seeds("0") == [0]


@pytest.mark.parametrize("text", ["", "a", "1,,2", "5-3", "1-", "-1", "1-2-3", "1.5", "1,1", "2-3,3"])
def test_bad_seeds_are_refused_naming_the_item(text):
    with pytest.raises(CampaignError, match="--seeds"):
        parse_seeds(text)


@given(st.lists(st.tuples(st.integers(1, 50), st.integers(0, 20)), min_size=1, max_size=8))
def test_seed_ranges_round_trip(items):
    # Each item is a single seed (width 0) or a range a-(a+width), apart from the one before by a gap;
    # the result is the union, sorted, whatever the order of the items.
    ranges, end = [], -1
    for gap, w in items:
        ranges.append((end + gap, end + gap + w))
        end += gap + w
    text = ",".join(f"{a}" if a == b else f"{a}-{b}" for a, b in reversed(ranges))
    assert parse_seeds(text) == [s for a, b in ranges for s in range(a, b + 1)]


@given(st.integers(0, 500), st.integers(0, 20), st.integers(0, 20))
def test_a_seed_named_twice_is_refused(a, w, k):
    with pytest.raises(CampaignError, match="more than once"):
        parse_seeds(f"{a}-{a + w},{a + min(k, w)}")


# -- success, follow time, aggregates -------------------------------------------------------------


def test_success_rule():
    rule = SuccessRule(min_followed_s=20.0)
    assert rule({"outcome": "landed"})  # a mission without a target: ending well is enough
    assert not rule({"outcome": "crashed"})
    assert not rule({"outcome": "timeout"})
    chase = {"outcome": "following", "target_in_fov_frac": 0.9, "t_acquire_s": 3.0, "followed_s": 25.0}
    assert rule(chase)
    # The target was there but never acquired: the paper's FOV share is not scored, the flight's is.
    assert not rule({"outcome": "following", "target_in_fov_frac": None, "target_in_fov_frac_flight": 0.6, "t_acquire_s": None})
    assert not rule({"outcome": "following", "has_target": True, "t_acquire_s": None})
    assert rule({"outcome": "landed", "has_target": False, "t_acquire_s": None})
    assert not rule({**chase, "followed_s": 19.9})
    assert not rule({**chase, "t_acquire_s": None})
    assert rule({**chase, "followed_s": None})  # no trace: acquisition is what can be checked
    assert not rule({"outcome": "landed", "sar_found": False, "target_in_fov_frac": 0.0})
    assert rule({"outcome": "landed", "sar_found": True})
    assert rule({"outcome": "landed", "sar_found": None})  # no person in the scenario: not a search and rescue


def test_followed_seconds_count_in_fov_ticks_after_acquisition():
    t = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    in_fov = np.array([1.0, 1.0, 0.0, 1.0, np.nan, 1.0])
    tr = FlightTrace(t=t, ownship_enu=np.zeros((6, 3)), ownship_yaw_rad=np.zeros(6), target_enu=np.zeros((6, 3)),
                     in_fov=in_fov, detected=np.zeros(6), events=[TraceEvent(1.0, "acquired")])
    # After t = 1: in FOV at 1, 3 and 5, each worth 1 s (the last tick counts the median step).
    assert followed_s(tr) == pytest.approx(3.0)
    tr.events = []
    assert followed_s(tr) == 0.0
    assert followed_s(None) is None


def test_summary_uses_linear_percentiles():
    s = summarise([4.0, 1.0, None, 3.0, 2.0, float("nan")])
    # Sorted 1 2 3 4; percentile q sits at position 3q: p10 1.3, p25 1.75, median 2.5, p75 3.25, p90 3.7.
    assert s["n"] == 4
    assert (s["p10"], s["p25"], s["median"], s["p75"], s["p90"]) == pytest.approx((1.3, 1.75, 2.5, 3.25, 3.7))
    assert s["iqr"] == pytest.approx(1.5) and s["mean"] == 2.5 and (s["min"], s["max"]) == (1.0, 4.0)
    assert summarise([])["median"] is None


def test_a_retasked_run_needs_every_scheduled_retask_taken_and_both_missions_done():
    rule = SuccessRule(min_followed_s=20.0)
    taken = {"t": 90.0, "accepted": True, "message": "tree a -> b, aircraft held at the hand-over"}
    refused = {"t": 90.0, "accepted": False, "message": "retask sar.yaml (scenario at 90 s): the autopilot is flying RTL"}
    # A search alone: its person is a target in the trace, but no radar track launched it.
    search = {"outcome": "landed", "sar_found": True, "has_target": True, "t_airborne_s": None, "t_acquire_s": None}
    assert rule(search)
    # A chase retasked at 90 s to a search: the chase (acquired, followed 25 s) and the find both count.
    both = {**search, "t_airborne_s": 11.6, "t_acquire_s": 2.7, "followed_s": 25.0, "custody_at_end": True,
            "retasks": [taken], "retasks_scheduled": 1}
    assert rule(both)
    assert not rule({**both, "sar_found": False})  # the search after the retask found no one
    assert not rule({**both, "t_acquire_s": None})  # the chase before it never acquired the intruder
    assert not rule({**both, "followed_s": 12.0})
    assert not rule({**both, "retasks": [refused]})  # the retask was refused: not what the scenario meant
    assert not rule({**both, "retasks": None})  # the run ended before the retask was due
    assert not rule({**both, "retasks": [taken], "retasks_scheduled": 2})
    assert rule({**both, "retasks": [refused, taken], "retasks_scheduled": 1})  # refused once, then taken
    assert cm.retasks_missed({**both, "retasks": [refused], "retasks_scheduled": 2}) == 2
    assert cm.retasks_missed({"outcome": "landed"}) == 0

    agg = aggregate([both, {**both, "retasks": [refused]}, {**both, "retasks": [refused, refused]}, search], rule)
    assert agg["success"] == 2  # the first run and the search alone
    assert agg["retasks"] == {"runs": 3, "scheduled": 3, "taken": 1, "missed": 2, "refusals": {refused["message"]: 3}}
    assert "retasks" not in aggregate([search], rule)


def test_following_another_drone_at_the_end_is_no_success():
    row = {"outcome": "following", "t_acquire_s": 3.0, "followed_s": 60.0, "has_target": True}
    assert SuccessRule()(row) and SuccessRule()({**row, "custody_at_end": True})
    assert not SuccessRule()({**row, "custody_at_end": False})


def test_aggregate_against_hand_worked_rows():
    base = {"target_in_fov_frac": 0.95, "followed_s": 30.0}
    rows = [
        {**base, "scenario_file": "a", "outcome": "following", "t_airborne_s": 10.0, "t_acquire_s": 2.0},
        {**base, "scenario_file": "a", "outcome": "following", "t_airborne_s": 14.0, "t_acquire_s": 6.0},
        {**base, "scenario_file": "b", "outcome": "crashed", "t_airborne_s": 12.0, "t_acquire_s": None},
        {**base, "scenario_file": "b", "outcome": "following", "t_airborne_s": 20.0, "t_acquire_s": 4.0,
         "target_in_fov_frac": 0.5, "followed_s": 5.0},
    ]
    agg = aggregate(rows, SuccessRule(min_followed_s=20.0))
    assert (agg["runs"], agg["success"], agg["success_frac"]) == (4, 2, 0.5)
    assert agg["outcomes"] == {"following": 3, "crashed": 1}
    a, b = agg["by_scenario"]["a"], agg["by_scenario"]["b"]
    assert (a["runs"], a["success"], a["success_frac"]) == (2, 2, 1.0)
    assert (b["runs"], b["success"], b["success_frac"]) == (2, 0, 0.0)
    # Per scenario: medians of a's acquisitions (2, 6) and b's one (4); b's FOV shares 0.95 and 0.5.
    assert (a["t_acquire_s_median"], b["t_acquire_s_median"], b["target_in_fov_frac_median"]) == (4.0, 4.0, 0.725)
    assert a["custody_frac_median"] is None and a["target_switches"] is None
    air = agg["metrics"]["t_airborne_s"]
    assert (air["n"], air["median"], air["p25"], air["p75"]) == (4, 13.0, 11.5, 15.5)
    assert air["paper"] == 15.48 and air["median_beats_paper"] is True  # 13 s < 15.48 s
    acq = agg["metrics"]["t_acquire_s"]
    assert (acq["n"], acq["median"]) == (3, 4.0) and acq["median_beats_paper"] is True
    fov = agg["metrics"]["target_in_fov_frac"]
    assert fov["median"] == pytest.approx(0.95) and fov["median_beats_paper"] is True
    assert agg["metrics"]["detection_frac"]["n"] == 0 and agg["metrics"]["detection_frac"]["median_beats_paper"] is None
    assert "sar_found_frac" not in agg
    sar = [{"outcome": "landed", "sar_found": True}, {"outcome": "landed", "sar_found": False}, {"outcome": "landed", "sar_found": None}]
    assert aggregate(sar)["sar_found_frac"] == 0.5
    assert aggregate(sar)["sar_wrong_finds"] == 0  # the one not found reported nothing
    wrong = {"outcome": "landed", "sar_found": False, "sar_find_error_m": 27.9}
    assert aggregate([*sar, wrong])["sar_wrong_finds"] == 1


# -- running, storing, resuming -------------------------------------------------------------------

EXECUTED: list[str] = []


def _fake_runner(spec: RunSpec) -> dict:
    """Stands in for a rehearsal: a row whose numbers follow from the seed; counts executions."""
    EXECUTED.append(spec.key)
    n = 20
    t = np.arange(n) * 1.0
    tr = FlightTrace(t=t, ownship_enu=np.column_stack([t, t * 0, t * 0 + 20]), ownship_yaw_rad=np.zeros(n),
                     target_enu=np.column_stack([t + 30, t * 0, t * 0 + 10]), in_fov=np.ones(n), detected=np.ones(n),
                     phase=["follow"] * n, mode=["GUIDED"] * n, tip=[""] * n,
                     events=[TraceEvent(2.0, "acquired")], desired_range_m=40.0)
    row = {"outcome": "following", "seed": spec.seed, "t_airborne_s": 10.0 + spec.seed, "t_acquire_s": 1.0 * spec.seed,
           "target_in_fov_frac": 0.9, "followed_s": followed_s(tr), "sim_time_s": 20.0, "wall_time_s": 0.01,
           "key": spec.key, "scenario_file": spec.scenario_stem, "fingerprint": spec.fingerprint}
    return {"row": row, "trace": tr}


HOP_TREE = """\
version: 1
main: Hop
trees:
  Hop:
    Sequence:
      name: hop
      children:
        - ArmAndTakeoff: {altitude_m: 5}
        - Land: {name: land}
"""


HOP_MAIN = """\
version: 1
includes: [parts/land.yaml]
main: Hop
trees:
  Hop:
    Sequence:
      children:
        - ArmAndTakeoff: {altitude_m: 5}
        - SubTree: {ID: Down}
"""
HOP_PARTS = {
    "parts/land.yaml": "version: 1\nincludes: [deeper.yaml]\ntrees:\n  Down:\n    SubTree: {ID: Deeper}\n",
    "parts/deeper.yaml": "version: 1\ntrees:\n  Deeper:\n    Land: {name: land}\n",
}


def test_campaign_flies_again_when_a_file_the_tree_includes_changes(tmp_path, inputs):
    _, scenario = inputs
    tree = tmp_path / "hop_main.yaml"
    tree.write_text(HOP_MAIN)
    for name, text in HOP_PARTS.items():
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text(text)
    (tmp_path / "parts/unused.yaml").write_text(HOP_PARTS["parts/deeper.yaml"])
    config = CampaignConfig(tree=tree, scenarios=[scenario], seeds=[1, 2], out_dir=tmp_path / "out")
    EXECUTED.clear()
    cm.run_campaign(config, runner=_fake_runner, report=False)
    assert len(EXECUTED) == 2

    EXECUTED.clear()
    (tmp_path / "parts/unused.yaml").write_text("# not included by the tree\n")
    cm.run_campaign(config, runner=_fake_runner, report=False)
    assert EXECUTED == []  # nothing the tree reads changed

    for edited in ("parts/deeper.yaml", "parts/land.yaml"):  # included through another file, then directly
        EXECUTED.clear()
        (tmp_path / edited).write_text((tmp_path / edited).read_text() + "# edited\n")
        cm.run_campaign(config, runner=_fake_runner, report=False)
        assert len(EXECUTED) == 2, edited

    EXECUTED.clear()
    scenario.write_text(scenario.read_text() + "\n# edited\n")
    cm.run_campaign(config, runner=_fake_runner, report=False)
    assert len(EXECUTED) == 2


@pytest.fixture
def inputs(tmp_path):
    """A short mission (take off to 5 m, land: about a minute of sim time) on the patrol field."""
    tree = tmp_path / "hop.yaml"
    scenario = tmp_path / "field.yaml"
    tree.write_text(HOP_TREE)
    shutil.copy(PATROL_SCENARIO, scenario)
    return tree, scenario


def test_stopped_campaign_resumes_without_redoing_finished_runs(tmp_path, inputs):
    tree, scenario = inputs
    config = CampaignConfig(tree=tree, scenarios=[scenario], seeds=list(range(1, 7)), out_dir=tmp_path / "out",
                            success=SuccessRule(min_followed_s=15.0))
    EXECUTED.clear()

    def stop_after_two(done, total, row):
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        cm.run_campaign(config, runner=_fake_runner, on_result=stop_after_two)
    assert EXECUTED == ["field/seed_0001", "field/seed_0002"]
    stored = sorted(p.name for p in (tmp_path / "out/runs/field").glob("*.json"))
    assert stored == ["seed_0001.json", "seed_0002.json"]
    (tmp_path / "out/runs/field/.seed_0003.json.tmp").write_text("{half a file")  # a run killed mid-write

    # The report of what is stored so far, flying nothing.
    EXECUTED.clear()
    partial = cm.run_campaign(dataclasses.replace(config, report_only=True), runner=_fake_runner)
    assert partial.executed == 0 and [r["seed"] for r in partial.rows] == [1, 2] and EXECUTED == []
    with pytest.raises(CampaignError, match="no stored runs"):
        cm.run_campaign(dataclasses.replace(config, report_only=True, seeds=[9]), runner=_fake_runner)

    EXECUTED.clear()
    result = cm.run_campaign(config, runner=_fake_runner)
    assert EXECUTED == [f"field/seed_{s:04d}" for s in range(3, 7)]  # four runs flown, two reused
    assert result.executed == 4 and len(result.rows) == 6
    assert [r["seed"] for r in result.rows] == [1, 2, 3, 4, 5, 6]
    # Aggregates over all six: t_airborne 11..16 -> median 13.5; acquire 1..6 -> median 3.5.
    assert result.aggregates["metrics"]["t_airborne_s"]["median"] == 13.5
    assert result.aggregates["metrics"]["t_acquire_s"]["median"] == 3.5
    assert [r["followed_s"] for r in result.rows] == [18.0] * 6  # in the FOV from the acquisition at 2 s to 20 s
    assert result.aggregates["success"] == 6  # 18 s >= the 15 s asked
    assert aggregate(result.rows, SuccessRule(min_followed_s=20.0))["success"] == 0
    # The report: every run in campaign.json, the figures drawn from the stored traces.
    saved = json.loads((tmp_path / "out/campaign.json").read_text())
    assert [r["key"] for r in saved["rows"]] == [f"field/seed_{s:04d}" for s in range(1, 7)]
    assert saved["aggregates"]["metrics"]["t_airborne_s"]["paper"] == 15.48
    assert set(result.files) == {"json", "markdown", "cdfs", "overhead", "geometry"}
    md = (tmp_path / "out/campaign.md").read_text()
    assert "| t_airborne_s | 6 | 13.5 |" in md
    assert "## By scenario" in md and "| field | 6/6 |" in md  # success as runs that succeeded / runs

    EXECUTED.clear()
    cm.run_campaign(config, runner=_fake_runner, report=False)
    assert EXECUTED == []  # everything stored: nothing flown

    # A run that ended in error (say, a weights file was missing) is flown again on resume.
    path = tmp_path / "out/runs/field/seed_0004.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), "outcome": "error"}))
    cm.run_campaign(config, runner=_fake_runner, report=False)
    assert EXECUTED == ["field/seed_0004"]
    assert json.loads(path.read_text())["outcome"] == "following"
    EXECUTED.clear()

    tree.write_text(tree.read_text() + "\n# edited\n")  # another tree: stored results no longer count
    cm.run_campaign(config, runner=_fake_runner, report=False)
    assert len(EXECUTED) == 6


def test_report_only_reports_a_campaign_still_writing_into_the_folder(tmp_path, inputs):
    """``--report-only`` only reads the stored runs and writes the report: it takes no lock, so it reports a
    campaign still flying into the folder, which refuses a second campaign all the same."""
    tree, scenario = inputs
    out = tmp_path / "out"
    config = CampaignConfig(tree=tree, scenarios=[scenario], seeds=[1, 2, 3], out_dir=out)
    cm.run_campaign(dataclasses.replace(config, seeds=[1, 2]), runner=_fake_runner, report=False)
    holder = subprocess.Popen(  # the campaign still flying: it holds the folder
        [sys.executable, "-c", "import sys; from pathlib import Path; from sitl.bench.out_lock import lock_out_dir\n"
                               "with lock_out_dir(Path(sys.argv[1])):\n    print('held', flush=True); sys.stdin.read()",
         str(out)], cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        EXECUTED.clear()
        partial = cm.run_campaign(dataclasses.replace(config, report_only=True), runner=_fake_runner)
        assert EXECUTED == [] and [r["seed"] for r in partial.rows] == [1, 2]
        assert "| t_airborne_s | 2 | 11.5 |" in (out / "campaign.md").read_text()
        with pytest.raises(cm.OutDirError, match=f"--out {out} is in use by another campaign \\(pid {holder.pid}\\)"):
            cm.run_campaign(config, runner=_fake_runner)
        assert EXECUTED == []  # the refused campaign flew nothing
    finally:
        holder.communicate("", timeout=30)


# -- the command line -----------------------------------------------------------------------------


def _cli(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="chaser-bt")
    cm.add_command(parser.add_subparsers(dest="command"))
    try:
        args = parser.parse_args(["campaign", *argv])
    except SystemExit as exc:  # argparse's own checks (types, choices)
        return exc.code
    return args.handler(args)


@pytest.mark.parametrize("argv, message", [
    (["--seeds", "9-2"], "--seeds"),
    (["--seeds", "x"], "--seeds"),
    (["--workers", "0"], "--workers"),
    (["--scenarios", "/nonexistent/dir"], "no such file or folder"),
    (["--min-success", "2"], "--min-success"),
])
def test_cli_bad_arguments_exit_2_with_a_message(tmp_path, inputs, capsys, argv, message):
    tree, scenario = inputs
    base = {"--scenarios": str(scenario), "--seeds": "1", "--out": str(tmp_path / "o")}
    for flag, value in zip(argv[::2], argv[1::2]):
        base[flag] = value
    assert _cli([str(tree), *[x for kv in base.items() for x in kv]]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o" / "runs").exists()  # nothing flown


def test_cli_refuses_an_invalid_tree_and_an_empty_scenario_folder(tmp_path, inputs, capsys):
    tree, scenario = inputs
    bad = tmp_path / "bad.yaml"
    bad.write_text("version: 1\nmain: X\ntrees:\n  X:\n    NoSuchNode: {}\n")
    assert _cli([str(bad), "--scenarios", str(scenario), "--seeds", "1", "--out", str(tmp_path / "o")]) == 2
    assert "bad.yaml: invalid tree" in capsys.readouterr().err
    assert _cli([str(tmp_path / "nope.yaml"), "--scenarios", str(scenario), "--seeds", "1", "--out", str(tmp_path / "o")]) == 2
    assert "nope.yaml: no such tree file" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert _cli([str(tree), "--scenarios", str(tmp_path / "empty"), "--seeds", "1", "--out", str(tmp_path / "o")]) == 2
    assert "no .yaml scenario files" in capsys.readouterr().err


def test_cli_flies_patrol_and_writes_the_report(tmp_path, inputs, capsys):
    tree, scenario = inputs
    out = tmp_path / "out"
    assert _cli([str(tree), "--scenarios", str(scenario), "--seeds", "3", "--workers", "1", "--no-camera", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "1 runs (1 flown now): success 1/1" in printed
    row = json.loads((out / "runs/field/seed_0003.json").read_text())
    assert row["outcome"] == "landed" and row["seed"] == 3 and row["fingerprint"]
    assert row["has_target"] is False and row["trace_file"] == "runs/field/seed_0003.npz"  # nothing to chase on this field
    assert row["sar_found"] is None  # the SAR observer rode along: no person on this field
    saved = json.loads((out / "campaign.json").read_text())
    assert saved["aggregates"]["success_frac"] == 1.0 and saved["rows"][0]["outcome"] == "landed"
    assert (out / "campaign.md").is_file() and (out / "cdfs.png").is_file()


def test_a_worker_pins_torch_and_blas_to_one_thread_before_flying(monkeypatch):
    class FakeTorch:
        threads = 4

        def get_num_threads(self):
            return self.threads

        def set_num_threads(self, n):
            self.threads = n

    fake = FakeTorch()
    monkeypatch.setitem(sys.modules, "torch", fake)
    monkeypatch.setenv("OMP_NUM_THREADS", "8")
    seen = {}

    def runner(spec):
        seen.update(omp=os.environ["OMP_NUM_THREADS"], torch=fake.threads, seed=spec.seed)
        return {"row": {}}

    cm._in_worker(runner, RunSpec("t.yaml", "s.yaml", 5))
    assert seen == {"omp": "1", "torch": 1, "seed": 5}


def test_progress_without_tqdm_prints_a_line_per_run_with_an_eta():
    import io

    stream = io.StringIO()
    progress = cm._Progress(stream, use_tqdm=False)
    progress.begin(total=10, already=4)
    progress.start -= 30.0  # two runs flown in 30 s: 15 s a run, 4 left -> 60 s
    progress(5, 10, {"key": "a/seed_0005", "outcome": "landed"})
    progress(6, 10, {"key": "a/seed_0006", "outcome": "crashed"})
    lines = stream.getvalue().splitlines()
    assert lines[0] == "4 of 10 runs already done: resuming"
    assert lines[2] == "[6/10] a/seed_0006: crashed | not ok 1 | ETA 1m00s"


def _stored(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((out / "runs").rglob("seed_*.json"))}


@pytest.mark.slow
def test_interrupted_process_campaign_resumes_where_it_stopped(tmp_path, inputs):
    """Ctrl-C on a 2-worker campaign of real patrol rehearsals, then the same command again."""
    tree, scenario = inputs
    out = tmp_path / "out"
    # Eight runs for two workers: when the second result is stored at most four more are queued or
    # flying, so the interrupt always leaves some unflown (with four, all could finish first).
    cmd = [sys.executable, "-m", "sitl.bench.campaign", str(tree), "--scenarios", str(scenario), "--seeds", "1-8",
           "--workers", "2", "--no-camera", "--out", str(out)]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # A shell that starts the suite in the background ignores SIGINT, and Python keeps an inherited
    # "ignore": give the campaign the default disposition, as in a terminal.
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while len(_stored(out)) < 2 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "run the same command again to resume" in err
    before = _stored(out)
    assert 2 <= len(before) < 8
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"8 runs ({8 - len(before)} flown now)" in done.stdout
    after = _stored(out)
    assert len(after) == 8
    assert all(after[name] == data for name, data in before.items())  # finished runs were not flown again


# -- one rehearsal's report -----------------------------------------------------------------------


def test_rehearsal_report_writes_json_markdown_trace_and_figures(tmp_path):
    n = 10
    t = np.arange(n) * 0.1
    tr = FlightTrace(t=t, ownship_enu=np.column_stack([t, t, t + 20]), ownship_yaw_rad=np.zeros(n),
                     target_enu=np.column_stack([t + 30, t, t + 5]), in_fov=np.ones(n), detected=np.ones(n),
                     phase=["follow"] * n, mode=["GUIDED"] * n, tip=[""] * n, events=[TraceEvent(0.3, "acquired", "by vision")])
    report = {"outcome": "following", "tree": "Chase", "scenario": "chase", "seed": 4, "t_airborne_s": 12.5,
              "t_acquire_s": 6.0, "target_in_fov_frac": 0.95, "detection_frac": None, "message": "following", "ticks": 10}
    files = write_rehearsal_report(report, tmp_path / "rep", trace=tr)
    assert set(files) == {"json", "markdown", "trace", "overhead", "geometry"}
    assert json.loads(files["json"].read_text()) == report
    md = files["markdown"].read_text()
    assert "| t_airborne_s | 12.5 | 15.48 | yes |" in md  # faster than the paper
    assert "| t_acquire_s | 6 | 4.95 | no |" in md  # slower
    assert "| detection_frac | – | 0.66 | – |" in md
    assert "| 0.3 | acquired | by vision |" in md and "![" in md
    assert "from the start of the rehearsal (`t_airborne_s` counts from the radar validation)" in md
    loaded = FlightTrace.load(files["trace"])
    np.testing.assert_array_equal(loaded.ownship_enu, tr.ownship_enu)
    assert files["overhead"].read_bytes()[:4] == b"\x89PNG"
    # Without a trace: the numbers only.
    files = write_rehearsal_report(report, tmp_path / "bare")
    assert set(files) == {"json", "markdown"}


def test_report_entry_point_rehearses_and_writes_the_folder(tmp_path, inputs, capsys):
    from sitl.bench.report import main as report_main

    tree, scenario = inputs
    assert report_main([str(tree), "--scenario", str(tmp_path / "missing.yaml"), "--out", str(tmp_path / "r")]) == 2
    assert report_main([str(tree), "--scenario", str(scenario), "--seed", "2", "--out", str(tmp_path / "r")]) == 0
    assert "landed" in capsys.readouterr().out
    saved = json.loads((tmp_path / "r/report.json").read_text())
    assert (saved["tree"], saved["seed"], saved["outcome"]) == ("Hop", 2, "landed")
    assert (tmp_path / "r/overhead.png").is_file() and (tmp_path / "r/trace.npz").is_file()


# -- Ray --------------------------------------------------------------------------------------------


def _ray_here_on_the_loopback(mp: pytest.MonkeyPatch) -> None:
    """A Ray instance started here binds to 127.0.0.1, without token authentication.

    Ray swaps 127.0.0.1 for the machine's routable address unless multi-node clusters are "off"
    (its switch for laptops); its token, left alone, would be written to ~/.ray.
    """
    mp.setenv("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
    mp.setenv("RAY_AUTH_MODE", "disabled")
    constants = sys.modules.get("ray._private.ray_constants")
    if constants is not None:  # read at import: this process imported ray before
        mp.setattr(constants, "ENABLE_RAY_CLUSTER", False)


def _flown(rows: list[dict]) -> dict[str, dict]:
    """Rows by key without the keys that depend on where and how fast a run flew (``VARYING_KEYS``)."""
    return {r["key"]: {k: v for k, v in r.items() if k not in cm.VARYING_KEYS} for r in rows}


def _local_rows(config: CampaignConfig) -> list[dict]:
    """The same campaign flown here, by the local executor, into a folder of its own."""
    return cm.run_campaign(dataclasses.replace(config, out_dir=config.out_dir.with_name("local"), ray_address=None),
                           report=False).rows


def test_a_node_without_the_mission_files_flies_the_copies_sent_with_the_task(tmp_path):
    mission = tmp_path / "mission"
    (mission / "parts").mkdir(parents=True)
    (mission / "hop_main.yaml").write_text(HOP_MAIN)
    for name, text in HOP_PARTS.items():
        (mission / name).write_text(text)
    shutil.copy(PATROL_SCENARIO, mission / "field.yaml")
    config = CampaignConfig(tree=mission / "hop_main.yaml", scenarios=[mission / "field.yaml"], seeds=[2],
                            out_dir=tmp_path / "out", camera=False)
    spec, = config.specs()
    sent = cm._input_files([spec])
    assert sorted(sent) == sorted(str(mission.resolve() / n) for n in ("hop_main.yaml", *HOP_PARTS, "field.yaml"))
    assert cm._on_this_node(spec, sent, tmp_path / "scratch") == spec  # the driver's machine: flown in place
    here = cm.run_one(spec)["row"]

    (mission / "field.yaml").write_text("an edited scenario\n")  # a node with other contents at the same path
    shutil.move(mission / "parts", tmp_path / "elsewhere")  # and without the includes
    copy = cm._on_this_node(spec, sent, tmp_path / "scratch")
    assert copy.tree.startswith(str(tmp_path / "scratch")) and Path(copy.scenario).read_bytes() == PATROL_SCENARIO.read_bytes()
    there = cm.run_one(copy)["row"]
    assert there["outcome"] == "landed"
    moved = {"tree_path", "scenario_path", *cm.VARYING_KEYS}
    assert {k: v for k, v in there.items() if k not in moved} == {k: v for k, v in here.items() if k not in moved}


@pytest.mark.slow
def test_campaign_on_a_local_ray_instance_matches_the_local_executor(tmp_path, inputs, monkeypatch):
    _ray_here_on_the_loopback(monkeypatch)
    tree, scenario = inputs
    config = CampaignConfig(tree=tree, scenarios=[scenario], seeds=[1, 2], out_dir=tmp_path / "ray", ray_address="local",
                            camera=False)
    result = cm.run_campaign(config, report=False)
    assert result.executed == 2
    assert [r["outcome"] for r in result.rows] == ["landed", "landed"]
    assert sorted(_stored(tmp_path / "ray")) == ["seed_0001.json", "seed_0002.json"]
    assert len({r["worker_node"] for r in result.rows}) == 1  # one node: this machine
    local = _local_rows(config)
    assert "worker_node" not in local[0]  # only Ray runs name a node
    assert _flown(result.rows) == _flown(local)


@dataclasses.dataclass
class RayCluster:
    address: str  # the head's GCS, HOST:PORT
    node_ids: set[str]


def _free_ports(n: int) -> list[int]:
    """``n`` distinct ports free on the loopback now (the OS's choice)."""
    socks = [socket.socket() for _ in range(n)]
    try:
        for s in socks:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def _ray_start(temp_dir: Path, log: Path, *args: str, env: dict[str, str] | None = None) -> int:
    """``ray start ARGS``, one CPU, its files under ``temp_dir``; the node's process group (its daemons
    and workers), or a test failure with the command's output."""
    agent, grpc, metrics, runtime_env = _free_ports(4)
    cmd = [sys.executable, "-m", "ray.scripts.scripts", "start", *args, "--num-cpus", "1", "--num-gpus", "0",
           "--object-store-memory", str(100 * 2**20), "--temp-dir", str(temp_dir),
           "--min-worker-port", "0", "--max-worker-port", "0",  # workers on ports the OS picks
           "--dashboard-agent-listen-port", str(agent), "--dashboard-agent-grpc-port", str(grpc),
           "--metrics-export-port", str(metrics), "--runtime-env-agent-port", str(runtime_env), "--disable-usage-stats"]
    with log.open("w") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
                                env={**os.environ, **(env or {})})
        try:
            rc = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            rc = None
    if rc != 0:
        _stop_ray([proc.pid], temp_dir)
        pytest.fail(f"ray start {' '.join(args)} {'timed out' if rc is None else f'exited {rc}'}:\n{log.read_text()[-3000:]}")
    return proc.pid


def _stop_ray(groups: list[int], temp_dir: Path) -> None:
    """End the nodes: every live process in their process groups or naming ``temp_dir``, politely, then not."""
    def ours() -> list[int]:
        pids = []
        for proc in Path("/proc").iterdir():
            if not proc.name.isdigit():
                continue
            try:
                stat = (proc / "stat").read_text().rsplit(")", 1)[1].split()  # state, ppid, pgrp, ...
                if stat[0] != "Z" and (int(stat[2]) in groups or str(temp_dir).encode() in (proc / "cmdline").read_bytes()):
                    pids.append(int(proc.name))
            except (OSError, IndexError, ValueError):
                pass
        return pids

    for sig, grace in ((signal.SIGTERM, 2.0), (signal.SIGKILL, 10.0)):  # Ray's daemons may take long over a SIGTERM
        for pid in ours():
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + grace
        while ours() and time.monotonic() < deadline:
            time.sleep(0.2)
        if not ours():
            return
    raise RuntimeError(f"Ray processes {ours()} outlived SIGKILL")


#: The head's address: a loopback one Ray keeps (it swaps 127.0.0.1 for the machine's routable
#: address). The second node, and the drivers here, reach it from 127.0.0.1: that node's address.
HEAD_IP = "127.0.0.2"


@pytest.fixture(scope="module")
def ray_cluster() -> Iterator[RayCluster]:
    """A two-node Ray cluster on this machine: ``ray start --head`` and a second ``ray start --address``,
    one CPU each, on the loopback, with files in a temporary folder; stopped however the tests end."""
    import ray

    mp = pytest.MonkeyPatch()
    mp.setenv("RAY_AUTH_MODE", "disabled")  # the nodes and the drivers here: no token to share
    temp_dir = Path(tempfile.mkdtemp(prefix="ray"))  # short: Ray's socket paths are limited to about 100 characters
    groups: list[int] = []
    try:
        port, = _free_ports(1)
        address = f"{HEAD_IP}:{port}"
        groups.append(_ray_start(temp_dir, temp_dir / "head.log", "--head", "--port", str(port), "--node-ip-address", HEAD_IP,
                                 "--include-dashboard", "false"))
        groups.append(_ray_start(temp_dir, temp_dir / "worker.log", "--address", address))
        ray.init(address=address, log_to_driver=False)
        try:
            deadline = time.monotonic() + 60
            while len(alive := [n["NodeID"] for n in ray.nodes() if n["Alive"]]) < 2 and time.monotonic() < deadline:
                time.sleep(0.2)
        finally:
            ray.shutdown()
        assert len(alive) == 2, f"the cluster at {address} has {len(alive)} live node(s), not 2"
        yield RayCluster(address, set(alive))
    finally:
        try:
            _stop_ray(groups, temp_dir)
        finally:
            shutil.rmtree(temp_dir, ignore_errors=True)
            mp.undo()


@pytest.mark.slow
def test_campaign_on_a_two_node_ray_cluster_spreads_and_matches_the_local_executor(tmp_path, inputs, ray_cluster):
    tree, scenario = inputs
    config = CampaignConfig(tree=tree, scenarios=[scenario], seeds=[1, 2, 3, 4], out_dir=tmp_path / "ray",
                            ray_address=ray_cluster.address, camera=False)
    result = cm.run_campaign(config, report=False)
    assert result.executed == 4 and [r["outcome"] for r in result.rows] == ["landed"] * 4
    stored = [json.loads(p.read_text()) for p in sorted((tmp_path / "ray/runs/field").glob("seed_*.json"))]
    assert {r["worker_node"] for r in stored} == ray_cluster.node_ids  # runs landed on both nodes, each named
    local = _local_rows(config)
    assert _flown(result.rows) == _flown(local)
    assert len({r["landed_dist_m"] for r in local}) > 1  # the seeds fly differently: equal rows are the same runs
    assert cm.run_campaign(config, report=False).executed == 0  # the node field does not stop a resume
