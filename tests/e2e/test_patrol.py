"""The patrol mission end to end: in-process rehearsal, reproducibility, failsafe, and over TCP."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from sitl.bench.rehearsal import rehearse

ROOT = Path(__file__).resolve().parents[2]
TREE = ROOT / "trees" / "patrol.yaml"
SCENARIO = ROOT / "sitl" / "scenarios" / "patrol.yaml"
CLI = [sys.executable, "-m", "chaser_bt.cli"]

pytestmark = pytest.mark.slow

# Scores that depend only on the simulation, not on how fast this machine ran it.
DETERMINISTIC_KEYS = ("outcome", "sim_time_s", "ticks", "landed_dist_m", "max_alt_m", "distance_flown_m", "battery_used_pct", "message")


def test_patrol_rehearsal_flies_the_square_and_lands_home():
    report = rehearse(TREE, SCENARIO, seed=1)
    assert report.outcome == "landed", report.message
    assert report.landed_dist_m < 3.0
    assert report.max_alt_m == pytest.approx(20.0, abs=2.0)
    # Out and back along a 100 m square: 400 m of legs, plus whatever RTL adds.
    assert 390 < report.distance_flown_m < 480


def test_patrol_rehearsal_is_reproducible_for_a_seed():
    first = rehearse(TREE, SCENARIO, seed=4).to_dict()
    second = rehearse(TREE, SCENARIO, seed=4).to_dict()
    assert {k: first[k] for k in DETERMINISTIC_KEYS} == {k: second[k] for k in DETERMINISTIC_KEYS}


def test_different_seeds_fly_different_gusts():
    a = rehearse(TREE, SCENARIO, seed=1).to_dict()
    b = rehearse(TREE, SCENARIO, seed=2).to_dict()
    assert a["outcome"] == b["outcome"] == "landed"
    assert (a["distance_flown_m"], a["battery_used_pct"]) != (b["distance_flown_m"], b["battery_used_pct"])


def test_link_loss_mid_mission_ends_in_the_autopilots_failsafe(tmp_path):
    scenario = yaml.safe_load(SCENARIO.read_text())
    scenario["faults"] = [{"at_s": 75.0, "kind": "link_loss"}]  # for good: the GCS never returns
    path = tmp_path / "link_loss.yaml"
    path.write_text(yaml.safe_dump(scenario))
    report = rehearse(TREE, path, seed=1)
    assert report.outcome == "failsafe", report.message
    assert "no messages" in report.message.lower() or "quiet" in report.message.lower()
    assert report.landed_dist_m < 5.0  # GCS failsafe -> RTL brings it home


def test_cli_rehearse_prints_the_json_report():
    out = subprocess.run(
        [*CLI, "rehearse", str(TREE), "--scenario", str(SCENARIO), "--seed", "1", "--json"],
        capture_output=True, text=True, timeout=300, check=True,
    )
    report = json.loads(out.stdout)
    assert report["outcome"] == "landed"
    for key in ("sim_time_s", "wall_time_s", "landed_dist_m"):
        assert key in report


@pytest.mark.parametrize("signed", [False, True], ids=["unsigned", "signed"])
def test_run_flies_the_simulator_over_tcp_to_a_landing(signed, tmp_path):
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    signing = []
    if signed:  # both ends share a MAVLink 2 signing key; the simulator obeys only signed commands
        (tmp_path / "key").write_text("correct horse battery staple\n")
        signing = ["--signing-key", str(tmp_path / "key")]
    # 10x, not more: the vehicle's GCS failsafe counts its own seconds, so at 25x a mission process the
    # shared machine starves for 0.2 s of wall time looks to the vehicle like a lost ground station.
    sim = subprocess.Popen(
        [*CLI, "sitl", "--scenario", str(SCENARIO), "--speedup", "10", "--tcp-port", "0", "--udp-port", "0", *signing],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
    )
    try:
        url = None
        for line in sim.stdout:
            match = re.search(r"(tcp:127\.0\.0\.1:\d+)", line)
            if match:
                url = match.group(1)
                break
        assert url, "the simulator printed no tcp connection string"
        run = subprocess.run([*CLI, "run", str(TREE), "--connect", url, *signing], capture_output=True, text=True, timeout=240)
        assert run.returncode == 0, run.stdout + run.stderr
        assert run.stdout.splitlines()[-1].startswith("completed: return and land: landed and disarmed")
    finally:
        sim.terminate()
        sim.wait(timeout=10)


@pytest.mark.parametrize("tree", ["patrol.yaml", "patrol.xml"])
def test_a_patrol_whose_take_off_fails_fails_and_never_reports_success(tree):
    """The false success seen against ArduCopter: the square failed on the ground, the fallback
    swallowed it, and RTL on the disarmed vehicle said "landed and disarmed". Here the vehicle has
    its position but its pre-arm checks never pass, so the arm fails."""
    import dataclasses

    from chaser_bt.vehicle import LinkConfig
    from sitl.vehicle.setup import BootParams
    from sitl.world.scenario import load_scenario

    never_ready = dataclasses.replace(load_scenario(SCENARIO), boot=BootParams(5.0, 25.0, 1e9))
    report = rehearse(ROOT / "trees" / tree, never_ready, seed=1,
                      link_config=LinkConfig(target_sysid=1, ready_timeout_s=30.0))  # 1: the simulator's SYSID_THISMAV
    # The root failed (the bench's "error"); the cause named is the take-off's, not the fallback's
    # "in the air?" that answered after it.
    assert report.outcome == "error" and report.max_alt_m < 1.0 and report.mission_outcome == "failed"
    assert report.message.startswith("ArmAndTakeoff: arming failed"), report.message


def test_a_patrol_cut_short_by_the_battery_still_flies_home(tmp_path):
    """What the fallback is there for: the battery guard halts the square and RTL lands at home."""
    scenario = yaml.safe_load(SCENARIO.read_text())
    scenario["params"] = {"BATT_CAPACITY": 700}  # 30 % left after 490 mAh, part-way round the square
    path = tmp_path / "small_battery.yaml"
    path.write_text(yaml.safe_dump(scenario))
    report = rehearse(TREE, path, seed=1)
    assert report.outcome == "landed", report.message
    assert report.landed_dist_m < 3.0 and report.distance_flown_m < 390  # the square was cut short


def test_run_says_crashed_and_exits_6_when_the_aircraft_is_disarmed_in_the_air(tmp_path):
    """A second ground station force-disarms the aircraft on the first leg: never "success", never "landed"."""
    scenario = yaml.safe_load(SCENARIO.read_text())
    scenario["faults"] = [{"at_s": 62.0, "kind": "disarm"}]
    path = tmp_path / "disarm.yaml"
    path.write_text(yaml.safe_dump(scenario))
    sim = subprocess.Popen([*CLI, "sitl", "--scenario", str(path), "--speedup", "10", "--tcp-port", "0", "--udp-port", "0"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    try:
        url = next((m.group(1) for line in sim.stdout if (m := re.search(r"(tcp:127\.0\.0\.1:\d+)", line))), None)
        assert url, "the simulator printed no tcp connection string"
        run = subprocess.run([*CLI, "run", str(TREE), "--connect", url], capture_output=True, text=True, timeout=240)
        assert run.returncode == 6, run.stdout + run.stderr
        assert run.stdout.splitlines()[-1].startswith("crashed: disarmed in the air at"), run.stdout
    finally:
        sim.terminate()
        sim.wait(timeout=10)


def test_run_with_require_failsafes_refuses_a_vehicle_without_a_fence():
    sim = subprocess.Popen([*CLI, "sitl", "--scenario", str(SCENARIO), "--speedup", "10", "--tcp-port", "0", "--udp-port", "0"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    try:
        url = next((m.group(1) for line in sim.stdout if (m := re.search(r"(tcp:127\.0\.0\.1:\d+)", line))), None)
        assert url, "the simulator printed no tcp connection string"
        run = subprocess.run([*CLI, "run", str(TREE), "--connect", url, "--require-failsafes"], capture_output=True, text=True, timeout=60)
        assert run.returncode == 2, run.stdout + run.stderr
        assert "warning: FENCE_ENABLE = 0: no geofence" in run.stderr and "--require-failsafes" in run.stderr
        assert "flying" not in run.stdout  # refused before the first tick
    finally:
        sim.terminate()
        sim.wait(timeout=10)
