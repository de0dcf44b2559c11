"""The flight recorder: a recorded flight reads back with every channel and schema; recording does not
change the flight; camera frames and the belief map are kept for Foxglove; a SIGKILL loses at most a second."""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import cv2
import numpy as np
import py_trees
import pytest
from log_flight import fly
from mcap.reader import make_reader
from scipy.spatial.transform import Rotation

from chaser_bt.clock import ManualClock
from chaser_bt.log import schemas as S
from chaser_bt.log.recorder import attach_recorder
from chaser_bt.log.replay import flight_trace, read_log
from chaser_bt.mission.runner import MissionRunner
from chaser_bt.search.belief import BeliefGrid, GridSpec
from chaser_bt.search.session import SearchSnapshot
from chaser_bt.tree import load_tree_text
from chaser_bt.vehicle import VehicleLink
from chaser_bt.vehicle.pipe import byte_pipe
from chaser_bt.vision.frame_source import Frame
from chaser_bt.vision.pipeline import OwnshipPose

HERE = Path(__file__).resolve().parent
FLIGHT_TOPICS = {S.TOPIC_MAVLINK_READ, S.TOPIC_MAVLINK_IN, S.TOPIC_MAVLINK_OUT, S.TOPIC_TREE, S.TOPIC_BLACKBOARD,
                 S.TOPIC_RADAR_DATAGRAMS, S.TOPIC_RADAR_PICTURE, S.TOPIC_TARGET, S.TOPIC_SCENE_RADAR,
                 S.TOPIC_SCENE_TARGET, S.TOPIC_TF}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "radar_hop.mcap"
    runner, recorder = fly(path)
    return path, runner, recorder


def test_recorded_flight_reads_back_with_every_channel_and_schema(recorded):
    path, runner, recorder = recorded
    with path.open("rb") as fh:  # the mcap package's own reader, through the file's summary
        reader = make_reader(fh)
        summary = reader.get_summary()
        topics = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
        per_topic = {c.topic: summary.statistics.channel_message_counts[c.id] for c in summary.channels.values()}
        messages = list(reader.iter_messages())
    assert set(topics) == FLIGHT_TOPICS
    assert per_topic == recorder.counts  # nothing lost between the recorder and the file
    assert len(messages) == sum(recorder.counts.values())
    for topic, schema in topics.items():
        spec = S.CHANNELS[topic]
        assert (schema.name, schema.encoding, schema.data) == (spec.schema_name, spec.schema_encoding, spec.schema_data)
    log = read_log(path)
    assert not log.truncated and log.meta["tree"] == runner.tree.name
    for msg in log.messages:  # every payload decodes with its schema; JSON carries exactly the schema's fields
        value = log.decode(msg)
        encoding, data = log.schemas[msg.schema_name]
        if encoding == "jsonschema":
            assert set(value) <= set(json.loads(data)["properties"]), msg.topic
    # One tree record per tick plus one for the stop, and they carry the runner's tick log exactly.
    assert recorder.counts[S.TOPIC_TREE] == runner.ticks + 1
    ticks = [log.decode(m) for m in log.topic(S.TOPIC_TREE)]
    assert [(c["node"], c["old"], c["new"]) for r in ticks for c in r["changes"]] == \
        [(c.node, c.old, c.new) for c in runner.tick_log]
    # Every blackboard write of the mission's clock is there, in order, with its value.
    times = [log.decode(m)["value"] for m in log.topic(S.TOPIC_BLACKBOARD) if log.decode(m)["key"] == "/mission/time_s"]
    assert times == pytest.approx([r["t"] for r in ticks[:-1]])
    # MAVLink both ways, decoded; the radar's association marks the ownship.
    out_types = {log.decode(m)["type"] for m in log.topic(S.TOPIC_MAVLINK_OUT)}
    assert {"HEARTBEAT", "COMMAND_LONG"} <= out_types
    pictures = [log.decode(m) for m in log.topic(S.TOPIC_RADAR_PICTURE)]
    assert any(p["ownship_ids"] for p in pictures)
    scene = log.decode(log.topic(S.TOPIC_SCENE_RADAR)[-1])
    assert {e.id for e in scene.entities} == {f"radar/{t['id']}" for t in pictures[-1]["tracks"]}


def test_recording_does_not_change_the_flight(recorded):
    _, runner, _ = recorded
    bare, _ = fly(None)
    assert bare.tick_log == runner.tick_log


