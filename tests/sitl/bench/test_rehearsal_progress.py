"""The rehearsal's progress bar: simulated time, phase and real-time factor."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from sitl.bench.rehearsal_progress import RehearsalProgress

ROOT = Path(__file__).resolve().parents[3]


def test_the_bar_follows_simulated_time_and_names_the_phase():
    out = io.StringIO()
    bar = RehearsalProgress(300.0, out, always=True, min_interval_s=0.0)
    bar(12.5, "launch")
    bar(40.0, "follow")
    assert bar.bar.n == pytest.approx(40.0)
    bar(400.0, "follow")  # past the limit (a run ends on the tick after it): the bar stops at the total
    assert bar.bar.n == pytest.approx(300.0)
    bar.close()
    text = out.getvalue()
    assert "launch" in text and "follow" in text and "300/300 sim s" in text and "x real time" in text


def test_the_bar_is_off_when_not_on_a_terminal_unless_asked():
    out = io.StringIO()  # not a terminal
    bar = RehearsalProgress(100.0, out)
    bar(50.0, "follow")
    bar.close()
    assert out.getvalue() == ""


@pytest.mark.slow
def test_rehearse_shows_progress_while_it_flies(capsys):
    from chaser_bt.cli import main

    assert main(["rehearse", str(ROOT / "trees/patrol.yaml"), "--scenario", str(ROOT / "sitl/scenarios/patrol.yaml"),
                 "--no-camera", "--progress", "always"]) == 0
    err = capsys.readouterr().err
    assert "sim s" in err and "x real time" in err
