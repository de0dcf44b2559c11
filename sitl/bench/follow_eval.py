"""Scoring a follow flight against the simulator's truth (rehearsal-side only, like sitl.bench.rehearsal).

:func:`fly_follow` takes off and follows the intruder with a two-node tree, by one of two range
sources: ``"telemetry"`` hands the intruder's telemetry to ``TargetTelemetryCue`` -> ``FollowGlobal``
(the paper's GPS range); ``"vision"`` renders the chaser's camera (the paper's e-con, tilted down by
the set-point elevation) and runs the shipped detector: ``VisionPipeline`` -> ``CVFollow``, azimuth,
elevation and range all from the camera (range from the box size), no telemetry at all. It records, every 0.2 s of simulated time, whether the
intruder is inside the chaser's fixed camera (the paper's e-con, tilted down by the set-point
elevation) and the true relative geometry. Scores count from the moment the intruder starts
moving (its ``start_s``): the share of that time with the target in the FOV, and the slant-range
and elevation errors. The mission side never sees any of this.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import py_trees

from chaser_bt.cue import TargetEstimate
from chaser_bt.mission.runner import MissionRunner
from chaser_bt.target_telemetry import TargetTelemetry
from chaser_bt.tree import load_tree_text, reset_blackboard
from chaser_bt.vehicle import LinkConfig
from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.pipeline import CameraSensor, PipelineConfig, VisionPipeline
from sitl.bench.in_process import InProcessVehicle
from sitl.world.camera.frame_source import SimTarget, SimulatorFrameSource
from sitl.world.scenario import Scenario

__all__ = ["FollowScore", "fly_follow", "intruder_scenario", "TRAJECTORY_PARAMS", "RANGE_SOURCES",
           "VISION_FOLLOW_PORTS"]

SAMPLE_S = 0.2
RANGE_SOURCES = ("telemetry", "vision")
#: CVFollow's ports for following on the camera's own range (no telemetry): range low-passed along
#: the accurate bearing, derivative terms from the filtered process variables rather than from
#: differenced camera positions, lean held to 15 deg so the fixed camera keeps the target in view.
VISION_FOLLOW_PORTS = "range_smoothing_s: 3, measured_rates: false, max_lean_deg: 15"
ESTIMATE_FRESH_S = 0.5  # an estimate younger than this counts as the camera tracking the target

#: One representative intruder per trajectory kind (sitl/scenarios/README.md), starting 40 m north of home.
TRAJECTORY_PARAMS: dict[str, dict] = {
    "rectangle": {"corners_enu_m": [[0, 140, 20], [100, 140, 20], [100, 40, 20], [0, 40, 20]], "speed_mps": 6,
                  "pause_s": 8},
    "circle": {"center_enu_m": [0, 100, 20], "radius_m": 60, "speed_mps": 8},
    "figure_eight": {"center_enu_m": [0, 40, 20], "half_length_m": 80, "speed_mps": 8, "heading_deg": 90},
    "random_waypoints": {"center_enu_m": [0, 90, 30], "half_extent_m": 80, "alt_min_m": 15, "alt_max_m": 45,
                         "speed_min_mps": 3, "speed_max_mps": 15, "pause_max_s": 4},
    "evasive": {"center_enu_m": [0, 100, 35], "half_extent_m": 120, "alt_min_m": 15, "alt_max_m": 60,
                "cruise_speed_mps": 8},
}


def intruder_scenario(kind: str, *, start_s: float = 50.0, time_limit_s: float = 400.0, params: dict | None = None,
                      wind_mps: float = 2.0, climb_mps: float = 5.0) -> Scenario:
    """A quick-boot scenario with one Phantom-like intruder (sysid 2) flying ``kind``; the chaser's
    ALT_HOLD climbs and descends at up to ``climb_mps`` (PILOT_SPEED_UP/DN)."""
    return Scenario.from_dict({
        "name": f"follow-{kind}",
        "home": {"lat_deg": 42.5445, "lon_deg": -71.6105, "alt_m": 80.0},
        "wind": {"speed_mps": wind_mps, "direction_deg": 270.0, "gust_std_mps": 0.3},
        "params": {"PILOT_SPEED_UP": round(climb_mps * 100), "PILOT_SPEED_DN": round(climb_mps * 100)},
        "boot": {"gps_fix_s": 1.0, "ekf_ready_s": 2.0, "prearm_ok_s": 3.0},
        "time_limit_s": time_limit_s,
        "intruders": [{"name": "phantom", "sysid": 2, "start_enu_m": [0, 40, 20], "start_s": start_s,
                       kind: params if params is not None else TRAJECTORY_PARAMS[kind]}],
    }, source=f"<follow-{kind}>")


@dataclass
class FollowScore:
    """Truth sampled every 0.2 s after the intruder started moving."""

    t: list[float] = field(default_factory=list)
    in_fov: list[bool] = field(default_factory=list)
    slant_m: list[float] = field(default_factory=list)
    elevation_rad: list[float] = field(default_factory=list)
    ground_m: list[float] = field(default_factory=list)
    height_m: list[float] = field(default_factory=list)
    chaser_speed: list[float] = field(default_factory=list)  # horizontal, m/s
    target_speed: list[float] = field(default_factory=list)
    azimuth_rad: list[float] = field(default_factory=list)  # target off the chaser's nose (left positive)
    vision_range_err_m: list[float] = field(default_factory=list)  # estimate minus true range, when fresh
    tracking: list[bool] = field(default_factory=list)  # a fresh vision estimate at the sample

    @property
    def in_fov_frac(self) -> float:
        return float(np.mean(self.in_fov)) if self.in_fov else float("nan")

    def range_err_p50(self, slant_sp: float) -> float:
        return float(np.median(np.abs(np.asarray(self.slant_m) - slant_sp)))

    def elev_err_deg_p50(self, el_sp: float) -> float:
        return float(np.degrees(np.median(np.abs(np.asarray(self.elevation_rad) - el_sp))))

    @property
    def vision_range_abs_err_p50(self) -> float:
        """Median |vision range - true range| over samples with a fresh estimate (NaN: none)."""
        e = np.abs(self.vision_range_err_m)
        return float(np.median(e)) if e.size else float("nan")

    @property
    def tracking_frac(self) -> float:
        """Share of samples with a fresh vision estimate (NaN when vision was not flown)."""
        return float(np.mean(self.tracking)) if self.tracking else float("nan")


def fly_follow(scenario: Scenario, seed: int, *, follow_ports: str = "", duration_s: float = 150.0,
               slant_range_m: float = 40.0, elevation_deg: float = 40.0, vehicle: InProcessVehicle | None = None,
               range_source: str = "telemetry", camera_size: tuple[int, int] = (640, 480),
               vision_ports: str = "", target_kind: str = "s1000", pipeline_config: PipelineConfig | None = None
               ) -> tuple[FollowScore, InProcessVehicle, MissionRunner]:
    """Take off, follow the scenario's first intruder, score ``duration_s`` of its flight.

    Args:
        range_source: ``"telemetry"`` (FollowGlobal on the intruder's MAVLink position) or
            ``"vision"`` (CVFollow on the rendered camera's estimate, no telemetry).
        camera_size: the rendered camera's (width, height) with vision.
        follow_ports, vision_ports: extra ports of the follow leaf and of VisionPipeline (YAML flow).
        target_kind: the airframe the camera draws for the intruder (it flies as the scenario
            says): ``s1000`` by default, the target of the paper's flight (section 4); a Phantom is
            under 4 px at 40 m in a 640 px frame, below what the shipped detector finds.
        pipeline_config: the vision pipeline's settings (default ``PipelineConfig()``).
    """
    if range_source not in RANGE_SOURCES:
        raise ValueError(f"range_source must be one of {', '.join(RANGE_SOURCES)}, got {range_source!r}")
    reset_blackboard()
    v = vehicle or InProcessVehicle(scenario, seed, link_config=LinkConfig(target_sysid=1))
    intruder = v.sim.intruders[0]
    tel = TargetTelemetry.attach(v.link, v.clock.now) if range_source == "telemetry" else None
    alt = intruder.pos[2] + slant_range_m * math.sin(math.radians(elevation_deg))
    _run(v, f"ArmAndTakeoff: {{altitude_m: {alt:.1f}}}", {}, 150.0)
    ports = f"slant_range_m: {slant_range_m}, elevation_deg: {elevation_deg}" + (f", {follow_ports}" if follow_ports else "")
    cam = CameraModel(width_px=int(camera_size[0]), height_px=int(camera_size[1]), tilt_rad=math.radians(elevation_deg))
    if tel is not None:
        body = ("ReactiveSequence:\n  children:\n    - TargetTelemetryCue: {sysid: %d}\n    - FollowGlobal: {%s}\n"
                % (intruder.spec.sysid, ports))
        runner = _runner(v, body, {"target_telemetry": tel})
    else:
        from sitl.bench.sensors import detector_threads, shared_detector, shared_ground

        source = SimulatorFrameSource(v.sim, cam, [SimTarget(target_kind, intruder)], seed, ground=shared_ground())
        camera = CameraSensor(source, VisionPipeline(cam, shared_detector(detector_threads()), pipeline_config or PipelineConfig()))
        body = ("ReactiveSequence:\n  children:\n    - ForceSuccess: {child: {VisionPipeline: {%s}}}\n"
                "    - CVFollow: {%s}\n" % (vision_ports, ports))
        runner = _runner(v, body, {"camera": camera})
    cam = CameraModel(width_px=cam.width_px, height_px=cam.height_px, tilt_rad=cam.tilt_rad, max_range_m=1e6)
    score = FollowScore()
    t_start = intruder.spec.start_s
    next_sample = [t_start]

    def step() -> bool:
        runner.tick_if_due()
        t = v.sim.time_s
        if t >= next_sample[0] - 1e-9:
            next_sample[0] += SAMPLE_S
            truth = v.sim.truth
            d = intruder.pos - truth.pos_enu
            score.t.append(t)
            score.in_fov.append(bool(cam.visible(intruder.pos[None], truth.pos_enu, truth.attitude)[0]))
            g = math.hypot(d[0], d[1])
            score.ground_m.append(g)
            score.height_m.append(-d[2])
            score.slant_m.append(float(np.linalg.norm(d)))
            score.elevation_rad.append(math.atan2(-d[2], g))
            score.chaser_speed.append(float(math.hypot(*truth.vel_enu[:2])))
            score.target_speed.append(float(math.hypot(*intruder.vel[:2])))
            yaw_enu = math.pi / 2 - truth.euler_ned[2]
            score.azimuth_rad.append((math.atan2(d[1], d[0]) - yaw_enu + math.pi) % (2 * math.pi) - math.pi)
            if range_source == "vision":
                est = _estimate()
                fresh = est is not None and t - est.t <= ESTIMATE_FRESH_S
                score.tracking.append(fresh)
                if fresh and math.isfinite(est.range_m):
                    score.vision_range_err_m.append(est.range_m - float(np.linalg.norm(d)))
        return runner.finished

    v.run_until(step, t_start + duration_s - v.sim.time_s)
    return score, v, runner


def _estimate() -> TargetEstimate | None:
    """The camera's estimate on the blackboard (scoring only), None before the first."""
    try:
        est = py_trees.blackboard.Blackboard.get("/target/estimate")
    except KeyError:
        return None
    return est if isinstance(est, TargetEstimate) else None


def _runner(v: InProcessVehicle, body: str, resources: dict) -> MissionRunner:
    text = "version: 1\ntrees:\n  Follow:\n" + "\n".join("    " + line for line in body.strip().splitlines()) + "\n"
    return MissionRunner(load_tree_text(text, source="<follow>"), v.link, v.clock, rate_hz=10.0, resources=resources)


def _run(v: InProcessVehicle, body: str, resources: dict, timeout_s: float) -> None:
    runner = _runner(v, body, resources)
    v.fly(runner, timeout_s)
    if runner.status.name != "SUCCESS":
        raise RuntimeError(f"follow set-up failed: {runner.tip_message()}")
