"""Every sensor of a rehearsal, built the way a real flight gets them (DESIGN §2 and §6).

A rehearsal's mission gets exactly what it would get on the field, and nothing more:

- **radar**: a :class:`~chaser_bt.radar.feed.RadarFeed` reading the simulator's radar datagrams from
  an in-process queue (:meth:`sitl.simulator.Simulator.add_radar_consumer`), with our correlator
  (``"gated"``). The mission is *not* handed the scenario's true radar pose: with
  ``radar_pose="calibrated"`` the pose comes from the paper's appendix-A calibration (the 6-DOF fit
  of :mod:`chaser_bt.radar.calibration`) run on a scripted calibration flight past the same radar
  model, from a handheld-GPS/compass guess; with ``"surveyed"`` it is the truth plus a survey error
  (GPS 1.5 m horizontal, 3 m vertical, compass 0.5 deg, inclinometer 0.2 deg, 1 sigma). Radar scan
  times and the mission clock are both the simulator's boot clock, so the feed's time offset is 0.
- **camera**: a :class:`~chaser_bt.vision.lagged_camera.LaggedCamera` (a frame behind the tick, as a
  flight's camera pipeline beside its control loop) over the simulator's renderer
  (:class:`ScenarioFrameSource`) drawing the scenario's intruders (``phantom``) and scripted targets
  present at the time (their ``kind``; the k-th in colour scheme k), read by the shipped detector;
  drawn in a :class:`~sitl.world.camera.render_process.RenderProcess` with ``render_process``.
  The detector is loaded at the first frame; the camera world is built (or waited for) by
  :meth:`ScenarioFrameSource.prepare`, which a rehearsal calls while it sets the sensors up when its
  tree has a camera leaf (a mission without vision never pays for either). The detector runs one
  thread, two beside a render process (:func:`detector_threads`).
- **target telemetry**: a :class:`~chaser_bt.target_telemetry.TargetTelemetry` as the vehicle delivers it (on its link in process, on the intruders' own radio beside ArduCopter)
  (the intruders' own MAVLink positions).

The radar pose is a geodetic position and an attitude, as a survey or a calibration gives it; it
is turned into the mission's ENU frame (the link's, at the vehicle's home) once the vehicle has
reported its home, so :func:`build_sensors` steps the simulator until it has. The calibration is
cached in memory per (radar, home, seed); it costs 0.3-1 s (2-core machine).
"""

from __future__ import annotations

import functools
import logging
import math
import os
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.geo import GeoPoint, LocalFrame
from chaser_bt.radar.feed import RadarFeed, RadarNoise
from chaser_bt.radar.geometry import RadarPose
from chaser_bt.radar.recording import calibrate_recording
from chaser_bt.radar.stream import QueueDatagramSource
from chaser_bt.target_telemetry import TargetTelemetry
from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.frame_source import Frame, Region
from chaser_bt.vision.lagged_camera import LaggedCamera
from chaser_bt.vision.pipeline import CameraSensor, VisionPipeline
from sitl.bench.radar_trials import (
    FIELD,
    OWNSHIP,
    handheld_guess,
    simulate_flight,
    to_recording,
)
from sitl.world.camera.frame_source import Shot, SimTarget, SimulatorFrameSource
from sitl.world.camera.render_process import RenderProcess
from sitl.world.camera.scene import GroundScene
from sitl.world.camera.world import PLAIN_FIELD_SEED, WorldSpec, build_world, plain_ground
from sitl.world.radar.config import RadarConfig
from sitl.world.targets import WaypointPath, circle_points

if TYPE_CHECKING:
    from sitl.bench.in_process import LockStepVehicle

__all__ = ["SensorOptions", "RadarPoseFix", "MissionSensors", "ScenarioFrameSource", "build_sensors",
           "calibrated_radar_pose", "surveyed_radar_pose", "shared_detector", "shared_ground", "SURVEY_SIGMA",
           "RADAR_POSE_MODES"]

log = logging.getLogger(__name__)

