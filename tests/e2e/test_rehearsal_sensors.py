"""Rehearsals with every sensor: the mission gets radar, target telemetry and the rendered camera the
way a real flight does (never the truth), and the report carries the DESIGN §7 scores."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import py_trees
import pytest
import yaml

from chaser_bt.radar.feed import RadarFeed
from chaser_bt.target_telemetry import TargetTelemetry
from chaser_bt.vision.pipeline import CameraSensor
from sitl.bench.in_process import InProcessVehicle
from sitl.bench.rehearsal import rehearse
from sitl.bench.sensors import (
    SURVEY_SIGMA,
    ScenarioFrameSource,
    SensorOptions,
    build_sensors,
    calibrated_radar_pose,
    surveyed_radar_pose,
)
from sitl.world.scenario import OnboardCamera, Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[2]
CHASE = ROOT / "sitl" / "scenarios" / "chase.yaml"
PATROL = ROOT / "sitl" / "scenarios" / "patrol.yaml"

# Wait for a validated radar track, take off, then fly toward the radar cue (FollowGlobal on the cue
# at a stand-off) while the intruder's telemetry is read.
MINI_CHASE = """
version: 1
main: MiniChase
trees:
  MiniChase:
    Sequence:
      name: mini chase
      children:
        - RetryUntilSuccessful:
            name: wait for a validated track
            num_attempts: -1
            child: {RadarTrackValidated: {min_confidence: 0.8}}
        - ArmAndTakeoff: {altitude_m: 20}
        - ReactiveSequence:
            name: fly to the cue
            children:
              - ForceSuccess: {child: TargetTelemetryCue}
              - %s
              - FollowGlobal: {target: "{target/%s}", output: guided, slant_range_m: %g, elevation_deg: 30}
