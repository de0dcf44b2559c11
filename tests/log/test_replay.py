"""Replay: a recorded rehearsal replayed into the same tree reproduces the tree's status changes and the
radar correlator's associations exactly; a changed tree shows what it would have done; ``chaser-bt
replay`` and ``chaser-bt plot`` on a log; a log cut short still replays up to the cut."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from chaser_bt.log import schemas as S
from chaser_bt.log.commands import add_command
from chaser_bt.log.replay import (LogError, flight_trace, read_log, recorded_associations, recorded_status_changes,
                                  replay)
from chaser_bt.tree import load_tree_text
from log_flight import TREE_TEXT, fly


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("replay") / "radar_hop.mcap"
    runner, recorder = fly(path)
    return path, runner


def tree(text: str = TREE_TEXT):
    return load_tree_text(text, source="<replay test>")


def cli(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    args = parser.parse_args(list(argv))
    return args.handler(args)


def test_replay_reproduces_status_changes_and_associations_exactly(recorded):
    path, runner = recorded
    log = read_log(path)
    result = replay(log, tree())
    assert result.status_changes == runner.tick_log  # the flight itself, not just its recording
    assert result.ticks == runner.ticks and result.ended == "root SUCCESS"
    assert recorded_status_changes(log) == runner.tick_log
    assert len(result.associations) > 20
    assert result.associations == recorded_associations(log)
    assert {a["associated_id"] for a in result.associations} - {None}  # the ownship was found


def test_a_changed_tree_on_the_recorded_flight_does_what_it_would_have_done(recorded):
    path, runner = recorded
    shorter = TREE_TEXT.replace("Hover: {duration_s: 6}", "Hover: {duration_s: 3}")
    result = replay(read_log(path), tree(shorter))
    hover = {(c.node, c.new): c.t for c in runner.tick_log}
    again = {(c.node, c.new): c.t for c in result.status_changes}
    assert again[("Hover", "RUNNING")] == hover[("Hover", "RUNNING")]  # same flight up to the hover
    assert again[("Hover", "SUCCESS")] == pytest.approx(hover[("Hover", "SUCCESS")] - 3.0, abs=0.15)
    # Landing was commanded 3 s early, but the replayed vehicle lands when the recorded one did.
    assert result.ended == "root SUCCESS"
    assert again[("Land", "SUCCESS")] == hover[("Land", "SUCCESS")]


def test_another_correlator_runs_on_the_recorded_datagrams(recorded):
    path, _ = recorded
    log = read_log(path)
    result = replay(log, tree(), correlator="alg1")
    assert result.correlator == "alg1" and replay(log, tree()).correlator == "gated"  # as recorded
    assert result.datagrams > 0
    # The paper's Algorithm 1 finds the same ownship track as ours in this clear scene.
    recorded_ids = [a["associated_id"] for a in recorded_associations(log)]
    assert [a["associated_id"] for a in result.associations] == recorded_ids


def test_replay_command_reports_an_exact_match(recorded, capsys):
    path, runner = recorded
    tree_file = path.with_name("radar_hop.yaml")
    tree_file.write_text(TREE_TEXT)
    assert cli("replay", str(path), str(tree_file), "--check", "--json") == 0
    out = json.loads(capsys.readouterr().out)
    assert out["status_changes_as_recorded"] and out["associations_as_recorded"] and out["target_cues_as_recorded"]
    assert len(out["status_changes"]) == len(runner.tick_log)
    assert out["target_cues"] == len(read_log(path).topic(S.TOPIC_TARGET)) > 20  # the radar's cues
    changed = path.with_name("changed.yaml")
    changed.write_text(TREE_TEXT.replace("Hover: {duration_s: 6}", "Hover: {duration_s: 3}"))
    assert cli("replay", str(path), str(changed), "--check") == 1
    assert "differ from the recording" in capsys.readouterr().out


def test_replay_command_rejects_what_is_not_a_log(tmp_path, capsys):
    bogus = tmp_path / "bogus.mcap"
    bogus.write_text("not mcap")
    tree_file = tmp_path / "t.yaml"
    tree_file.write_text(TREE_TEXT)
    assert cli("replay", str(bogus), str(tree_file)) == 2
    assert str(bogus) in capsys.readouterr().err
    assert cli("replay", str(tmp_path / "missing.mcap"), str(tree_file)) == 2
    assert "no such log file" in capsys.readouterr().err
    with pytest.raises(LogError, match="not a readable MCAP log"):
        read_log(bogus)


def test_a_log_cut_short_replays_up_to_the_cut(recorded, tmp_path):
    path, runner = recorded
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    log = read_log(cut)
    full = read_log(path)
    assert log.truncated and 0 < len(log.messages) < len(full.messages)
    assert [m.data for m in log.messages] == [m.data for m in full.messages[: len(log.messages)]]
    result = replay(log, tree())
    assert result.ended == "end of log"
    assert result.status_changes == runner.tick_log[: len(result.status_changes)]


def test_flight_trace_follows_the_recorded_telemetry(recorded):
    path, runner = recorded
    log = read_log(path)
    trace = flight_trace(log)
    ticks = [m.json() for m in log.topic(S.TOPIC_TREE) if m.json()["tick"] is not None]
    assert len(trace) == runner.ticks == len(ticks)
    assert trace.t == pytest.approx([r["t"] for r in ticks])
    states = [m.json()["value"] for m in log.topic(S.TOPIC_BLACKBOARD) if m.json()["key"] == "/vehicle/state"]
    assert np.allclose(trace.ownship_enu, [s["position_enu"] for s in states], equal_nan=True)
    assert trace.target_source == "cue"
    cue_ticks = ~np.isnan(trace.target_enu[:, 0])
    assert 20 < cue_ticks.sum() < len(trace)  # from the first cue, held while fresh
    # Events from the recorded decisions: validated, then airborne, each once; the modes it flew.
    names = [e.name for e in trace.events if e.name != "mode"]
    assert sorted(names) == ["airborne", "radar_validated"]
    validated = trace.first_event("radar_validated")
    validated_at = next(c.t for c in runner.tick_log if c.node == "RadarTrackValidated" and c.new == "SUCCESS")
    assert validated.t == pytest.approx(validated_at, abs=1e-6)  # log times are whole nanoseconds
    assert [e.detail for e in trace.events if e.name == "mode"][-2:] == ["GUIDED", "LAND"]
    assert trace.phase == trace.mode  # the tree writes no /mission/phase: the mode stands in
    assert np.nanmax(trace.ownship_enu[:, 2]) == pytest.approx(15.0, abs=1.5)


def test_plot_command_draws_the_figures(recorded, tmp_path, capsys):
    path, _ = recorded
    out = tmp_path / "plots"
    assert cli("plot", str(path), "--out", str(out)) == 0
    written = capsys.readouterr().out.split()
    assert {p.rsplit("/", 1)[-1] for p in written} == {"overhead.png", "relative_geometry.png"}
    for p in written:
        assert (out / p.rsplit("/", 1)[-1]).stat().st_size > 5000


@pytest.mark.slow
@pytest.mark.parametrize("camera_lag", [False, True], ids=["inline", "lagged"])
def test_replay_reruns_the_detector_on_lossless_frames_exactly(tmp_path, camera_lag, capsys):
    """Every frame recorded as PNG: the replayed detector, trackers and range filter give the same
    estimates, byte for byte, and the same status changes (JPEG frames would not promise that); a
    rehearsal's camera, a frame behind the tick, too."""
    from chaser_bt.log.recorder import attach_recorder
    from chaser_bt.log.replay import recorded_camera_factory
    from log_flight import VISION_TREE_TEXT

    runner, recorder = fly(tmp_path / "vision.mcap", vision=True, camera_lag=camera_lag, frame_format="png",
                           frame_period_s=0.0)
    log = read_log(tmp_path / "vision.mcap")
    assert json.loads(log.meta["camera"]).get("lag_frames", 0) == int(camera_lag)
    again: list = []
    result = replay(log, tree(VISION_TREE_TEXT), camera_factory=recorded_camera_factory(log),
                    on_start=lambda r, link, res: again.append(attach_recorder(r, link, res, tmp_path / "again.mcap")))
    again[0].close()
    assert result.status_changes == runner.tick_log
    assert result.frames == recorder.counts[S.TOPIC_CAMERA] >= 25
    estimates = [m.data for m in log.topic(S.TOPIC_TARGET)]
    assert len(estimates) > 15  # the target was seen
    assert [m.data for m in read_log(tmp_path / "again.mcap").topic(S.TOPIC_TARGET)] == estimates
    tree_file = tmp_path / "vision.yaml"
    tree_file.write_text(VISION_TREE_TEXT)
    assert cli("replay", str(tmp_path / "vision.mcap"), str(tree_file), "--check") == 0  # the command says so too
    assert f"target cues and estimates: {len(estimates)}, exactly as recorded" in capsys.readouterr().out