RADAR_POSE_MODES = ("calibrated", "surveyed")
#: 1-sigma survey errors: east/north (m), up (m), yaw, pitch, roll (rad).
SURVEY_SIGMA = (1.5, 3.0, math.radians(0.5), math.radians(0.2), math.radians(0.2))
_HOME_WAIT_S = 60.0  # sim seconds to wait for the vehicle's home before falling back to the scenario's


@dataclass(frozen=True)
class SensorOptions:
    """Which sensors a rehearsal gives the mission (each only where the scenario provides it).

    Args:
        radar: a RadarFeed when the scenario has a radar.
        radar_pose: how the mission learns the radar pose: ``"calibrated"`` (appendix A on a
            calibration flight) or ``"surveyed"`` (truth plus survey error).
        camera: the rendered camera and the vision pipeline.
        camera_size: (width, height) pixels.
        camera_detection: False: the targets are never drawn (search-only runs).
        telemetry: the intruders' own MAVLink position as TargetTelemetry.
        whole_frames: render every frame whole instead of only the regions the pipeline reads
            (the reference a speed benchmark compares with; docs/vision.md, "Regions of interest").
        camera_lag: the camera one frame behind the tick (:class:`~chaser_bt.vision.lagged_camera.LaggedCamera`:
            the estimate a tick reads is the last frame's, as on an aircraft whose camera pipeline
            runs beside the control loop); False: each frame read and processed inside its tick.
        render_process: with ``camera_lag``, draw the frames in a process of their own
            (:class:`~sitl.world.camera.render_process.RenderProcess`), beside the tick: the same
            frames, on a second core. Campaign workers leave it off (the runs are their parallelism).
    """

    radar: bool = True
    radar_pose: str = "calibrated"
    camera: bool = True
    camera_size: tuple[int, int] = (640, 480)
    camera_detection: bool = True
    telemetry: bool = True
    whole_frames: bool = False
    camera_lag: bool = True
    render_process: bool = False

    def __post_init__(self) -> None:
        if self.radar_pose not in RADAR_POSE_MODES:
            raise ValueError(f"radar_pose must be one of {', '.join(RADAR_POSE_MODES)}, got {self.radar_pose!r}")
        if len(self.camera_size) != 2 or any(int(v) <= 0 for v in self.camera_size):
            raise ValueError(f"camera_size must be (width, height) > 0, got {self.camera_size!r}")


@dataclass(frozen=True)
class RadarPoseFix:
    """The radar pose as the mission knows it: geodetic position and radar-frame -> ENU rotation.

    ``method`` says where it came from; ``residual_rms_m`` is the calibration fit's residual (NaN for
    a survey); ``wall_s`` what finding it cost.
    """

    position: GeoPoint
    rotation: Rotation
    method: str
    residual_rms_m: float = math.nan
    wall_s: float = 0.0

    def in_frame(self, frame: LocalFrame) -> RadarPose:
        """The pose in the mission's ENU ``frame``."""
        return RadarPose(frame.point_to_enu(self.position), self.rotation)


def surveyed_radar_pose(config: RadarConfig, home: GeoPoint, seed: int) -> RadarPoseFix:
    """The true pose plus a survey error drawn from ``seed`` (:data:`SURVEY_SIGMA`)."""
    rng = np.random.default_rng([seed, 0x5E7])
    frame = LocalFrame(home)
    sh, sv, syaw, spitch, sroll = SURVEY_SIGMA
    pos = frame.point_to_enu(config.position) + rng.normal(0.0, [sh, sh, sv])
    dy, dp, dr = rng.normal(0.0, [syaw, spitch, sroll])
    pose = RadarPose.from_attitude(pos, config.yaw_rad + dy, config.pitch_rad + dp, config.roll_rad + dr)
    return RadarPoseFix(frame.to_geodetic(pose.position_enu), pose.rotation, "surveyed")