"""


def _tree(tmp_path: Path, camera: bool = False) -> Path:
    """The mini chase; with the camera it follows the intruder's telemetry 20 m off and runs the vision
    pipeline (close in, the radar merges the two drones' tracks: the real chase tree searches then)."""
    path = tmp_path / "mini_chase.yaml"
    if camera:
        path.write_text(MINI_CHASE % ("ForceSuccess: {child: VisionPipeline}", "telemetry", 20.0))
    else:
        path.write_text(MINI_CHASE % ("RadarCue: {max_age_s: 3}", "cue", 40.0))
    return path


def _chase(time_limit_s: float, **changes) -> Scenario:
    doc = yaml.safe_load(CHASE.read_text())
    doc["time_limit_s"] = time_limit_s
    doc.update(changes)
    return Scenario.from_dict(doc, "chase (test)")


def test_chase_scenario_has_a_radar_and_a_phantom_a_few_hundred_metres_out():
    sc = load_scenario(CHASE)
    assert sc.radar is not None and sc.radar.off_at_s is None and sc.time_limit_s == 300
    (phantom,) = sc.intruders
    assert phantom.sysid == 2 and phantom.trajectory == "random_waypoints"
    assert 200 < math.hypot(*phantom.start_enu[:2]) < 500
    off = load_scenario(ROOT / "sitl" / "scenarios" / "chase_radar_off.yaml")
    assert off.radar.off_at_s == 35.0 and off.intruders == sc.intruders


def test_rehearsal_gives_the_mission_radar_and_telemetry_and_scores_them(tmp_path):
    seen = {}

    def on_start(runner, vehicle, resources):
        seen.update(resources, ticks=runner.ticks, setup=runner._set_up)

    report = rehearse(_tree(tmp_path), _chase(70.0), seed=1, sensors=SensorOptions(camera=False), trace=True,
                      on_start=on_start)
    assert report.outcome == "following", report.message  # FollowGlobal still running at the time limit
    assert report.sensors == ["radar", "target_telemetry"]
    assert isinstance(seen["radar"], RadarFeed) and isinstance(seen["target_telemetry"], TargetTelemetry)
    assert seen["ticks"] == 0 and seen["setup"]  # the hook runs after setup, before the first tick
    # The mission's radar pose came from the calibration flight, not from the scenario.
    assert report.radar_pose == "calibrated"
    assert 0.0 < report.radar_pose_err_m < 5.0 and abs(report.radar_yaw_err_deg) < 1.0
    # Validation -> 20 m: arming and a 2.5 m/s climb (about 8 s), and the trace agrees.
    trace = report.trace
    validated, airborne = trace.first_event("radar_validated"), trace.first_event("airborne")
    assert report.t_airborne_s == pytest.approx(airborne.t - validated.t, abs=0.01)
    assert 7.0 < report.t_airborne_s < 20.0
    # The ownship's radar track was associated through the fly-out (drops and swaps included).
    assert report.radar_windows > 30 and report.radar_assoc_frac > 0.7 and report.wrong_assoc_frac < 0.1
    # Telemetry reached the blackboard and is the intruder's position (truth from the trace).
    assert seen["target_telemetry"].received > 100
    cue = py_trees.blackboard.Blackboard.storage["/target/telemetry"]
    assert np.linalg.norm(cue.position_enu - trace.target_enu[-1]) < 5.0
    # It flew from the ground toward the intruder, 300 m out, and is at the stand-off now.
    assert trace.slant_range_m[0] > 250.0 and trace.slant_range_m[-1] < 70.0
    # No camera: its scores do not apply.
    assert report.detection_frames == 0 and report.detection_frac is None and report.target_in_fov_frac is None
    assert len(trace) == report.ticks and trace.meta["ownship_source"] == "truth"
    assert trace.desired_range_m == 40.0 and trace.desired_elevation_rad == pytest.approx(math.radians(30))
    d = report.to_dict()
    assert "trace" not in d and json.loads(json.dumps(d))["t_airborne_s"] == report.t_airborne_s


def test_surveyed_radar_pose_is_the_truth_plus_survey_error():
    sc = load_scenario(CHASE)
    from chaser_bt.geo import LocalFrame
    from chaser_bt.radar.geometry import RadarPose

    frame = LocalFrame(sc.home)
    truth = RadarPose.from_geodetic(frame, sc.radar.position, sc.radar.yaw_rad, sc.radar.pitch_rad, sc.radar.roll_rad)
    errs = []
    for seed in range(300):
        pose = surveyed_radar_pose(sc.radar, sc.home, seed).in_frame(frame)
        dyaw = (pose.yaw_pitch_roll[0] - truth.yaw_pitch_roll[0] + math.pi) % (2 * math.pi) - math.pi
        errs.append([*(pose.position_enu - truth.position_enu), dyaw])
    e = np.array(errs)
    assert np.std(e[:, 0]) == pytest.approx(SURVEY_SIGMA[0], rel=0.15)
    assert np.std(e[:, 2]) == pytest.approx(SURVEY_SIGMA[1], rel=0.15)
    assert np.std(e[:, 3]) == pytest.approx(SURVEY_SIGMA[2], rel=0.15)
    assert abs(np.mean(e[:, 0])) < 0.3
    a, b = surveyed_radar_pose(sc.radar, sc.home, 5), surveyed_radar_pose(sc.radar, sc.home, 5)
    assert a.position == b.position and np.allclose(a.rotation.as_quat(), b.rotation.as_quat())


def test_calibrated_radar_pose_is_close_and_cached():
    sc = load_scenario(CHASE)
    from chaser_bt.geo import LocalFrame
    from chaser_bt.radar.geometry import RadarPose

    frame = LocalFrame(sc.home)
    truth = RadarPose.from_geodetic(frame, sc.radar.position, sc.radar.yaw_rad, sc.radar.pitch_rad, sc.radar.roll_rad)
    fix = calibrated_radar_pose(sc.radar, sc.home, 2)
    pose = fix.in_frame(frame)
    assert fix.method == "calibrated" and fix.residual_rms_m < 4.0
    assert np.linalg.norm(pose.position_enu - truth.position_enu) < 5.0
    angle = (pose.rotation * truth.rotation.inv()).magnitude()
    assert math.degrees(angle) < 2.0  # 20 seeds: median 0.7 deg, max 1.2 deg
    assert calibrated_radar_pose(sc.radar, sc.home, 2) is fix  # cached per (radar, home, seed)


def test_build_sensors_gives_only_what_the_scenario_provides():
    patrol = load_scenario(PATROL)  # no radar, no intruders
    assert build_sensors(InProcessVehicle(patrol, 1), SensorOptions(camera=False), 1).resources == {}
    vehicle = InProcessVehicle(load_scenario(CHASE), 1)
    sensors = build_sensors(vehicle, SensorOptions(radar_pose="surveyed", telemetry=False, camera_size=(160, 120)), 1)
    assert sorted(sensors.resources) == ["camera", "radar"] and isinstance(sensors.resources["camera"], CameraSensor)
    assert vehicle.link.frame is not None  # the radar pose is placed in the frame of the home the vehicle reported
    assert sensors.frame_source.camera.width_px == 160 and sensors.camera.pipeline.camera is sensors.frame_source.camera
    # The chase scenario carries its camera on a gimbal, 10 deg below the horizon.
    assert (sensors.camera.pipeline.camera.mount, sensors.camera.pipeline.camera.tilt_rad) == ("stabilised", math.radians(10))
    # The rendered camera reads out the pipeline's regions of interest unless whole frames are asked for.
    assert sensors.frame_source.reads_regions and not sensors.camera.whole_frames
    whole = build_sensors(InProcessVehicle(load_scenario(CHASE), 1), SensorOptions(radar=False, whole_frames=True), 1)
    assert whole.camera.whole_frames
    # The scenario's camera key says how the chaser carries its camera: the renderer and the pipeline alike.
    fixed = dataclasses.replace(load_scenario(CHASE), camera=OnboardCamera("fixed", 25.0))
    held = build_sensors(InProcessVehicle(fixed, 1), SensorOptions(radar=False, camera_size=(160, 120)), 1)
    assert held.frame_source.camera is held.camera.pipeline.camera
    assert (held.camera.pipeline.camera.mount, held.camera.pipeline.camera.tilt_rad) == ("fixed", math.radians(25))
    with pytest.raises(ValueError, match="radar_pose"):
        SensorOptions(radar_pose="truth")


def test_radar_datagrams_reach_the_feed_and_stop_when_the_radar_goes_off():
    vehicle = InProcessVehicle(_chase(60.0, radar={**yaml.safe_load(CHASE.read_text())["radar"], "off_at_s": 10.0}), 3)
    sensors = build_sensors(vehicle, SensorOptions(camera=False, telemetry=False, radar_pose="surveyed"), 3)
    vehicle.run_until(lambda: vehicle.sim.time_s >= 9.0, 20.0)
    pic = sensors.radar.update(vehicle.sim.time_s)
    assert pic.intruders and pic.counts.accepted >= 35  # 5 Hz for about 8 s
    vehicle.run_until(lambda: vehicle.sim.time_s >= 14.0, 20.0)
    assert sensors.radar.update(vehicle.sim.time_s).tracks == {}  # tracks time out once the radar is off
    assert sensors.radar_queue.receive() == []


@pytest.mark.slow
def test_camera_rehearsal_acquires_the_intruder_and_scores_vision(tmp_path):
    # 20 m stand-off: a Phantom (0.6 m) is about 6 px wide there at 640 x 480, which the detector finds.
    report = rehearse(_tree(tmp_path, camera=True), _chase(60.0), seed=1,
                      sensors=SensorOptions(camera_size=(640, 480)), trace=True)
    assert report.sensors == ["camera", "radar", "target_telemetry"]
    assert report.t_acquire_s is not None and report.t_acquire_s > 0.0
    assert report.detection_frames > 100
    assert 0.0 < report.detection_frac <= 1.0
    assert 0.5 < report.target_in_fov_frac <= 1.0 and 0.0 < report.target_in_fov_frac_flight <= 1.0
    trace = report.trace
    assert trace.first_event("acquired").t == pytest.approx(trace.first_event("airborne").t + report.t_acquire_s, abs=0.01)
    scored = trace.detected[np.isfinite(trace.detected)]
    assert scored.size > 100 and scored.mean() > 0.0


def test_camera_draws_the_scripted_targets_present_and_keeps_their_indices():
    doc = yaml.safe_load(CHASE.read_text())
    for key in ("radar", "intruders"):
        doc.pop(key)
    ahead = {"speed_mps": 0.1}
    doc["targets"] = [  # in front of the parked chaser (heading north), one arriving at 5 s
        {"name": "early", "kind": "s1000", "waypoints": {"points_enu_m": [[-2, 15, 3], [-2, 16, 3]], **ahead}},
        {"name": "late", "kind": "phantom", "start_s": 5.0, "waypoints": {"points_enu_m": [[2, 12, 2], [2, 13, 2]], **ahead}},
    ]
    sc = Scenario.from_dict(doc, "two targets (test)")
    vehicle = InProcessVehicle(sc, 1)
    sensors = build_sensors(vehicle, SensorOptions(camera_size=(320, 240)), 1)
    src = sensors.frame_source
    assert sorted(sensors.resources) == ["camera"] and src.source._renderer is None  # no world built before the first frame drawn
    vehicle.run_until(lambda: vehicle.sim.time_s >= 2.0, 5.0)
    assert src.read(2.0).image.shape == (240, 320, 3)
    assert [(lab.index, lab.kind) for lab in src.last_labels] == [(0, "s1000")]
    vehicle.run_until(lambda: vehicle.sim.time_s >= 6.0, 5.0)
    src.read(6.0)
    assert [(lab.index, lab.kind) for lab in src.last_labels] == [(0, "s1000"), (1, "phantom")]
    blind = build_sensors(InProcessVehicle(sc, 1), SensorOptions(camera_detection=False, camera_size=(320, 240)), 1)
    blind.frame_source.read(0.0)
    assert blind.frame_source.last_labels == ()


def test_the_camera_world_is_built_while_the_sensors_are_set_up_and_only_for_a_tree_that_looks(monkeypatch):
    calls: list[str] = []
    prepare, develop = ScenarioFrameSource.prepare, ScenarioFrameSource.develop

    def spy_prepare(self):
        calls.append(f"prepare:{self.source._renderer is None}")
        prepare(self)
        calls.append(f"built:{self.source._renderer is not None}")

    def spy_develop(self, shot, regions=None):
        calls.append("develop")
        return develop(self, shot, regions)

    monkeypatch.setattr(ScenarioFrameSource, "prepare", spy_prepare)
    monkeypatch.setattr(ScenarioFrameSource, "develop", spy_develop)
    short = dataclasses.replace(load_scenario(CHASE), time_limit_s=15.0)  # airborne, then looking
    report = rehearse(ROOT / "trees" / "chase.yaml", short, 1, sensors=SensorOptions(camera_size=(320, 240)))
    assert calls[:2] == ["prepare:True", "built:True"] and calls.count("prepare:True") == 1
    assert calls[2:] and set(calls[2:]) == {"develop"}  # frames drawn only after the world was there
    assert report.sensors_wall_s > 0.0
    calls.clear()
    rehearse(ROOT / "trees" / "takeoff_land.yaml", short, 1, sensors=SensorOptions(camera_size=(320, 240)))
    assert calls == []  # no camera leaf: no world, no frame


def test_the_detector_takes_a_second_thread_only_beside_a_render_process(monkeypatch):
    from sitl.bench.sensors import detector_threads

    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    assert detector_threads() == 1 and detector_threads(beside_renderer=True) == 2
    monkeypatch.setattr("os.cpu_count", lambda: 1)
    assert detector_threads(beside_renderer=True) == 1  # one core: the renderer has no idle core to lend
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    assert detector_threads() == detector_threads(beside_renderer=True) == 3  # said outright: as said
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    assert detector_threads(beside_renderer=True) == 1  # a campaign worker's setting holds
    monkeypatch.delenv("OMP_NUM_THREADS")
    options = SensorOptions(radar=False, telemetry=False, camera_size=(160, 120))
    drawn_here = build_sensors(InProcessVehicle(load_scenario(CHASE), 1), options, 1)
    beside = build_sensors(InProcessVehicle(load_scenario(CHASE), 1), dataclasses.replace(options, render_process=True), 1)
    try:
        assert drawn_here.camera.pipeline.detector.threads == 1
        assert beside.render_process is not None and beside.camera.pipeline.detector.threads == 2
    finally:
        drawn_here.close()
        beside.close()


def test_a_render_process_that_cannot_build_its_world_fails_the_set_up_in_one_line(tmp_path, monkeypatch, capsys):
    """Nothing is flown: rehearse() raises SensorSetupError naming the child's own error (its traceback
    chained), and ``chaser-bt rehearse`` says it in one line and exits 1."""
    from sitl.bench.rehearsal import SensorSetupError
    from sitl.world.camera.world import WorldSpec

    broken = dataclasses.replace(load_scenario(CHASE), time_limit_s=5.0, camera_world=WorldSpec(family="no-such-family"))
    options = SensorOptions(camera_size=(160, 120), render_process=True)
    with pytest.raises(SensorSetupError, match=r"^the sensors could not be set up: RuntimeError: .*no-such-family") as err:
        rehearse(ROOT / "trees" / "chase.yaml", broken, 1, sensors=options)
    assert "\n" not in str(err.value) and "Traceback" in str(err.value.__cause__)

    import chaser_bt.cli as cli

    monkeypatch.setattr(cli, "_load_scenario", lambda path: broken)
    code = cli.main(["rehearse", str(ROOT / "trees" / "chase.yaml"), "--scenario", str(CHASE), "--progress", "never",
                     "--camera-size", "160x120"])
    err_lines = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err_lines) == 1
    assert err_lines[0].startswith("chaser-bt: rehearse: the sensors could not be set up: RuntimeError:")
