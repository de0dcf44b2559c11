"""The search-only SITL test (paper section 4.4) in the full simulator: the mission flies to the radar
cue, the radar goes silent within 200 m of the target, and RHCSearch runs on with the camera's
detection off, logging belief gain."""

from __future__ import annotations

import math

import numpy as np

from sitl.bench.search_trial import (
    SEARCH_ONLY,
    RadarGate,
    SearchConfig,
    run_trial,
    target_waypoints,
    trial_scenario,
)
from sitl.world.scenario import load_scenario


def test_target_paths_are_seeded_and_stay_well_inside_the_search_grid():
    assert target_waypoints(3) == target_waypoints(3)
    assert target_waypoints(3) != target_waypoints(4)
    for seed in range(20):
        pts = np.array(target_waypoints(seed))
        assert len(pts) >= 2
        assert np.all(np.abs(pts[:, 0]) <= 200) and np.all((pts[:, 1] >= 300) & (pts[:, 1] <= 450))
        assert np.all((pts[:, 2] >= 25) & (pts[:, 2] <= 55))
        # the radar is 150 m north of home: every point is 100 m or more inside the +-400 m grid around it
        assert np.all(np.abs(pts[:, 1] - 150.0) <= 300) and np.all(np.abs(pts[:, 0]) <= 300)
    sc = trial_scenario(5)
    assert sc.targets[0].path.points_enu[0] == tuple(target_waypoints(5)[0])
    assert load_scenario(SEARCH_ONLY).radar is not None


def test_the_radar_gate_passes_datagrams_until_silenced_then_drains_and_drops_them():
    class Queue:
        def __init__(self):
            self.items = []

        def receive(self):
            out, self.items = self.items, []
            return out

    q = Queue()
    gate = RadarGate(q)
    q.items = [b"a", b"b"]
    assert gate.receive() == [b"a", b"b"]
    gate.silence()
    q.items = [b"c"]
    assert gate.receive() == [] and q.items == []


def test_a_search_only_run_silences_the_radar_at_200_m_and_searches_on():
    trial = run_trial(SearchConfig("rhc", 5, 0.9), seed=0, search_s=30.0)
    assert trial.outcome == "searched", trial.outcome
    # The radar went off when the chaser closed to 200 m; the cue went stale and the search took over.
    assert trial.radar_off_s is not None and trial.search_start_s is not None
    assert 0.0 < trial.search_start_s - trial.radar_off_s < 3.5
    assert trial.t[0] == 0.0 and trial.t[-1] >= 30.0
    gains = np.array(trial.gain)
    assert np.all((gains >= 0.0) & (gains <= 1.0))
    # The belief's cumulative detection probability only grows, and the search did look at it.
    detected = np.array(trial.detected)
    assert np.all(np.diff(detected) >= -1e-12)
    assert detected[-1] > 0.3
    # Scoring: the search brought the (undetectable) target into the camera's footprint.
    assert trial.first_in_view_s is not None and math.isfinite(trial.first_in_view_s)


def test_the_search_trial_command_prints_a_summary_and_refuses_bad_input(capsys):
    import argparse
    import json

    from sitl.bench.search_trial import add_command

    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    args = parser.parse_args(["search-trial", "--horizon", "0"])
    assert args.handler(args) == 2
    assert "--horizon >= 1" in capsys.readouterr().err  # an error: on stderr
    args = parser.parse_args(["search-trial", "--planner", "max", "--search-s", "5", "--seed", "1", "--json"])
    assert args.handler(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["config"] == "max-belief" and out["outcome"] == "searched" and out["searched_s"] >= 5.0
    assert out["radar_off_s"] < out["search_start_s"]
