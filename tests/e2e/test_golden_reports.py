"""Golden rehearsal reports: a patrol and a 60 s camera-on chase, recorded once, must not change.

They pin the simulator and the bench to their behaviour when the reports were recorded (before
``sitl/`` was split into the simulator and the bench), so a refactor that moves code cannot move
a figure. Keys that time this machine (wall time, real-time factor, tick and sensor set-up wall
times) are left out; every other key must match byte for byte in the JSON. A deliberate change of
behaviour records new goldens: ``CHASER_BT_RECORD_GOLDEN=1 pytest tests/e2e/test_golden_reports.py``.

The camera-on chase is pinned to the machine's vector instructions as well as to the code: the
detector's float and int8 kernels in onnxruntime and OpenCV's warps round differently with AVX2 than
with AVX-512 VNNI, and a chase is chaotic enough that a changed detection moves the flight. So it has
one golden per instruction set it was recorded on (``chase60_seed1.<isa>.json``, :func:`cpu_isa`);
on a machine of another kind it skips and says so. Recording on one kind cannot renew the others: a
deliberate change of the chase removes the goldens it could not record.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import pytest

from sitl.bench.rehearsal import rehearse
from sitl.bench.sensors import SensorOptions
from sitl.world.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).with_name("golden")
WALL_CLOCK_KEYS = ("wall_time_s", "realtime_factor", "tick_ms_median", "sensors_wall_s")

pytestmark = pytest.mark.slow


def _report_text(tree: str, scenario: str, seed: int, time_limit_s: float | None = None,
                 sensors: SensorOptions | None = None) -> str:
    sc = load_scenario(ROOT / scenario)
    if time_limit_s is not None:
        sc = dataclasses.replace(sc, time_limit_s=time_limit_s)
    report = rehearse(ROOT / tree, sc, seed=seed, sensors=sensors).to_dict()
    kept = {k: v for k, v in report.items() if k not in WALL_CLOCK_KEYS}
    return json.dumps(kept, indent=1, sort_keys=True) + "\n"


def cpu_isa() -> str:
    """The vector instructions the detector's kernels take their rounding from: ``avx512-vnni``, ``avx2`` or ``other``."""
    try:
        flags = next((line.split(":", 1)[1].split() for line in Path("/proc/cpuinfo").read_text().splitlines()
                      if line.startswith("flags")), [])
    except OSError:
        flags = []
    if "avx512_vnni" in flags:
        return "avx512-vnni"
    return "avx2" if "avx2" in flags else "other"


MACHINE_PINNED = {"chase60_seed1"}  # camera-on: one golden per instruction set

CASES = {
    "patrol_seed1": ("trees/patrol.yaml", "sitl/scenarios/patrol.yaml", 1, None),
    "chase60_seed1": ("trees/chase.yaml", "sitl/scenarios/chase.yaml", 1, 60.0),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_rehearsal_report_matches_its_golden_byte_for_byte(name):
    path = GOLDEN / (f"{name}.{cpu_isa()}.json" if name in MACHINE_PINNED else f"{name}.json")
    recording = os.environ.get("CHASER_BT_RECORD_GOLDEN") == "1"
    if not recording and not path.exists():
        pytest.skip(f"{name}: no golden recorded for this machine's instruction set ({cpu_isa()}); "
                    f"record one with CHASER_BT_RECORD_GOLDEN=1")
    text = _report_text(*CASES[name])
    if recording:
        path.write_text(text)
    assert text == path.read_text(), f"{name}: the rehearsal report changed; see the module docstring"


def test_the_chase_drawn_in_a_render_process_flies_the_in_process_golden():
    """`chaser-bt rehearse` draws the camera in a process beside the tick; the flight must not notice."""
    path = GOLDEN / f"chase60_seed1.{cpu_isa()}.json"
    if not path.exists():
        pytest.skip(f"no chase golden recorded for this machine's instruction set ({cpu_isa()})")
    text = _report_text(*CASES["chase60_seed1"], sensors=SensorOptions(render_process=True))
    assert text == path.read_text(), "the chase drawn in a render process differs from the one drawn in-process"
