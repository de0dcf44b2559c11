"""``chaser-bt calibrate FILE`` on a simulated, recorded calibration flight (appendix A)."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest

from chaser_bt.radar.commands import add_command
from chaser_bt.radar.recording import write_recording
from sitl.bench.radar_trials import (
    calibration_test_flight,
    handheld_guess,
    to_recording,
)


def cli(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="chaser-bt")
    add_command(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    return args.handler(args)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    flight = calibration_test_flight(seed=4, duration_s=120.0)
    path = tmp_path_factory.mktemp("cal") / "flight.jsonl"
    write_recording(path, to_recording(flight, handheld_guess(flight, 4)))
    return flight, path


def test_calibrate_prints_a_pose_near_the_truth(recorded, capsys):
    flight, path = recorded
    assert cli(["calibrate", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    truth = flight.true_pose
    from chaser_bt.geo import GeoPoint

    err = flight.frame.point_to_enu(GeoPoint(out["lat_deg"], out["lon_deg"], out["alt_m"])) - truth.position_enu
    assert np.linalg.norm(err) < 5.0
    assert abs(out["yaw_deg"] - math.degrees(truth.yaw_pitch_roll[0])) < 1.5
    assert max(out["residual_std_enu_m"]) < 3.0


def test_calibrate_human_output_and_the_paper_method(recorded, capsys):
    _, path = recorded
    assert cli(["calibrate", str(path), "--method", "longest"]) == 0
    text = capsys.readouterr().out
    assert "longest-track" in text and "residual 1-sigma" in text


def test_bad_file_is_exit_2_naming_file_and_line(tmp_path, capsys):
    p = tmp_path / "bad.jsonl"
    p.write_text('{"type": "header", "format": "chaser-bt/radar-calibration", "version": 1, '
                 '"radar_guess": {"lat_deg": 1, "lon_deg": 2, "alt_m": 3, "yaw_deg": 0, "pitch_deg": 0, "roll_deg": 0}}\n'
                 '{"type": "gps", "t": 1.0, "lat_deg": "x"}\n')
    assert cli(["calibrate", str(p)]) == 2
    assert f"{p}:2: lat_deg" in capsys.readouterr().err
    assert cli(["calibrate", str(tmp_path / "missing.jsonl")]) == 2
