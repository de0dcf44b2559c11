"""The simulator's camera as a FrameSource: renders from the chaser's true pose and the targets' paths."""

from __future__ import annotations

import numpy as np
from mavlink_gcs import quick_scenario

from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.frame_source import FrameSource
from sitl.simulator import Simulator
from sitl.world.camera.frame_source import SimTarget, SimulatorFrameSource
from sitl.world.targets import WaypointPath


def test_simulator_frame_source_sees_a_target_ahead_of_the_parked_chaser():
    sim = Simulator(quick_scenario(), 0)
    sim.run_until(0.5)
    truth = sim.truth
    heading = truth.attitude.apply([1.0, 0.0, 0.0])
    # A target 12 m ahead along the chaser's nose, 1 m lower than the camera's axis would put it.
    p = truth.pos_enu + 12.0 * heading * np.array([1, 1, 0]) + np.array([0.0, 0.0, 1.0])
    path = WaypointPath((tuple(p), tuple(p + np.array([10.0, 0.0, 0.0]))), speed_mps=2.0)
    cam = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
    src = SimulatorFrameSource(sim, cam, [SimTarget("phantom", path)], seed=1)
    assert isinstance(src, FrameSource)
    f1 = src.read(10.0)
    sim.run_until(1.0)
    f2 = src.read(10.5)
    assert f1.image.shape == (240, 320, 3) and (f1.t, f2.t) == (10.0, 10.5) and (f1.index, f2.index) == (0, 1)
    assert len(src.last_labels) == 1 and src.last_labels[0].kind == "phantom"
