"""The rehearsal's camera one frame behind the tick: what it plans, draws and processes at each step."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.vision.frame_source import Frame
from chaser_bt.vision.pipeline import OwnshipPose
from chaser_bt.vision.lagged_camera import LaggedCamera
from sitl.world.camera.frame_source import Shot


class _Source:
    """Takes numbered shots and develops them, logging both; ``accept`` logs labels from elsewhere."""

    reads_regions = True

    def __init__(self, log: list) -> None:
        self.log = log
        self.index = 0

    def shot(self, t: float, regions=None) -> Shot:
        self.log.append(("shot", t, regions))
        self.index += 1
        return Shot(t, t, self.index - 1, np.zeros(3), Rotation.identity(), (), 0.0)

    def develop(self, shot: Shot, regions) -> Frame:
        self.log.append(("develop", shot.t, regions))
        return Frame(shot.t, np.zeros((4, 4, 3), np.uint8), shot.index, regions)



class _Plan:
    def __init__(self, t: float) -> None:
        self.t = t
        self.regions = ((0, 0, 2, 2),) if t < 1.0 else None


class _Pipeline:
    """Plans and processes, logging both; the estimate of a frame is its time."""

    def __init__(self, log: list) -> None:
        self.log = log

    def plan(self, t, ownship, cue):
        self.log.append(("plan", t))
        return _Plan(t)

    def process(self, frame, ownship, target_range_m, cue, plan):
        self.log.append(("process", frame.t, ownship.t, target_range_m, cue, None if plan is None else plan.t))
        return f"estimate of {frame.t}"


def _pose(t: float) -> OwnshipPose:
    return OwnshipPose(t, np.zeros(3), np.zeros(3), Rotation.identity())


def test_each_step_plans_and_shoots_its_frame_then_processes_the_last_one_with_that_ticks_inputs():
    log: list = []
    cam = LaggedCamera(_Source(log), _Pipeline(log))
    assert cam.step(0.0, _pose(0.0), 30.0, "cue0") is None  # nothing shot before: nothing to process
    assert log == [("plan", 0.0), ("shot", 0.0, ((0, 0, 2, 2),))] and cam.last_frame is None
    log.clear()
    assert cam.step(0.1, _pose(0.1), 31.0, "cue1") == "estimate of 0.0"
    # Frame 0.1 is planned (from the tracks frame 0.0 has not changed yet) and shot before frame 0.0
    # is drawn and processed, with the inputs and the plan of its own tick.
    assert log == [("plan", 0.1), ("shot", 0.1, ((0, 0, 2, 2),)), ("develop", 0.0, ((0, 0, 2, 2),)),
                   ("process", 0.0, 0.0, 30.0, "cue0", 0.0)]
    assert cam.last_frame.t == 0.0 and cam.last_frame.index == 0


def test_a_frame_older_than_stale_after_s_is_processed_but_gives_no_estimate():
    log: list = []
    cam = LaggedCamera(_Source(log), _Pipeline(log), stale_after_s=0.5)
    cam.step(0.0, _pose(0.0))
    assert cam.step(0.5, _pose(0.5)) == "estimate of 0.0"  # exactly stale_after_s old: still used
    log.clear()
    assert cam.step(1.2, _pose(1.2)) is None  # the node was not ticked for 0.7 s
    assert ("process", 0.5, 0.5, None, None, 0.5) in log and cam.last_frame.t == 0.5


def test_whole_frames_are_shot_without_a_plan_and_planned_when_processed():
    log: list = []
    cam = LaggedCamera(_Source(log), _Pipeline(log), whole_frames=True)
    cam.step(0.0, _pose(0.0))
    cam.step(0.1, _pose(0.1))
    assert log == [("shot", 0.0, None), ("shot", 0.1, None), ("develop", 0.0, None), ("process", 0.0, 0.0, None, None, None)]


class _WholeFrames(_Source):
    """A source that reads out whole frames only (the flight recorder's)."""

    reads_regions = False


def test_a_source_that_reads_whole_frames_gets_whole_shots_and_plans_made_when_processed():
    log: list = []
    cam = LaggedCamera(_WholeFrames(log), _Pipeline(log))
    cam.step(0.0, _pose(0.0))
    cam.step(0.1, _pose(0.1))
    assert log == [("shot", 0.0, None), ("shot", 0.1, None), ("develop", 0.0, None), ("process", 0.0, 0.0, None, None, None)]


class _SomeFrames(_Source):
    """Develops only the shots taken at whole seconds (a replayed log that kept some frames)."""

    def develop(self, shot: Shot, regions):
        return super().develop(shot, regions) if shot.t == int(shot.t) else None


def test_a_shot_the_source_has_no_frame_for_gives_no_estimate_and_keeps_the_last_frame():
    log: list = []
    cam = LaggedCamera(_SomeFrames(log), _Pipeline(log))
    cam.step(1.0, _pose(1.0))
    assert cam.step(1.1, _pose(1.1)) == "estimate of 1.0"
    assert cam.step(1.2, _pose(1.2)) is None  # frame 1.1 was not kept: nothing processed
    assert cam.last_frame.t == 1.0 and [e for e in log if e[0] == "process"] == [("process", 1.0, 1.0, None, None, 1.0)]
