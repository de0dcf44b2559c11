"""The perception worker: the camera pipeline in its own threads, the tick reading its latest result.

No timing asserts: the tick's reads are shown not to wait by making them while the worker is held
inside the detector; waits for the worker are bounded polls that only fail a broken worker.
"""

from __future__ import annotations

import threading

import numpy as np
import py_trees
import pytest
from scipy.spatial.transform import Rotation

from chaser_bt.clock import WallClock
from chaser_bt.tree import load_tree_text
from chaser_bt.vehicle.state import VehicleState
from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detection import Detection
from chaser_bt.vision.frame_source import Frame
from chaser_bt.vision.perception import PerceptionWorker, PipelineSetup
from chaser_bt.vision.pipeline import CameraSensor, OwnshipPose, PipelineConfig, VisionPipeline

Status = py_trees.common.Status
CAM = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
BOX = (150.0, 110.0, 170.0, 130.0)  # centred: the bearing is the camera's axis, east
WAIT_S = 20.0  # only a broken worker takes this long


class _Source:
    """A camera that always has a new frame; counts its reads, raises on the ones listed in ``fail``."""

    def __init__(self, fail: tuple[int, ...] = ()) -> None:
        self.reads, self.fail, self.closed = 0, fail, False

    def read(self, t):
        self.reads += 1
        if self.reads in self.fail:
            raise OSError("camera glitch")
        return Frame(t, np.zeros((240, 320, 3), np.uint8), self.reads)

    def close(self):
        self.closed = True


class _Detector:
    """One box in the middle; raises ``errors`` (exception instances) on its first calls, in order."""

    def __init__(self, errors=()) -> None:
        self.errors, self.calls = list(errors), 0

    def __call__(self, image):
        self.calls += 1
        if self.errors:
            raise self.errors.pop(0)
        return [Detection(BOX, 0.9, 0, "s1000")]


class _GatedDetector(_Detector):
    """Holds the processing thread inside the detector until released."""

    def __init__(self) -> None:
        super().__init__()
        self.inside, self.release = threading.Event(), threading.Event()

    def __call__(self, image):
        self.inside.set()
        assert self.release.wait(3 * WAIT_S)  # longer than the test waits for a tick: a blocked tick fails the test
        self.release.clear()
        return super().__call__(image)


class _Fatal(BaseException):
    """Not an Exception: nothing in the worker's loop catches it (like a bug that kills a thread)."""


def _sensor(detector, source=None) -> CameraSensor:
    config = PipelineConfig(detect_every=1, tracker_kinds=(), confirm_hits=1, focus=False)
    return CameraSensor(source or _Source(), VisionPipeline(CAM, detector, config))


def _pose(clock) -> OwnshipPose:
    return OwnshipPose(clock.now(), np.array([0.0, 0.0, 20.0]), np.zeros(3), Rotation.identity())


def _until(condition, what: str) -> None:
    done = threading.Event()
    for _ in range(int(WAIT_S / 0.01)):
        if condition():
            return
        done.wait(0.01)
    raise AssertionError(f"the worker never got to: {what}")


@pytest.fixture
def clock():
    return WallClock()


def test_the_worker_publishes_the_estimate_of_the_newest_frame_with_its_time(clock):
    worker = PerceptionWorker(_sensor(_Detector()), clock, max_fps=200.0)
    worker.start()
    try:
        assert worker.latest() is None and "no frame processed yet" in worker.health(clock.now())
        worker.submit(_pose(clock))
        _until(lambda: worker.latest() is not None and worker.latest().estimate is not None, "an estimate")
        result = worker.latest()
        est = result.estimate
        assert est.source == "vision" and est.t == result.frame.t  # the frame's time, not the tick's
        assert est.bearing_enu == pytest.approx([1.0, 0.0, 0.0], abs=1e-9)
        assert result.box == pytest.approx(BOX) and worker.last_frame is result.frame
        assert worker.health(clock.now()) is None
        stats = worker.stats()
        assert stats.running and stats.frames_processed >= 1 and stats.errors == 0
    finally:
        assert worker.stop()