def _calibration_paths(radar_enu: np.ndarray, yaw_rad: float) -> WaypointPath:
    """The paper's calibration flight (appendix A, 3 min 36 s) laid out in front of the radar:
    two circles, three vertical passes at different ranges and bearings, a far circle."""
    u = np.array([math.sin(yaw_rad), math.cos(yaw_rad), 0.0])  # boresight, horizontal, ENU
    left = np.array([-u[1], u[0], 0.0])
    ground = np.array([radar_enu[0], radar_enu[1], 0.0])
    pts = circle_points(tuple(ground + 90.0 * u + [0, 0, 20.0]), 25.0, laps=2)
    for side, rng_m in ((-30.0, 70.0), (0.0, 110.0), (30.0, 80.0)):
        base = ground + rng_m * u + side * left
        pts += [tuple(base + [0, 0, 10.0]), tuple(base + [0, 0, 60.0]), tuple(base + 5 * u + [0, 0, 60.0]),
                tuple(base + 5 * u + [0, 0, 10.0])]
    pts += circle_points(tuple(ground + 150.0 * u + [0, 0, 40.0]), 35.0, laps=1)
    return WaypointPath(tuple(pts), speed_mps=5.0, loop=True)


@functools.lru_cache(maxsize=64)
def calibrated_radar_pose(config: RadarConfig, home: GeoPoint, seed: int, duration_s: float = 216.0) -> RadarPoseFix:
    """Calibrate the radar as the paper did (appendix A): fly a drone past it, fit the 6-DOF pose.

    The flight goes through the same radar model (noise, id drops, duplicates, clutter of
    ``config``) with the ownship's GPS noise; the fit starts from a handheld-GPS position and a
    phone-compass attitude (:func:`sitl.bench.radar_trials.handheld_guess`). The flight is simulated in
    the radar-flight module's field frame with the radar at the same offset from home, so the fitted
    offset is the radar's offset from ``home``. Cached per (config, home, seed).
    """
    start = time.perf_counter()
    offset = LocalFrame(home).point_to_enu(config.position)  # the radar relative to home
    field_frame = LocalFrame(FIELD)
    cfg = replace(config, position=field_frame.to_geodetic(offset), off_at_s=None, udp_port=None)
    flight = simulate_flight({OWNSHIP: _calibration_paths(offset, config.yaw_rad)}, cfg, seed, duration_s)
    result, where = calibrate_recording(to_recording(flight, handheld_guess(flight, seed)), "six")
    fitted_offset = field_frame.point_to_enu(where)
    wall = time.perf_counter() - start
    log.info("radar calibrated in %.2f s: residual %.2f m rms over %d bins", wall, result.residual_rms_m, result.n_bins)
    return RadarPoseFix(LocalFrame(home).to_geodetic(fitted_offset), result.pose.rotation, "calibrated",
                        result.residual_rms_m, wall)


def detector_threads(beside_renderer: bool = False) -> int:
    """Threads for the rehearsal's detector: ``OMP_NUM_THREADS`` when set; else two when the frames
    are drawn in a render process on a machine with two cores or more, one otherwise.

    Beside a render process the second thread runs while the renderer's core is idle (its drawing
    fills a little more than half of each tick): the same detections, and rehearsals 1.5-21 % faster
    in eight interleaved pairs of 120 s chases on the two-core machine (median 6 %). Drawing
    in-process, as a campaign's workers do, both cores are already busy, so one (onnxruntime's
    threads sleep rather than spin while they wait: :func:`~chaser_bt.vision.detector.onnx_copy.ort_session`)."""
    env = os.environ.get("OMP_NUM_THREADS", "")
    if env.isdigit() and int(env) > 0:
        return int(env)
    return 2 if beside_renderer and (os.cpu_count() or 1) >= 2 else 1


@functools.lru_cache(maxsize=2)
def shared_detector(threads: int = 1) -> Any:
    """The shipped detector with ``threads`` threads (onnxruntime or torch), loaded once per process."""
    from chaser_bt.vision.detector.inference import Detector

    return Detector(threads=threads)


def shared_ground() -> GroundScene:
    """The rendered camera's plain field, made once per process."""
    return plain_ground(PLAIN_FIELD_SEED)


