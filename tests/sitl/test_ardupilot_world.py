"""ArduCopter SITL inside our world (``rehearse --autopilot ardupilot``).

The unit tests need no binary. The slow ones fly ArduPilot's own ArduCopter (``../shared/ardupilot``
beside the repository, or ``$CHASER_BT_ARDUPILOT``) on our S1000 rotor body and skip, saying so,
where it is absent. Kept short: a patrol (about 50 s of wall time) and a 40 s chase with the radar and
the camera.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sitl.ardupilot.process import ARDUPILOT_ENV, ArduPilotMissing, find_ardupilot
from sitl.ardupilot.simulator import ReportedAutopilot, pilot_rc
from sitl.vehicle.setup import PilotEvent, PilotScript

ROOT = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-m", "chaser_bt.cli"]


# -- no binary needed ------------------------------------------------------------------------------

def test_find_ardupilot_names_the_folder_and_the_missing_file(tmp_path, monkeypatch):
    monkeypatch.delenv(ARDUPILOT_ENV, raising=False)
    with pytest.raises(ArduPilotMissing, match=f"no ArduCopter SITL at {tmp_path}: arducopter is missing"):
        find_ardupilot(tmp_path)
    (tmp_path / "arducopter").write_bytes(b"")
    with pytest.raises(ArduPilotMissing, match="copter.parm is missing"):
        find_ardupilot(tmp_path)
    (tmp_path / "copter.parm").write_text("")
    assert find_ardupilot(tmp_path) == tmp_path
    monkeypatch.setenv(ARDUPILOT_ENV, str(tmp_path))  # the environment, when no folder is given
    assert find_ardupilot() == tmp_path


def test_armed_is_read_from_the_motor_outputs():
    """Disarmed ArduCopter holds every motor at its minimum (1000 us); armed, they idle at MOT_SPIN_ARM."""
    ap = ReportedAutopilot(motor_pwm=(1000,) * 8)
    assert not ap.armed
    ap.motor_pwm = (1000,) * 7 + (1112,)
    assert ap.armed
    assert not ReportedAutopilot().armed  # before the first frame


def test_the_pilot_holds_the_throttle_down_on_the_ground_and_centred_in_the_air():
    pilot = PilotScript(gate_channel=7, gate=False, on_pwm=1900, off_pwm=1100, events=(PilotEvent(10.0, True),))
    ground = pilot_rc(pilot, 5.0, airborne=False)
    assert len(ground) == 16
    assert ground[2] == 1000 and ground[6] == 1100  # throttle down, switch off before its event
    air = pilot_rc(pilot, 12.0, airborne=True)
    assert air[2] == 1500 and air[6] == 1900  # throttle centred, switch on after it
    assert air[:2] == (1500, 1500) and air[3] == 1500  # the other sticks centred
    nobody = pilot_rc(None, 12.0, airborne=True)
    assert nobody[:8] == (1500, 1500, 1000, 1500, 1800, 1000, 1000, 1800)  # SITL's own defaults


def test_rehearse_without_the_binary_says_where_it_looked(tmp_path):
    run = subprocess.run([*CLI, "rehearse", str(ROOT / "trees" / "patrol.yaml"), "--scenario",
                          str(ROOT / "sitl" / "scenarios" / "patrol.yaml"), "--autopilot", "ardupilot",
                          "--ardupilot", str(tmp_path), "--progress", "never"],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert run.returncode == 1
    assert f"chaser-bt: rehearse: no ArduCopter SITL at {tmp_path}: arducopter is missing" in run.stderr
    assert "Traceback" not in run.stderr


def test_rehearse_with_an_arducopter_that_cannot_run_says_so(tmp_path):
    (tmp_path / "arducopter").write_bytes(bytes(range(256)))  # executable, but no program
    (tmp_path / "arducopter").chmod(0o755)
    (tmp_path / "copter.parm").write_text("FRAME_CLASS 1\n")
    run = subprocess.run([*CLI, "rehearse", str(ROOT / "trees" / "patrol.yaml"), "--scenario",
                          str(ROOT / "sitl" / "scenarios" / "patrol.yaml"), "--autopilot", "ardupilot",
                          "--ardupilot", str(tmp_path), "--progress", "never"],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert run.returncode == 1 and "Traceback" not in run.stderr, run.stderr
    assert f"{tmp_path / 'arducopter'} cannot be run: Exec format error" in run.stderr


# -- the real ArduCopter ---------------------------------------------------------------------------

def _ardupilot() -> Path:
    try:
        return find_ardupilot()
    except ArduPilotMissing as exc:
        pytest.skip(f"{exc}")


@pytest.mark.slow
def test_arducopter_flies_the_patrol_in_our_world_and_lands_at_home():
    """The patrol tree, unchanged, on real ArduCopter flying our S1000: armed, four 100 m legs, home."""
    _ardupilot()
    run = subprocess.run([*CLI, "rehearse", str(ROOT / "trees" / "patrol.yaml"), "--scenario",
                          str(ROOT / "sitl" / "scenarios" / "patrol.yaml"), "--autopilot", "ardupilot", "--json",
                          "--progress", "never"], capture_output=True, text=True, timeout=400, cwd=ROOT)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-3000:]
    report = json.loads(run.stdout)
    assert report["outcome"] == "landed", report
    assert report["landed_dist_m"] < 1.0  # ArduCopter's RTL lands where it took off
    assert 19.0 < report["max_alt_m"] < 22.0  # the patrol's 20 m
    assert 380.0 < report["distance_flown_m"] < 460.0  # a 100 m square plus the corners
    assert report["sim_time_s"] < 200.0  # the world's clock starts once ArduCopter is ready, not at its boot


@pytest.mark.slow
def test_arducopter_chase_sees_the_radar_validate_and_takes_off_on_the_cue():
    """The chase's front half on real ArduCopter: the radar (seeing our rotor body) validates the
    intruder's track, the tree launches, ArduCopter climbs to the take-off altitude and the radar
    keeps associating the ownship's track."""
    _ardupilot()
    from sitl.bench.rehearsal import AutopilotChoice, rehearse
    from sitl.world.scenario import load_scenario

    scenario = dataclasses.replace(load_scenario(ROOT / "sitl" / "scenarios" / "chase.yaml"), time_limit_s=40.0)
    report = rehearse(ROOT / "trees" / "chase.yaml", scenario, 1, autopilot=AutopilotChoice("ardupilot"))
    assert report.outcome in ("timeout", "following"), report.message
    assert report.t_airborne_s is not None and report.t_airborne_s < 30.0, report
    assert report.max_alt_m > 15.0
    assert report.radar_assoc_frac is not None and report.radar_assoc_frac > 0.8, report
    assert set(report.sensors) == {"camera", "radar", "target_telemetry"}