def test_the_tick_reads_and_submits_while_the_worker_is_inside_the_detector(clock):
    det = _GatedDetector()
    worker = PerceptionWorker(_sensor(det), clock, max_fps=200.0)
    worker.start()
    try:
        worker.submit(_pose(clock))
        assert det.inside.wait(WAIT_S)
        det.inside.clear()
        det.release.set()  # first frame through
        _until(lambda: worker.latest() is not None, "the first result")
        assert det.inside.wait(WAIT_S)  # the worker now holds the second frame, inside the detector
        # What ticks do, in another thread so a tick that waited on the worker fails the test instead of hanging it.
        seen = []
        tick = threading.Thread(target=lambda: seen.extend([worker.latest(), worker.configure(PipelineSetup()),
                                                            worker.submit(_pose(clock)), worker.latest(),
                                                            worker.health(clock.now())]))
        tick.start()
        tick.join(WAIT_S)
        assert not tick.is_alive() and seen, "the tick waited for the frame being processed"
        first = seen[0]
        assert first.sequence == 1 and seen[3] is first  # the previous result, while the worker is on the next frame
        assert det.calls == 1 and det.inside.is_set()
        det.release.set()
        _until(lambda: worker.latest().sequence > first.sequence, "the second result")
    finally:
        det.release.set()
        assert worker.stop()


def test_an_exception_in_processing_or_reading_is_counted_and_the_worker_goes_on(clock):
    det = _Detector(errors=[RuntimeError("bad tensor"), ValueError("bad box")])
    worker = PerceptionWorker(_sensor(det, _Source(fail=(2,))), clock, max_fps=200.0)
    worker.start()
    try:
        worker.submit(_pose(clock))
        _until(lambda: worker.latest() is not None and worker.latest().estimate is not None, "an estimate after errors")
        stats = worker.stats()
        assert stats.running and stats.errors == 2 and stats.read_errors == 1
        assert stats.last_error in ("ValueError: bad box", "OSError: camera glitch")
        assert worker.health(clock.now()) is None
    finally:
        assert worker.stop()


def test_stop_joins_both_threads_and_close_closes_the_source(clock):
    source = _Source()
    worker = PerceptionWorker(_sensor(_Detector(), source), clock, max_fps=200.0)
    worker.start()
    threads = [t for t in threading.enumerate() if t.name.startswith("perception-")]
    assert {t.name for t in threads} == {"perception-capture", "perception-process"} and all(t.daemon for t in threads)
    worker.close()
    assert not any(t.is_alive() for t in threads) and source.closed
    assert not worker.running and worker.health(clock.now()) == "perception worker stopped"
    worker.start()  # a stopped worker starts again
    try:
        assert worker.running
    finally:
        assert worker.stop()


def test_a_worker_whose_thread_died_says_so(clock):
    worker = PerceptionWorker(_sensor(_Detector(errors=[_Fatal("segfault-like")])), clock, max_fps=200.0)
    worker.start()
    worker.submit(_pose(clock))
    _until(lambda: not worker.running, "dying")
    assert worker.health(clock.now()) == "perception worker died: _Fatal: segfault-like"
    assert worker.stop()


def test_frames_are_not_processed_without_fresh_inputs_from_the_tick(clock):
    det = _Detector()
    worker = PerceptionWorker(_sensor(det), clock, max_fps=200.0, stale_after_s=0.5)
    worker.start()
    try:
        _until(lambda: worker.stats().frames_dropped >= 3, "dropping frames")
        assert det.calls == 0 and worker.latest() is None
        pose = _pose(clock)
        worker.submit(OwnshipPose(pose.t - 5.0, pose.position_enu, pose.velocity_enu, pose.attitude))  # a tick long ago
        dropped = worker.stats().frames_dropped
        _until(lambda: worker.stats().frames_dropped >= dropped + 3, "dropping frames with stale inputs")
        assert det.calls == 0
    finally:
        assert worker.stop()


