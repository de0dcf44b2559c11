"""`chaser-bt run` against ArduPilot's own ArduCopter SITL (the real autopilot), when it is here.

The binary is looked for at ``../shared/ardupilot`` beside the repository (CI has it) or at
``$CHASER_BT_ARDUPILOT``; elsewhere these tests skip and say why. Kept short: one patrol at 10x
(about 15 s of wall time), started right after the SITL boots, the way a new user tries it.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-m", "chaser_bt.cli"]
INSTANCE = int(os.environ.get("CHASER_BT_ARDUPILOT_INSTANCE", "7"))  # ports 5760 + 10 * INSTANCE

pytestmark = pytest.mark.slow


def _ardupilot_dir() -> Path:
    where = Path(os.environ.get("CHASER_BT_ARDUPILOT", ROOT.parent / "shared" / "ardupilot"))
    if not (where / "arducopter").is_file() or not (where / "start_sitl.sh").is_file():
        pytest.skip(f"no ArduCopter SITL at {where} (set CHASER_BT_ARDUPILOT to its folder)")
    return where


@pytest.fixture
def arducopter(tmp_path):
    """A fresh ArduCopter SITL at 10x with the GCS failsafe on (FS_GCS_ENABLE 1: RTL, or disarm on
    the ground); yields its connection string and stops it by its recorded pid."""
    where = _ardupilot_dir()
    (tmp_path / "fs_gcs.parm").write_text("FS_GCS_ENABLE 1\n")
    env = dict(os.environ, SITL_RUN_DIR=str(tmp_path / "run"), SITL_DEFAULTS=str(tmp_path / "fs_gcs.parm"))
    started = subprocess.run([str(where / "start_sitl.sh"), str(INSTANCE), "10"], capture_output=True, text=True,
                             env=env, timeout=90)
    pid_file = tmp_path / "run" / f"I{INSTANCE}" / "sitl.pid"
    try:
        assert started.returncode == 0, started.stdout + started.stderr
        url = started.stdout.strip().splitlines()[-1]
        assert re.fullmatch(r"tcp:127\.0\.0\.1:\d+", url), url
        yield url
    finally:
        if pid_file.exists():
            pid = int(pid_file.read_text().strip())
            try:
                os.kill(pid, 15)
            except ProcessLookupError:
                pass


def test_patrol_right_after_boot_arms_flies_and_lands_with_the_gcs_failsafe_on(arducopter):
    """Today's defects, on the real autopilot: the first tick waits for SYS_STATUS and home (no
    "battery unknown" false success), and heartbeats keep to vehicle time (no GCS failsafe at 10x)."""
    run = subprocess.run([*CLI, "-v", "run", str(ROOT / "trees" / "patrol.yaml"), "--connect", arducopter],
                         capture_output=True, text=True, timeout=240)
    out = run.stdout + run.stderr
    assert run.returncode == 0, out
    assert "Arming motors" in out and "GCS Failsafe" not in out, out
    ticks = int(re.search(r"completed: .* after (\d+) ticks", out).group(1))
    assert ticks > 1000  # a 100 m square at 10 Hz, not the 2-tick "success" on a disarmed vehicle
