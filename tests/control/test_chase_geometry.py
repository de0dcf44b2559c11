"""The chase-geometry analysis: the paper's choice, hand-checked formulas, brute-force dashes, the CLI."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math

import numpy as np
import pytest

from chaser_bt.control.chase_geometry import (
    ChaseInputs, pixels_on_target, recommend, time_to_horizon, time_to_leave_vertical_fov,
)
from chaser_bt.control.commands import add_command

PAPER = ChaseInputs()


def test_paper_inputs_give_the_papers_choice_40_m_40_deg():
    rec = recommend(PAPER)
    assert rec.slant_range_m == 40.0
    assert math.degrees(rec.elevation_rad) == pytest.approx(40.0)
    assert rec.ground_range_m == pytest.approx(30.6, abs=0.05) and rec.rel_height_m == pytest.approx(25.7, abs=0.05)


def test_pixels_hand_computed_at_40_m_40_deg():
    fx = 960 / math.tan(math.radians(47.5))  # 879.8 px
    fy = 540 / math.tan(math.radians(36.5))  # 730.0 px
    w = 0.49 * fx / 40
    h = (0.2 * math.cos(math.radians(40)) + 0.49 * math.sin(math.radians(40))) * fy / 40
    assert pixels_on_target(PAPER, 40.0, math.radians(40)) == pytest.approx(math.sqrt(w * h))
    assert math.sqrt(w * h) == pytest.approx(9.59, abs=0.01)


def test_time_to_horizon_is_height_over_climb_speed():
    assert time_to_horizon(PAPER, 40.0, math.radians(40)) == pytest.approx(40 * math.sin(math.radians(40)) / 6.0)


@pytest.mark.parametrize("el_deg", [10, 25, 40, 50, 60, 75])
def test_dash_time_matches_brute_force(el_deg):
    """March the target towards and away from the chaser until it leaves the vertical FOV."""
    el, a, r = math.radians(el_deg), math.radians(36.5), 40.0
    g0, h = r * math.cos(el), r * math.sin(el)
    times = []
    for sign in (-1.0, 1.0):  # towards, away
        t, dt = 0.0, 1e-4
        while t < 100.0:
            g = g0 + sign * 20.0 * t
            depression = math.atan2(h, g)
            if not el - a <= depression <= el + a:
                break
            t += dt
        times.append(t)
    assert time_to_leave_vertical_fov(PAPER, r, el) == pytest.approx(min(times), abs=2e-3)


def test_more_pixels_needed_means_closer():
    rec = recommend(dataclasses.replace(PAPER, min_pixels=10.0))
    assert rec.slant_range_m == 35.0 and math.degrees(rec.elevation_rad) == pytest.approx(40.0)


@pytest.mark.parametrize("vfov_deg, min_px, speed_up", [(56.0, 9.0, 6.0), (73.0, 6.0, 2.0), (40.0, 12.0, 6.0)])
def test_recommendation_is_the_best_feasible_grid_point(vfov_deg, min_px, speed_up):
    inputs = dataclasses.replace(PAPER, vfov_rad=math.radians(vfov_deg), min_pixels=min_px, speed_up_mps=speed_up)
    a = math.radians(vfov_deg) / 2
    best = None
    for r in inputs.ranges_m:  # a plain loop over the grid, scalar by scalar
        for el in inputs.elevations_rad:
            if pixels_on_target(inputs, r, el) < min_px - 1e-9 or el < a - 1e-9 or el + a > math.pi / 2 + 1e-9:
                continue
            score = min(float(time_to_horizon(inputs, r, el)), float(time_to_leave_vertical_fov(inputs, r, el)))
            if best is None or score > best[0]:
                best = (score, r, el)
    rec = recommend(inputs)
    assert (rec.slant_range_m, rec.elevation_rad) == (best[1], best[2])
    assert rec.elevation_rad >= a - 1e-9  # the horizon stays out of the frame


def test_no_feasible_position_is_an_error():
    with pytest.raises(ValueError, match="min_pixels"):
        recommend(dataclasses.replace(PAPER, min_pixels=500.0))


def _cli(argv):
    p = argparse.ArgumentParser()
    add_command(p.add_subparsers())
    args = p.parse_args(["chase-geometry", *argv])
    return args.handler(args)


def test_cli_prints_the_recommendation_and_plots(capsys, tmp_path):
    png = tmp_path / "fig.png"
    assert _cli(["--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["slant_range_m"] == 40.0 and out["elevation_deg"] == pytest.approx(40.0)
    assert png.stat().st_size > 10_000


def test_cli_bad_input_exits_2_naming_the_option(capsys):
    assert _cli(["--vfov-deg", "200"]) == 2
    assert "--vfov-deg" in capsys.readouterr().err