def test_belief_and_camera_frames_are_recorded_for_foxglove(tmp_path):
    """A hand-driven mission: a belief written to the blackboard and frames read from the camera."""
    spec = GridSpec((-10.0, 0.0, 0.0), 10.0, (3, 2, 2))
    p = np.arange(12, dtype=float).reshape(3, 2, 2) / 66.0
    snapshot = SearchSnapshot(t=1.0, belief=BeliefGrid(spec, p), gain=0.1, target_enu=np.zeros(3), yaw_enu_rad=None,
                              plan=None, replanned=True)
    image = np.zeros((48, 64, 3), np.uint8)
    image[10:20, 30:40] = (0, 200, 255)

    class Source:
        def read(self, t):
            return Frame(t, image, int(round(t * 10)))

    class Pipeline:
        track = type("T", (), {"box": (30.0, 10.0, 40.0, 20.0)})()

    class Sensor:
        def __init__(self):
            self.source, self.pipeline, self.last_frame = Source(), Pipeline(), None

        def step(self, t):
            self.last_frame = self.source.read(t)

    _, ground = byte_pipe()
    clock = ManualClock(0.0)
    link = VehicleLink.over_pipe(ground, monotonic=clock.now)
    runner = MissionRunner(load_tree_text("version: 1\ntrees:\n  T: {Wait: {duration_s: 100}}\n", source="<t>"), link, clock)
    sensor = Sensor()
    runner.setup()
    recorder = attach_recorder(runner, link, {"camera": sensor}, tmp_path / "cam.mcap", frame_format="png",
                               frame_period_s=0.0)
    writer = py_trees.blackboard.Client(name="search")
    writer.register_key("/search/belief", access=py_trees.common.Access.WRITE)
    for k in range(3):
        clock.set(1.0 + 0.1 * k)
        sensor.step(clock.now())
        writer.set("/search/belief", snapshot)
        runner.tick()
    recorder.close()
    log = read_log(tmp_path / "cam.mcap")
    images = [log.decode(m) for m in log.topic(S.TOPIC_CAMERA)]
    assert len(images) == 3 and {i.format for i in images} == {"png"}
    back = cv2.imdecode(np.frombuffer(images[0].data, np.uint8), cv2.IMREAD_COLOR)
    assert np.array_equal(back, image)  # png: lossless
    boxes = [log.decode(m) for m in log.topic(S.TOPIC_CAMERA_BOXES)]
    assert len(boxes) == 3
    assert [(q.x, q.y) for q in boxes[0].points[0].points] == [(30, 10), (40, 10), (40, 20), (30, 20)]
    # The belief once per second at most, summed over altitude; cell centres as the grid has them.
    assert len(log.topic(S.TOPIC_BELIEF)) == 1
    belief = flight_trace(log).beliefs[0]
    assert np.allclose(belief.mass, p.sum(axis=2))
    assert np.allclose(belief.x_m, [-10.0, 0.0, 10.0]) and np.allclose(belief.y_m, [0.0, 10.0])


def test_a_lagged_camera_is_recorded_frame_by_frame_as_its_shots_are_developed(tmp_path):
    """A rehearsal's camera develops each shot a tick later: each frame is recorded once, whole, with its box."""
    from chaser_bt.vision.lagged_camera import LaggedCamera

    shots: list = []

    class Source:
        reads_regions = True  # the recorder's wrapper reads whole frames: the shots must come whole

        def shot(self, t, regions=None):
            shots.append(regions)
            return t

        def develop(self, shot, regions=None):
            return Frame(shot, np.full((24, 32, 3), int(shot * 100), np.uint8), int(round(shot * 10)))

    class Pipeline:
        track = type("T", (), {"box": (1.0, 2.0, 5.0, 6.0)})()

        def plan(self, t, ownship, cue):
            raise AssertionError("a whole-frame source is not planned for at the shot")

        def process(self, frame, ownship, target_range_m, cue, plan):
            return None

    _, ground = byte_pipe()
    clock = ManualClock(0.0)
    link = VehicleLink.over_pipe(ground, monotonic=clock.now)
    runner = MissionRunner(load_tree_text("version: 1\ntrees:\n  T: {Wait: {duration_s: 100}}\n", source="<t>"), link, clock)
    camera = LaggedCamera(Source(), Pipeline())
    runner.setup()
    recorder = attach_recorder(runner, link, {"camera": camera}, tmp_path / "lag.mcap", frame_format="png", frame_period_s=0.0)
    pose = OwnshipPose(0.0, np.zeros(3), np.zeros(3), Rotation.identity())
    for k in range(4):
        clock.set(1.0 + 0.1 * k)
        camera.step(clock.now(), pose)
        runner.tick()
    recorder.close()
    log = read_log(tmp_path / "lag.mcap")
    images = [cv2.imdecode(np.frombuffer(log.decode(m).data, np.uint8), cv2.IMREAD_COLOR) for m in log.topic(S.TOPIC_CAMERA)]
    assert shots == [None] * 4
    assert [int(i[0, 0, 0]) for i in images] == [100, 110, 120]  # frames 1.0, 1.1, 1.2: the last is still in flight
    assert len(log.topic(S.TOPIC_CAMERA_BOXES)) == 3