@dataclass(frozen=True)
class _SharedDetector:
    """The shipped detector, loaded at its first use (missions without vision never load torch);
    its attributes (class names, box refiner) are the loaded detector's."""

    threads: int = 1

    def __call__(self, image: np.ndarray) -> list:
        return shared_detector(self.threads)(image)

    def __getattr__(self, name: str) -> Any:
        return getattr(shared_detector(self.threads), name)


class ScenarioFrameSource:
    """The rendered camera over a scenario: draws the targets present now (scripted targets come and
    go). The world and its renderer are made by :meth:`prepare` or at the first frame drawn here, so
    a mission that never looks, or one whose frames a
    :class:`~sitl.world.camera.render_process.RenderProcess` draws, pays nothing for them here.

    ``last_labels`` (scoring only) are the true boxes of the targets in the frame last developed,
    each ``index`` the target's position in ``targets``. With a ``renderer`` (a
    :class:`~sitl.world.camera.render_process.RenderProcess`) each shot is handed to it when taken
    and its frame collected when developed; the frames are the same.
    """

    def __init__(self, simulator: Any, camera_model: CameraModel, targets: list[tuple[SimTarget, Any]],
                 seed: int, world: WorldSpec = WorldSpec(), renderer: RenderProcess | None = None) -> None:
        self.simulator = simulator
        self.camera = camera_model
        self.targets = targets  # (target, present(t) -> bool)
        self.renderer = renderer
        self.source = SimulatorFrameSource(simulator, camera_model, [], seed, world=functools.partial(
            build_world, world, seed, camera_model.width_px, camera_model.height_px))
        self.last_labels: tuple = ()
        self._shown: dict[int, list[int]] = {}  # frame index -> the targets drawn in it, until developed

    reads_regions = True  # the renderer draws only the regions the pipeline asks for

    def read(self, t: float, regions: Sequence[Region] | None = None) -> Frame | None:
        return self.develop(self.shot(t, regions), regions)

    def shot(self, t: float, regions: Sequence[Region] | None = None) -> Shot:
        """The scene now, with the targets present now (:meth:`SimulatorFrameSource.shot`); a
        renderer starts drawing its ``regions`` at once."""
        now = float(self.simulator.time_s)
        shown = [k for k, (_, present) in enumerate(self.targets) if present(now)]
        self.source.targets = [self.targets[k][0] for k in shown]
        shot = self.source.shot(t)
        self._shown[shot.index] = shown
        if self.renderer is not None:
            self.renderer.submit(shot, regions)
        return shot

    def prepare(self) -> None:
        """Have the camera world built now, not at the first frame: here, or by the renderer
        (waiting until it is). A rehearsal does this while it sets the sensors up, so the flight's
        wall time is the flight's."""
        if self.renderer is None:
            self.source.renderer  # noqa: B018 -- builds the world and its renderer
        else:
            self.renderer.wait_ready()

    def develop(self, shot: Shot, regions: Sequence[Region] | None = None) -> Frame:
        """``shot`` drawn (shots in the order taken): here, or collected from the renderer (which
        draws the regions given to :meth:`shot`)."""
        if self.renderer is None:
            frame = self.source.develop(shot, regions)
            labels = self.source.last_labels
        else:
            image, drawn, labels, _ = self.renderer.collect()
            frame = Frame(shot.t, image, shot.index, drawn)
        shown = self._shown.pop(shot.index)
        self.last_labels = tuple(replace(lab, index=shown[lab.index]) for lab in labels)
        return frame

    def close(self) -> None:
        self.source.close()
        if self.renderer is not None:
            self.renderer.close()


def _always(t: float) -> bool:
    return True


