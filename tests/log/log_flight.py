"""A short radar mission flown lock-step against the simulator, recorded: shared by the tests in tests/log/.

Boot is quick, the radar looks at the home area, an intruder circles 150 m north. The tree takes
off, waits for a validated radar track, takes its cue, hovers, and lands: status changes and
correlator associations on every tick, which is what replay has to reproduce.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import numpy as np

from chaser_bt.geo import GeoPoint
from chaser_bt.log.recorder import Recorder, attach_recorder
from chaser_bt.mission.runner import MissionRunner
from chaser_bt.radar.feed import RadarFeed, RadarNoise
from chaser_bt.radar.geometry import RadarPose
from chaser_bt.radar.stream import QueueDatagramSource
from chaser_bt.tree import load_tree_text, reset_blackboard
from sitl.bench.in_process import InProcessVehicle
from sitl.world.radar import RadarConfig
from sitl.world.scenario import BootParams, Scenario, ScriptedTarget
from sitl.world.targets import CirclePath

HOME = GeoPoint(42.5445, -71.6105, 80.0)
RADAR = RadarConfig(GeoPoint(42.5436, -71.6105, 81.0), pitch_rad=np.radians(10.0), pd=1.0)

TREE_TEXT = """\
version: 1
trees:
  RadarHop:
    Sequence:
      name: radar hop
      children:
        - ArmAndTakeoff: {altitude_m: 15}
        - RetryUntilSuccessful:
            num_attempts: -1
            child: {RadarTrackValidated: {min_confidence: 0.8, min_track_age_s: 1.0}}
        - ReactiveSequence:
            name: hold on the cue
            children:
              - RadarCue: {}
              - Hover: {duration_s: 6}
        - Land: {wait_landed: true}
"""


VISION_TREE_TEXT = """\
version: 1
trees:
  VisionHop:
    Sequence:
      name: vision hop
      children:
        - ArmAndTakeoff: {altitude_m: 15}
        - Timeout:
            msec: 3000
            child:
              KeepRunningUntilFailure:
                child: {ForceSuccess: {child: {VisionPipeline: {}}}}
"""


def scenario(time_limit_s: float = 120.0, vision: bool = False) -> Scenario:
    if vision:  # a target circling 40 m ahead of the camera (the ownship faces north)
        targets = (ScriptedTarget("intruder", CirclePath((0.0, 40.0, 16.0), 6.0, 2.0)),)
    else:
        targets = (ScriptedTarget("intruder", CirclePath((0.0, 150.0, 30.0), 30.0, 5.0)),)
    return Scenario("log-radar-hop", HOME, boot=BootParams(1.0, 2.0, 3.0), radar=RADAR, time_limit_s=time_limit_s,
                    targets=targets)


def fly(path: Path | None, seed: int = 3, *, time_limit_s: float = 120.0, pace: float | None = None, vision: bool = False,
        camera_lag: bool = False, on_tick: Callable[[MissionRunner], None] | None = None,
        on_start: Callable[[Recorder], None] | None = None, **record) -> tuple[MissionRunner, Recorder | None]:
    """Fly the radar hop lock-step as a rehearsal does, recording to ``path`` (None: no recording).

    ``pace``: simulated seconds per wall second (None: as fast as possible). ``vision``: fly the
    vision hop (the camera resource, :data:`VISION_TREE_TEXT`) instead, its camera inside the tick
    as on a flight flown inline, or a frame behind it as a rehearsal's (``camera_lag``).
    """
    reset_blackboard()
    tree = load_tree_text(VISION_TREE_TEXT if vision else TREE_TEXT, source="<log test>")
    v = InProcessVehicle(scenario(time_limit_s, vision), seed)
    queue = QueueDatagramSource()
    v.sim.add_radar_consumer(queue.push)
    # The radar's pose needs the ENU frame, which the link sets from HOME_POSITION: the vehicle
    # boots (and the radar scans) before the mission starts, as on a real field.
    v.run_until(lambda: v.link.frame is not None, 30)
    pose = RadarPose.from_geodetic(v.link.frame, RADAR.position, RADAR.yaw_rad, RADAR.pitch_rad, RADAR.roll_rad)
    feed = RadarFeed(queue, pose, noise=RadarNoise(RADAR.sigma_range_m, RADAR.sigma_az_rad, RADAR.sigma_el_rad))
    resources = {"radar": feed}
    if vision:
        from sitl.bench.sensors import SensorOptions, build_sensors

        options = SensorOptions(radar=False, telemetry=False, camera_size=(320, 240), camera_lag=camera_lag)
        resources = build_sensors(v, options, seed).resources
    runner = MissionRunner(tree, v.link, v.clock, resources=resources)
    runner.setup()
    recorder = attach_recorder(runner, v.link, runner.resources, path, **record) if path is not None or record else None
    if recorder is not None and on_start is not None:
        on_start(recorder)
    start = time.monotonic()
    try:
        while v.sim.time_s < time_limit_s:
            v.step()
            if runner.tick_if_due():
                if on_tick is not None:
                    on_tick(runner)
                if runner.finished:
                    runner.stop("done")
                    break
            if pace is not None:
                ahead = v.sim.time_s / pace - (time.monotonic() - start)
                if ahead > 0:
                    time.sleep(ahead)
    finally:
        if recorder is not None:
            recorder.close()
    return runner, recorder