@pytest.mark.slow
def test_two_arducopters_at_once_take_different_instances():
    """Campaign workers each claim their own ports (the physics port is bound first)."""
    _ardupilot()
    from sitl.ardupilot.simulator import ArduPilotSimulator
    from sitl.world.scenario import load_scenario

    scenario = load_scenario(ROOT / "sitl" / "scenarios" / "patrol.yaml")
    first = ArduPilotSimulator(scenario, 1)
    try:
        second = ArduPilotSimulator(scenario, 2)
        try:
            assert first.process.instance != second.process.instance
            assert first.url != second.url
            for sim in (first, second):  # both answer their own ArduCopter's frames
                sim.step()
                assert sim.physics_time_s == pytest.approx(0.02, abs=0.002)
        finally:
            second.close()
    finally:
        first.close()
    assert not os.path.exists(first.process.workdir)  # the working folder goes with it


@pytest.mark.slow
def test_arducopter_estimate_agrees_with_our_truth_while_it_turns_and_flies():
    """Our frames and ArduPilot's agree: flying a velocity with a yaw rate, ArduCopter's own EKF
    attitude and position (over MAVLink) match the rotor body's truth (what the camera renders from)."""
    _ardupilot()
    from sitl.bench.ardupilot_vehicle import ArduPilotVehicle
    from sitl.world.scenario import load_scenario

    vehicle = ArduPilotVehicle(load_scenario(ROOT / "sitl" / "scenarios" / "patrol.yaml"), 1)
    try:
        link = vehicle.link
        link.set_mode("GUIDED")
        assert vehicle.run_until(lambda: link.state.mode == "GUIDED", 5.0)
        link.arm()
        assert vehicle.run_until(lambda: link.state.armed, 5.0)
        vehicle.run_until(lambda: False, 2.5)  # ArduCopter's arming delay
        link.takeoff(15.0)
        assert vehicle.run_until(lambda: link.state.alt_rel_m > 14.0, 40.0)
        yaw0 = vehicle.sim.truth.euler_ned[2]
        worst_deg, worst_m = 0.0, 0.0
        for k in range(300):  # 6 s at 4 m/s east, 2 m/s north, turning 0.3 rad/s counter-clockwise
            if k % 25 == 0:
                link.velocity_enu((4.0, 2.0, 0.0), yaw_rate=0.3)
            vehicle.step()
            if k > 25 and k % 10 == 0:
                truth = vehicle.sim.truth
                worst_deg = max(worst_deg, float(np.degrees((truth.attitude.inv() * link.state.attitude).magnitude())))
                worst_m = max(worst_m, float(np.linalg.norm(truth.pos_enu - link.state.position_enu)))
        turned = (vehicle.sim.truth.euler_ned[2] - yaw0 + np.pi) % (2 * np.pi) - np.pi
    finally:
        vehicle.close()
    assert worst_deg < 3.0 and worst_m < 1.0, (worst_deg, worst_m)  # telemetry is 10 Hz: a little behind
    assert -1.9 < turned < -1.3  # NED yaw falls as it turns counter-clockwise: about 0.3 rad/s for 5.5 s