@dataclass
class MissionSensors:
    """The sensors built for one rehearsal: ``resources`` goes to ``MissionRunner(resources=...)``.

    Keys of ``resources``: ``radar`` (RadarFeed), ``camera`` (CameraSensor), ``target_telemetry``
    (TargetTelemetry), each only when enabled and present in the scenario. ``radar_pose`` says how
    the mission's radar pose was found; ``frame_source`` (scoring only) exposes the rendered labels.
    """

    radar: RadarFeed | None = None
    camera: CameraSensor | None = None
    telemetry: TargetTelemetry | None = None
    radar_pose: RadarPoseFix | None = None
    frame_source: ScenarioFrameSource | None = None
    radar_queue: QueueDatagramSource | None = None
    render_process: RenderProcess | None = None
    resources: dict[str, Any] = field(default_factory=dict)

    def close(self) -> None:
        """Release what the sensors hold (the frame source and its render process)."""
        if self.frame_source is not None:
            self.frame_source.close()
        elif self.render_process is not None:  # spawned, then the build failed before the camera
            self.render_process.close()


def _mission_frame(vehicle: LockStepVehicle) -> LocalFrame:
    """The link's ENU frame (at the home the vehicle reports), stepping until it is known."""
    link = vehicle.link
    if link.frame is None and not vehicle.run_until(lambda: link.frame is not None, _HOME_WAIT_S):
        log.warning("no HOME_POSITION within %.0f s: radar pose taken in the scenario's home frame", _HOME_WAIT_S)
        return LocalFrame(vehicle.sim.scenario.home)
    return link.frame


def build_sensors(vehicle: LockStepVehicle, options: SensorOptions, seed: int) -> MissionSensors:
    """Build the mission's sensors on ``vehicle`` (see the module docstring); ``seed`` seeds their noise."""
    out = MissionSensors()
    try:
        _build(out, vehicle, options, seed)
    except BaseException:
        out.close()  # a render process already spawned goes with it
        raise
    return out


def _build(out: MissionSensors, vehicle: LockStepVehicle, options: SensorOptions, seed: int) -> None:
    sim = vehicle.sim
    scenario = sim.scenario
    model = CameraModel(width_px=int(options.camera_size[0]), height_px=int(options.camera_size[1]),
                        tilt_rad=math.radians(scenario.camera.tilt_deg), mount=scenario.camera.mount)
    if options.camera and options.camera_lag and options.render_process:
        # Spawned first: its imports and its world are made while the radar is calibrated here.
        out.render_process = RenderProcess(model, scenario.camera_world, seed)
    if options.radar and scenario.radar is not None:
        cfg = scenario.radar
        if options.radar_pose == "calibrated":
            fix = calibrated_radar_pose(cfg, scenario.home, seed)
        else:
            fix = surveyed_radar_pose(cfg, scenario.home, seed)
        pose = fix.in_frame(_mission_frame(vehicle))
        queue = QueueDatagramSource()
        sim.add_radar_consumer(queue.push)
        noise = RadarNoise(cfg.sigma_range_m, cfg.sigma_az_rad, cfg.sigma_el_rad)
        out.radar = RadarFeed(queue, pose, noise=noise, correlator="gated", time_offset_s=0.0)
        out.radar_pose, out.radar_queue = fix, queue
        out.resources["radar"] = out.radar
    if options.camera:
        targets: list[tuple[SimTarget, Any]] = []
        if options.camera_detection:
            targets += [(SimTarget(intruder.spec.airframe, intruder), _always) for intruder in sim.intruders]
            targets += [(SimTarget(tg.kind, tg.path, k), tg.present) for k, tg in enumerate(scenario.targets)]
        out.frame_source = ScenarioFrameSource(sim, model, targets, seed, scenario.camera_world, out.render_process)
        pipeline = VisionPipeline(model, _SharedDetector(detector_threads(beside_renderer=out.render_process is not None)))
        if options.camera_lag:
            out.camera = LaggedCamera(out.frame_source, pipeline, whole_frames=options.whole_frames)
        else:
            out.camera = CameraSensor(out.frame_source, pipeline, whole_frames=options.whole_frames)
        out.resources["camera"] = out.camera
    if options.telemetry and sim.intruders:
        out.telemetry = vehicle.attach_target_telemetry()
        out.resources["target_telemetry"] = out.telemetry
