"""The camera drawn in a render process: the same frames as drawn here, failures said, clean stops."""

from __future__ import annotations

import os

import numpy as np
import pytest
from mavlink_gcs import quick_scenario

from chaser_bt.vision.camera import CameraModel
from sitl.simulator import Simulator
from sitl.world.camera.frame_source import Shot, SimTarget, SimulatorFrameSource
from sitl.world.camera.render_process import RenderProcess
from sitl.world.camera.world import WorldSpec, build_world
from sitl.world.targets import WaypointPath

CAM = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
SPEC = WorldSpec(family="suburb")  # clutter, birds, specks: every part of the renderer draws
SEED = 4


def _shots(n: int) -> list[Shot]:
    """Shots of a target ahead of a parked chaser, 0.1 s apart, the chaser turning as it arms."""
    sim = Simulator(quick_scenario(), 0)
    sim.run_until(0.5)
    truth = sim.truth
    ahead = truth.pos_enu + 15.0 * truth.attitude.apply([1.0, 0.0, 0.0]) * np.array([1, 1, 0]) + np.array([0.0, 0.0, 2.0])
    path = WaypointPath((tuple(ahead), tuple(ahead + np.array([5.0, 3.0, 1.0]))), speed_mps=3.0)
    taker = SimulatorFrameSource(sim, CAM, [SimTarget("phantom", path)], SEED)
    shots = []
    for k in range(n):
        sim.run_until(0.5 + 0.1 * k)
        shots.append(taker.shot(10.0 + 0.1 * k))
    return shots


def test_frames_drawn_in_the_render_process_are_the_frames_drawn_here_byte_for_byte():
    shots = _shots(6)
    regions = [None, ((100, 60, 220, 180),), ((0, 0, 80, 80), (200, 150, 300, 230)), None, ((120, 90, 200, 170),), None]
    here = SimulatorFrameSource(None, CAM, [], SEED, world=build_world(SPEC, SEED, CAM.width_px, CAM.height_px))
    expected = []
    for shot, reg in zip(shots, regions):
        frame = here.develop(shot, reg)
        expected.append((frame.image, frame.regions, here.last_labels))
    assert any(labels for _, _, labels in expected)  # the target is in some frames: labels are compared too
    with RenderProcess(CAM, SPEC, SEED) as rp:
        drawn = []
        for k, (shot, reg) in enumerate(zip(shots, regions)):
            rp.submit(shot, reg)  # one in flight ahead, as a rehearsal keeps it
            if k:
                drawn.append(rp.collect())
        drawn.append(rp.collect())
        assert rp.in_flight == 0 and all(ms > 0 for *_, ms in drawn)
        got = [d[:3] for d in drawn]
    for (image, views, labels), (want_image, want_views, want_labels) in zip(got, expected):
        assert np.array_equal(image, want_image)
        assert views == want_views and labels == want_labels


def test_a_failure_in_the_render_process_comes_back_with_its_traceback():
    shot = _shots(1)[0]
    broken = Shot(shot.t, shot.sim_t, shot.index, shot.position_enu, shot.attitude,
                  (shot.targets[0].__class__("no-such-kind", shot.targets[0].position_enu),), shot.blur_px)
    with RenderProcess(CAM, SPEC, SEED) as rp:
        rp.submit(broken, None)
        with pytest.raises(RuntimeError, match="render process failed(.|\n)*no-such-kind"):
            rp.collect()
    with RenderProcess(CAM, SPEC, SEED) as rp, pytest.raises(RuntimeError, match="no shot submitted"):
        rp.collect()


def test_a_third_shot_in_flight_is_refused_before_it_could_overwrite_a_frame_not_collected():
    a, b, c = _shots(3)
    with RenderProcess(CAM, SPEC, SEED) as rp:
        rp.submit(a, None)
        rp.submit(b, None)
        with pytest.raises(RuntimeError, match="2 shots already in flight"):
            rp.submit(c, None)
        first = rp.collect()[0]
        rp.submit(c, None)  # a slot is free again
        assert rp.in_flight == 2 and first.shape == (CAM.height_px, CAM.width_px, 3)


def test_closing_with_a_frame_in_flight_stops_the_child_and_removes_the_frame_slots():
    shot = _shots(1)[0]
    rp = RenderProcess(CAM, SPEC, SEED)
    rp.submit(shot, None)
    path = rp._path
    assert os.path.exists(path)
    rp.close()
    assert not rp._proc.is_alive() and rp._proc.exitcode == 0
    assert not os.path.exists(path)


def test_the_child_says_when_its_world_is_built_and_a_world_it_cannot_build_is_said_at_once():
    with RenderProcess(CAM, SPEC, SEED) as rp:
        took = rp.wait_ready()
        assert took > 0 and rp.wait_ready() == took  # heard once, remembered
        rp.submit(_shots(1)[0], None)
        assert rp.collect()[0].shape == (CAM.height_px, CAM.width_px, 3)
    with RenderProcess(CAM, WorldSpec(family="no-such-family"), SEED) as rp:
        with pytest.raises(RuntimeError, match="render process failed(.|\n)*no-such-family"):
            rp.wait_ready()


def test_the_child_starts_on_one_thread_without_numpy_huge_pages_and_the_parent_environment_is_left_alone(monkeypatch):
    monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE", raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "2")  # the parent's own setting: the child overrides it, the parent keeps it
    with RenderProcess(CAM, SPEC, SEED) as rp:
        rp.wait_ready()  # exec'd by now: before, /proc shows the parent's environment as it started
        environ = f"/proc/{rp._proc.pid}/environ"
        if not os.path.exists(environ):
            pytest.skip("no /proc here to read the child's environment from")
        with open(environ, "rb") as f:
            child_env = f.read().split(b"\0")
    assert b"NUMPY_MADVISE_HUGEPAGE=0" in child_env and b"OMP_NUM_THREADS=1" in child_env
    assert "NUMPY_MADVISE_HUGEPAGE" not in os.environ and os.environ["OMP_NUM_THREADS"] == "2"
