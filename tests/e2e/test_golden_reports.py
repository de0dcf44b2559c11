"""Golden rehearsal reports: a patrol and a 60 s camera-on chase, recorded once, must not change.

They pin the simulator and the bench to their behaviour when the reports were recorded (before
``sitl/`` was split into the simulator and the bench), so a refactor that moves code cannot move
a figure. Keys that time this machine (wall time, real-time factor, tick and sensor set-up wall
times) are left out; every other key must match byte for byte in the JSON. A deliberate change of
behaviour records new goldens: ``CHASER_BT_RECORD_GOLDEN=1 pytest tests/e2e/test_golden_reports.py``.

The camera-on chase is pinned to the machine as well as to the code: the detector's float (and int8)
kernels in onnxruntime and OpenCV's warps round differently on different CPUs, and a chase is chaotic
enough that a changed detection moves the flight. Its golden was last recorded on an AVX-512 (VNNI)
x86 machine, after the rendered camera started reading out regions of interest and the detector ran
its int8 copy; the base commit before those changes no longer reproduced the previous one there either.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import pytest

from sitl.bench.rehearsal import rehearse
from sitl.world.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).with_name("golden")
WALL_CLOCK_KEYS = ("wall_time_s", "realtime_factor", "tick_ms_median", "sensors_wall_s")

pytestmark = pytest.mark.slow


def _report_text(tree: str, scenario: str, seed: int, time_limit_s: float | None = None) -> str:
    sc = load_scenario(ROOT / scenario)
    if time_limit_s is not None:
        sc = dataclasses.replace(sc, time_limit_s=time_limit_s)
    report = rehearse(ROOT / tree, sc, seed=seed).to_dict()
    kept = {k: v for k, v in report.items() if k not in WALL_CLOCK_KEYS}
    return json.dumps(kept, indent=1, sort_keys=True) + "\n"


CASES = {
    "patrol_seed1": ("trees/patrol.yaml", "sitl/scenarios/patrol.yaml", 1, None),
    "chase60_seed1": ("trees/chase.yaml", "sitl/scenarios/chase.yaml", 1, 60.0),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_rehearsal_report_matches_its_golden_byte_for_byte(name):
    text = _report_text(*CASES[name])
    path = GOLDEN / f"{name}.json"
    if os.environ.get("CHASER_BT_RECORD_GOLDEN") == "1":
        path.write_text(text)
    assert text == path.read_text(), f"{name}: the rehearsal report changed; see the module docstring"