@pytest.mark.slow
def test_arducopter_dies_with_the_process_that_started_it(tmp_path):
    """A campaign worker ended at once (SIGKILL) leaves no ArduCopter behind waiting for physics."""
    _ardupilot()
    script = tmp_path / "start.py"
    script.write_text(
        "import sys, time\n"
        "from sitl.ardupilot.simulator import ArduPilotSimulator\n"
        "from sitl.world.scenario import load_scenario\n"
        f"sim = ArduPilotSimulator(load_scenario({str(ROOT / 'sitl' / 'scenarios' / 'patrol.yaml')!r}), 1)\n"
        "print(sim.process.proc.pid, flush=True)\n"
        "time.sleep(60)\n")
    starter = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        pid = int(starter.stdout.readline())
        assert Path(f"/proc/{pid}").exists()
    finally:
        starter.kill()
        starter.wait()
    for _ in range(50):
        if not Path(f"/proc/{pid}").exists() or "Z" in Path(f"/proc/{pid}/stat").read_text().split()[2]:
            break
        time.sleep(0.1)
    else:
        os.kill(pid, 9)
        pytest.fail("arducopter outlived the process that started it")


def test_the_command_line_offers_exactly_the_rotor_airframes():
    """cli_args cannot import the simulator, so it names the airframes itself: they must stay the same."""
    from chaser_bt.cli_args import AIRFRAMES as CLI_AIRFRAMES
    from sitl.vehicle.rotor_body import AIRFRAMES

    assert set(CLI_AIRFRAMES) == set(AIRFRAMES)


def test_the_command_line_offers_exactly_the_camera_mounts():
    """cli_args does not import the camera model either, so it names the mounts itself."""
    from chaser_bt.cli_args import CAMERA_MOUNTS
    from chaser_bt.vision.camera import MOUNTS

    assert CAMERA_MOUNTS == MOUNTS


def test_renamed_parameters_are_written_under_both_names_in_each_unit():
    from sitl.ardupilot.process import with_renamed

    out = with_renamed({"WPNAV_SPEED_UP": 500.0, "RTL_ALT": 1500.0, "FS_GCS_ENABLE": 1.0})
    assert out == {"WPNAV_SPEED_UP": 500.0, "RTL_ALT": 1500.0, "FS_GCS_ENABLE": 1.0,
                   "WP_SPD_UP": 5.0, "RTL_ALT_M": 15.0}
    assert with_renamed({"WPNAV_SPEED_UP": 500.0, "WP_SPD_UP": 3.0})["WP_SPD_UP"] == 3.0  # a new name given wins


@pytest.mark.slow
def test_the_scenarios_climb_limits_reach_arducopter_under_whichever_name_it_knows():
    """chase.yaml sets WPNAV_SPEED_UP 500 (cm/s); ArduCopter 4.7+ calls it WP_SPD_UP (m/s). Read back."""
    _ardupilot()
    from sitl.bench.ardupilot_vehicle import ArduPilotVehicle
    from sitl.world.scenario import load_scenario

    vehicle = ArduPilotVehicle(load_scenario(ROOT / "sitl" / "scenarios" / "chase.yaml"), 1)
    try:
        commands = [vehicle.link.request_param(name) for name in ("WPNAV_SPEED_UP", "WP_SPD_UP")]
        vehicle.run_until(lambda: any(c.done and c.ok for c in commands), 30.0)
        params = vehicle.link.params
        assert params.get("WP_SPD_UP") == pytest.approx(5.0) or params.get("WPNAV_SPEED_UP") == pytest.approx(500.0), params
    finally:
        vehicle.close()