def test_the_pose_is_carried_to_the_frame_time_along_the_velocity():
    seen = []

    class Pipeline(VisionPipeline):
        def process(self, frame, ownship, target_range_m=None, cue=None):
            seen.append((frame.t, ownship))
            return None

    clock = WallClock()
    sensor = CameraSensor(_Source(), Pipeline(CAM, _Detector(), PipelineConfig(tracker_kinds=())))
    worker = PerceptionWorker(sensor, clock, max_fps=200.0)
    worker.start()
    try:
        t0 = clock.now()
        worker.submit(OwnshipPose(t0, np.array([0.0, 0.0, 20.0]), np.array([2.0, 0.0, 0.0]), Rotation.identity()))
        _until(lambda: len(seen) >= 2, "processing")
    finally:
        assert worker.stop()
    t, pose = seen[-1]
    assert pose.t == t and pose.position_enu == pytest.approx([2.0 * (t - t0), 0.0, 20.0])


def test_a_pipeline_setup_is_applied_once_and_keeps_the_tracks():
    pipeline = VisionPipeline(CAM, _Detector(), PipelineConfig(detect_every=3, tracker_kinds=()))
    other = _Detector()
    setup = PipelineSetup(other, "other", ("phantom",), True, 2)
    setup.apply(pipeline)
    assert pipeline.detector is other and pipeline.detector_name == "other"
    assert pipeline.config.classes == ("phantom",) and pipeline.config.target_on_ground and pipeline.config.detect_every == 2
    pipeline.frames = 7  # use_detector would reset this
    setup.apply(pipeline)
    assert pipeline.frames == 7
    PipelineSetup().apply(pipeline)  # the camera's own detector, its classes, flat-ground off
    assert pipeline.detector is other and pipeline.config.classes == ("phantom",) and not pipeline.config.target_on_ground
    assert pipeline.frames == 0


# -- the VisionPipeline behaviour with a threaded camera ------------------------------------------------


def _tree(camera, clock):
    tree = load_tree_text("version: 1\ntrees:\n  Test:\n    VisionPipeline: {}\n", source="<test>")
    bt = py_trees.trees.BehaviourTree(tree.root)
    bt.setup(link=object(), clock=clock, camera=camera)
    return bt


def _blackboard():
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
    bb.register_key("/target/estimate", access=py_trees.common.Access.READ)
    bb.set("/vehicle/state", VehicleState(position_enu=np.array([0.0, 0.0, 20.0]), velocity_enu=np.zeros(3),
                                          attitude=Rotation.identity()))
    return bb


def test_the_behaviour_starts_the_worker_and_writes_its_latest_estimate(clock):
    bb = _blackboard()
    worker = PerceptionWorker(_sensor(_Detector()), clock, max_fps=200.0)
    bt = _tree(worker, clock)
    try:
        assert worker.running  # setup started it
        bt.tick()
        assert bt.root.status == Status.FAILURE and "no frame processed yet" in bt.root.feedback_message
        _until(lambda: (bt.tick(), bt.root.status == Status.SUCCESS)[1], "a successful tick")
        est = bb.get("/target/estimate")
        assert est is worker.latest().estimate or est.t <= worker.latest().estimate.t
        assert est.t <= clock.now() and est.bearing_enu == pytest.approx([1.0, 0.0, 0.0], abs=1e-9)
    finally:
        worker.stop()


def test_the_behaviour_fails_saying_so_when_the_worker_stopped_or_died(clock):
    _blackboard()
    worker = PerceptionWorker(_sensor(_Detector()), clock, max_fps=200.0)
    bt = _tree(worker, clock)
    _until(lambda: (bt.tick(), bt.root.status == Status.SUCCESS)[1], "a successful tick")
    worker.stop()
    bt.tick()
    assert bt.root.status == Status.FAILURE and bt.root.feedback_message == "perception worker stopped"
    dying = PerceptionWorker(_sensor(_Detector(errors=[_Fatal("detector crashed")])), clock, max_fps=200.0)
    bt = _tree(dying, clock)
    _until(lambda: (bt.tick(), not dying.running)[1], "dying")
    bt.tick()
    assert bt.root.status == Status.FAILURE
    assert bt.root.feedback_message == "perception worker died: _Fatal: detector crashed"
    dying.stop()