def test_a_threaded_camera_is_recorded_from_its_results_on_the_ticks_thread(tmp_path):
    from chaser_bt.clock import WallClock
    from chaser_bt.vision.camera import CameraModel
    from chaser_bt.vision.detection import Detection
    from chaser_bt.vision.perception import PerceptionWorker
    from chaser_bt.vision.pipeline import CameraSensor, OwnshipPose, PipelineConfig, VisionPipeline

    class Source:
        """Gives a frame only when the test lets one through, so no result lands between the test's reads."""

        def __init__(self):
            self.reads = 0
            self.gate = threading.Semaphore(0)

        def read(self, t):
            if not self.gate.acquire(timeout=0.01):
                return None
            self.reads += 1
            return Frame(t, np.full((48, 64, 3), self.reads % 250, np.uint8), self.reads)

        def close(self):
            pass

    config = PipelineConfig(detect_every=1, tracker_kinds=(), confirm_hits=1, focus=False)
    pipeline = VisionPipeline(CameraModel(width_px=64, height_px=48, tilt_rad=0.0),
                              lambda image: [Detection((30.0, 10.0, 40.0, 20.0), 0.9, 0, "s1000")], config)
    source = Source()
    wall = WallClock()
    worker = PerceptionWorker(CameraSensor(source, pipeline), wall, max_fps=100.0)
    _, ground = byte_pipe()
    clock = ManualClock(0.0)
    link = VehicleLink.over_pipe(ground, monotonic=clock.now)
    runner = MissionRunner(load_tree_text("version: 1\ntrees:\n  T: {Wait: {duration_s: 100}}\n", source="<t>"), link, clock)
    runner.setup()
    recorder = attach_recorder(runner, link, {"camera": worker}, tmp_path / "cam.mcap", frame_format="png",
                               frame_period_s=0.0)
    assert worker.sensor.source is source  # not wrapped: it is read in the worker's thread, records are written on the tick's
    worker.start()
    results = []
    try:
        for k in range(3):
            worker.submit(OwnshipPose(wall.now(), np.array([0.0, 0.0, 20.0]), np.zeros(3), Rotation.identity()))
            source.gate.release()  # one frame, then none until the next round
            for _ in range(2000):  # its result (bounded: only a broken worker runs out)
                latest = worker.latest()
                if latest is not None and latest.estimate is not None and latest.frame.index == k + 1:
                    break
                worker._stop.wait(0.01)
            results.append(worker.latest())
            assert results[-1].frame.index == k + 1
            clock.set(1.0 + 0.1 * k)
            runner.tick()
            runner.tick()  # a tick without a new result records nothing more
    finally:
        worker.stop()
    recorder.close()
    log = read_log(tmp_path / "cam.mcap")
    images = [log.decode(m) for m in log.topic(S.TOPIC_CAMERA)]
    assert len(images) == len({id(r) for r in results}) == 3
    for image, result in zip(images, results):
        assert np.array_equal(cv2.imdecode(np.frombuffer(image.data, np.uint8), cv2.IMREAD_COLOR), result.frame.image)
    boxes = [log.decode(m) for m in log.topic(S.TOPIC_CAMERA_BOXES)]
    assert len(boxes) == 3 and [(q.x, q.y) for q in boxes[0].points[0].points] == [(30, 10), (40, 10), (40, 20), (30, 20)]


@pytest.mark.slow
def test_sigkill_mid_flight_loses_at_most_the_last_second(tmp_path):
    path = tmp_path / "killed.mcap"
    child = subprocess.Popen([sys.executable, str(HERE / "log_kill_child.py"), str(path)], stdout=subprocess.PIPE,
                             text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    printed: list[tuple[float, float]] = []  # (mission time, wall time) of every tick the child made
    try:
        for line in child.stdout:
            t, wall = (float(v) for v in line.split())
            printed.append((t, wall))
            if t - printed[0][0] >= 3.5:  # mid-flight, climbing: several flush periods in
                child.send_signal(signal.SIGKILL)
                break
        printed += [tuple(float(v) for v in line.split()) for line in child.stdout]
    finally:
        child.kill()
        child.wait(timeout=10)
    assert child.returncode == -signal.SIGKILL
    log = read_log(path)
    assert log.truncated  # no footer: the process never finished the file
    recorded_ticks = [m.json()["t"] for m in log.topic(S.TOPIC_TREE)]
    assert recorded_ticks == [t for t, _ in printed[:len(recorded_ticks)]]  # a prefix of what happened
    wall_at = dict(printed)
    lost_s = printed[-1][1] - wall_at[recorded_ticks[-1]]
    assert 0.0 <= lost_s <= 1.1, f"{lost_s:.2f} s of ticks lost"


def test_record_and_live_flags_attach_a_recorder_through_the_hook(tmp_path):
    from chaser_bt.log.commands import (
        RecordingError,
        RecordingHook,
        add_recording_arguments,
    )
    from chaser_bt.log.live import DEFAULT_PORT

    parser = argparse.ArgumentParser()
    add_recording_arguments(parser)
    assert RecordingHook.from_args(parser.parse_args([])) is None
    assert parser.parse_args(["--live"]).live == DEFAULT_PORT
    hook = RecordingHook.from_args(parser.parse_args(["--record", str(tmp_path / "f.mcap"), "--live", "0"]))
    assert hook.live is not None and hook.live.port > 0  # started at once: a taken port stops the command early
    with pytest.raises(RecordingError, match=f"--live {hook.live.port}: .*in use"):
        RecordingHook.from_args(parser.parse_args(["--live", str(hook.live.port)]))
    with pytest.raises(SystemExit):  # --record's folder is checked as the command line is read
        parser.parse_args(["--record", str(tmp_path / "nowhere" / "f.mcap")])
    with pytest.raises(RecordingError, match="no such folder"):  # ... and again by the hook, for callers without it
        RecordingHook(tmp_path / "nowhere" / "f.mcap", None)
    _, ground = byte_pipe()
    clock = ManualClock(1.0)
    link = VehicleLink.over_pipe(ground, monotonic=clock.now)
    tree = load_tree_text("version: 1\ntrees:\n  T: {Wait: {duration_s: 0.15}}\n", source="<t>")
    runner = MissionRunner(tree, link, clock)
    runner.setup()
    hook(runner, type("Vehicle", (), {"link": link})())  # the rehearsal's on_start(runner, vehicle, resources)
    while not runner.finished:
        runner.tick()
        clock.advance(0.1)
    runner.stop("done")
    hook.close()
    assert hook.live.closed
    log = read_log(tmp_path / "f.mcap")
    assert not log.truncated
    ticks = [m.json() for m in log.topic(S.TOPIC_TREE)]
    assert [r["tick"] for r in ticks] == [1, 2, 3, None] and ticks[2]["root"] == "SUCCESS"
    assert ticks[-1]["changes"] == [{"node": "Wait", "old": "SUCCESS", "new": "INVALID"}]


def test_the_signing_key_never_reaches_the_log(tmp_path):
    from chaser_bt.vehicle import LinkConfig
    from chaser_bt.vehicle.signing import SigningConfig

    key = bytes(range(100, 132))
    _, ground = byte_pipe()
    clock = ManualClock(1.0)
    link = VehicleLink.over_pipe(ground, LinkConfig(signing=SigningConfig(key=key)), monotonic=clock.now)
    runner = MissionRunner(load_tree_text("version: 1\ntrees:\n  T: {Wait: {duration_s: 1}}\n", source="<t>"), link, clock)
    runner.setup()
    recorder = attach_recorder(runner, link, {}, tmp_path / "signed.mcap")
    link.poll()  # sends a (signed) heartbeat, recorded on /mavlink/out
    runner.tick()
    recorder.close()
    log = read_log(tmp_path / "signed.mcap")
    # The file as stored (metadata is not compressed) and every payload decompressed.
    data = (tmp_path / "signed.mcap").read_bytes() + b"".join(m.data for m in log.messages)
    assert log.meta["link_signed"] == "true" and "signing" not in json.loads(log.meta["link_config"])
    assert log.topic(S.TOPIC_MAVLINK_OUT)
    for form in (key, key.hex().encode(), S.b64(key).encode(), json.dumps(list(key)).encode()):
        assert form not in data
