"""The ground stream: its wire format, the UDP sender, the documented receiver, and StreamToGround."""

from __future__ import annotations

import json
import logging
import math
import queue
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import py_trees
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.ground import (
    MAX_DATAGRAM,
    FrameAssembler,
    GroundSender,
    chunk_frame,
    parse_chunk,
    parse_datagram,
)
from chaser_bt.ground.protocol import (
    VIDEO_HEADER,
    Box,
    VideoChunk,
    draw_boxes,
    estimate_message,
    json_datagram,
    tracks_message,
)
from chaser_bt.radar.feed import RadarTrack

DOC = Path(__file__).resolve().parents[2] / "docs" / "ground.md"
RED = np.array([0, 0, 255])


# ----------------------------------------------------------------------------- wire format
@settings(max_examples=40, deadline=None)
@given(size=st.integers(0, 150_000), max_datagram=st.integers(200, 70_000), seed=st.integers(0, 2**16))
def test_chunks_fit_a_datagram_and_reassemble_in_any_order(size, max_datagram, seed):
    rng = np.random.default_rng(seed)
    jpeg = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
    chunks = chunk_frame(jpeg, 7, 1.25, max_datagram)
    room = max_datagram - VIDEO_HEADER.size
    assert len(chunks) == max(1, math.ceil(size / room))
    assert all(len(c) <= max_datagram for c in chunks)
    assembler = FrameAssembler()
    done = [assembler.add(parse_chunk(chunks[k])) for k in rng.permutation(len(chunks))]
    assert all(d is None for d in done[:-1]) and done[-1] == (7, 1.25, jpeg)


def test_chunk_header_is_the_documented_layout():
    (chunk,) = chunk_frame(b"JPEGDATA", 0x01020304, 2.5)
    # magic, version 1, flags 0, frame id (LE uint32), index 0, count 1 (LE uint16), t (LE float64)
    assert chunk[:22] == b"CBTV" + bytes([1, 0]) + bytes([4, 3, 2, 1]) + bytes([0, 0, 1, 0]) + np.float64(2.5).tobytes()
    assert chunk[22:] == b"JPEGDATA"


def test_frames_needing_more_chunks_than_the_header_counts_are_refused():
    with pytest.raises(ValueError, match="at most 65535"):
        chunk_frame(bytes(65_536), 0, 0.0, VIDEO_HEADER.size + 1)
    with pytest.raises(ValueError, match="no room"):
        chunk_frame(b"x", 0, 0.0, VIDEO_HEADER.size)


def test_incomplete_frames_are_given_up_after_keep_newer_ones():
    assembler = FrameAssembler(keep=2)
    for fid in range(4):
        assert assembler.add(parse_chunk(chunk_frame(b"x" * 100, fid, 0.0, VIDEO_HEADER.size + 10)[0])) is None
    assert assembler.dropped == 2


def test_json_messages_are_plain_json_with_nulls_for_non_finite_numbers():
    est = TargetEstimate(t=3.0, position_enu=np.array([10.0, 20.0, 30.0]), covariance_enu=np.diag([4.0, 9.0, 16.0]),
                         source="vision", track_id=np.int64(2), bearing_enu=np.array([0.6, 0.8, 0.0]),
                         range_m=float("nan"), range_std_m=np.float32(1.5), confidence=0.9)
    msg = parse_datagram(json_datagram("estimate", 5, 3.1, estimate_message(est)))
    assert msg == {"v": 1, "type": "estimate", "seq": 5, "t": 3.1, "source": "vision", "track_id": 2, "t_measured": 3.0,
                   "position_enu": [10.0, 20.0, 30.0], "sigma_enu_m": [2.0, 3.0, 4.0], "velocity_enu": None,
                   "bearing_enu": [0.6, 0.8, 0.0], "range_m": None, "range_std_m": 1.5, "confidence": 0.9}


def test_tracks_flag_the_ownship():
    tr = [RadarTrack(4, 1.0, np.array([1.0, 2.0, 3.0]), None, np.eye(3), 0.7, 0.5),
          RadarTrack(9, 1.1, np.array([5.0, 6.0, 7.0]), np.array([1.0, 0.0, 0.0]), np.eye(3), 0.9, 0.2)]
    body = tracks_message(tr, ownship_ids={9})
    assert [(t["id"], t["ownship"]) for t in body["tracks"]] == [(4, False), (9, True)]
    assert body["tracks"][1]["velocity_enu"] == [1.0, 0.0, 0.0]


@pytest.mark.parametrize("data", [b"", b"garbage", b"[1, 2]", b'{"v": 2, "type": "status"}', b"CBTV\x01",
                                  b"CBTV" + bytes([9, 0]) + bytes(16)])
def test_garbage_datagrams_are_value_errors(data):
    with pytest.raises(ValueError):
        parse_datagram(data)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200) | st.builds(lambda n: b"[" * n, st.integers(1, 200_000))
       | st.builds(lambda tail: b"CBTV" + tail, st.binary(max_size=60)))
def test_whatever_arrives_parse_datagram_raises_only_its_documented_error(data):
    try:
        parsed = parse_datagram(data)
    except ValueError:
        return
    assert isinstance(parsed, (dict, VideoChunk))  # what it returns is one of the two things it reads


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 5), st.integers(1, 6), st.binary(max_size=20)), max_size=40))
def test_the_assembler_takes_any_chunk_sequence_and_returns_only_whole_frames(chunks):
    # Chunks of one frame with different counts, repeats, any order: never an exception, and every
    # frame returned is exactly the chunks of one count, in order.
    assembler = FrameAssembler(keep=2)
    for frame_id, index, count, payload in chunks:
        if index >= count:
            continue  # parse_chunk refuses those
        done = assembler.add(VideoChunk(frame_id, index, count, 0.0, payload))
        if done is not None:
            assert done[0] == frame_id


def test_oversized_json_message_is_refused_before_sending():
    with pytest.raises(ValueError, match="exceeds one datagram"):
        json_datagram("tracks", 0, 0.0, {"blob": "x" * MAX_DATAGRAM})


def test_boxes_are_drawn_on_a_copy():
    image = np.full((120, 160, 3), 90, np.uint8)
    out = draw_boxes(image, [Box((40, 30, 100, 80), "s1000 0.9")])
    assert (out[55, 40] == RED).all() and (out[30, 70] == RED).all()  # left and top edges
    assert (out[55, 70] == 90).all() and (image == 90).all()  # inside untouched; the input unchanged


# ----------------------------------------------------------------------------- sender
def _listener() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)  # room for a whole burst of video
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    return sock


def _scene(width: int = 640, height: int = 480, box=(250, 180, 330, 240)) -> np.ndarray:
    """A grainy sky gradient (a JPEG of 100+ kB at 1280x960) with a dark drone-sized blob in ``box``."""
    rng = np.random.default_rng(1)
    sky = np.linspace(200, 120, height)[:, None, None] + rng.normal(0.0, 6.0, (height, width, 3))
    image = np.clip(sky, 0, 255).astype(np.uint8)
    x0, y0, x1, y1 = box
    image[y0 + 10:y1 - 10, x0 + 10:x1 - 10] = 30
    return image


def test_sender_frames_arrive_whole_and_decode_with_the_box():
    ground = _listener()
    sender = GroundSender("127.0.0.1", ground.getsockname()[1])
    assert sender.sock.getblocking() is False
    image = _scene(1280, 960)
    assert sender.send_frame(image, 4.0, [Box((250, 180, 330, 240), "s1000")], quality=90)
    assembler, whole = FrameAssembler(), None
    while whole is None:
        whole = assembler.add(parse_datagram(ground.recv(65535)))
    assert sender.counters.datagrams >= 2  # a 1280x960 noisy frame needs several chunks
    decoded = cv2.imdecode(np.frombuffer(whole[2], np.uint8), cv2.IMREAD_COLOR)
    assert decoded.shape == image.shape and whole[:2] == (0, 4.0)
    edge = decoded[210, 248:253].astype(int)  # the left edge of the box, JPEG-blurred
    assert (edge[:, 2] > 180).any() and (edge[:, 0] < 80).any()
    ground.close()
    sender.close()


def test_sender_without_a_ground_counts_errors_and_logs_each_kind_once(caplog):
    sender = GroundSender("255.255.255.255", 14600)  # broadcast without SO_BROADCAST: refused locally
    with caplog.at_level(logging.WARNING, logger="chaser_bt.ground.sender"):
        results = [sender.send_message("status", float(k), {}) for k in range(5)]
    assert results == [False] * 5 and sender.counters.errors == 5 and sender.counters.messages == 0
    assert len(caplog.records) == 1
    sender.close()


@pytest.mark.parametrize("host, port", [("no-such-host.invalid", 14600), ("127.0.0.1", 0), ("127.0.0.1", 70000)])
def test_sender_refuses_a_bad_address(host, port):
    with pytest.raises(ValueError, match="ground"):
        GroundSender(host, port)


# ----------------------------------------------------------------------------- the documented receiver
def _receiver_script() -> str:
    text = DOC.read_text()
    section = text[text.index("## A receiver in plain Python"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_receiver_in_the_docs_reads_what_the_sender_sends(tmp_path):
    script = tmp_path / "ground_receiver.py"
    script.write_text(_receiver_script())
    assert len(script.read_text().splitlines()) <= 45
    port = _free_udp_port()
    proc = subprocess.Popen([sys.executable, str(script), str(port), str(tmp_path / "frames"), "30"],
                            stdout=subprocess.PIPE, text=True)
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=lambda: [lines.put(ln) for ln in proc.stdout], daemon=True).start()
    sender = GroundSender("127.0.0.1", port)
    try:
        deadline = time.monotonic() + 20.0
        while lines.empty() and time.monotonic() < deadline:  # until the receiver is listening
            sender.send_message("status", 0.0, {"mode": "GUIDED"})
            time.sleep(0.1)
        assert json.loads(lines.get(timeout=1.0))["type"] == "status"
        est = TargetEstimate(t=9.0, position_enu=np.array([1.0, 2.0, 3.0]), bearing_enu=np.array([0.0, 0.0, 1.0]),
                             range_m=40.0, range_std_m=6.0, confidence=0.8, source="vision")
        sender.send_message("estimate", 9.5, estimate_message(est))
        image = _scene(1280, 960)
        assert sender.send_frame(image, 9.6, [Box((250, 180, 330, 240), "s1000 0.80")], quality=90)
        got = []
        while len(got) < 2 or got[-1]["type"] != "frame":
            msg = json.loads(lines.get(timeout=10.0))
            if msg["type"] != "status":
                got.append(msg)
    finally:
        proc.kill()
        proc.wait()
        sender.close()
    assert got[0] == parse_datagram(json_datagram("estimate", got[0]["seq"], 9.5, estimate_message(est)))
    frame = got[1]
    assert frame["t"] == 9.6 and frame["bytes"] > MAX_DATAGRAM  # it did come in several chunks
    decoded = cv2.imread(str(tmp_path / "frames" / f"frame_{frame['frame_id']}.jpg"))
    assert decoded.shape == image.shape and (decoded[210, 248:253, 2] > 180).any()


def test_the_receiver_in_the_docs_survives_hostile_datagrams(tmp_path):
    # Garbage, a truncated JSON, a 5-byte chunk, nesting too deep to read, chunks of one frame that
    # disagree on its size, an index past the count: it reads on, and the next status still prints.
    script = tmp_path / "ground_receiver.py"
    script.write_text(_receiver_script())
    port = _free_udp_port()
    proc = subprocess.Popen([sys.executable, str(script), str(port), str(tmp_path / "frames"), "30"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=lambda: [lines.put(ln) for ln in proc.stdout], daemon=True).start()
    hostile = [b"\x00garbage", b"{garbage", b"CBTV\x01", b"[" * 60_000, b'{"a":' * 10_000,
               VIDEO_HEADER.pack(b"CBTV", 1, 0, 7, 0, 3, 1.0) + b"a", VIDEO_HEADER.pack(b"CBTV", 1, 0, 7, 1, 2, 1.0) + b"b",
               VIDEO_HEADER.pack(b"CBTV", 1, 0, 8, 5, 2, 1.0) + b"c"]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            deadline = time.monotonic() + 20.0
            while lines.empty() and time.monotonic() < deadline:  # until the receiver is listening
                sock.sendto(json_datagram("status", 0, 0.0, {"mode": "GUIDED"}), ("127.0.0.1", port))
                time.sleep(0.1)
            assert json.loads(lines.get(timeout=1.0))["type"] == "status"
            for data in hostile:
                sock.sendto(data, ("127.0.0.1", port))
            sock.sendto(json_datagram("status", 1, 2.0, {"mode": "RTL"}), ("127.0.0.1", port))
            while True:
                msg = json.loads(lines.get(timeout=10.0))
                if msg["seq"] == 1:
                    break
            assert msg["mode"] == "RTL" and proc.poll() is None
        finally:
            proc.kill()
            _, err = proc.communicate()
    assert "Traceback" not in err, err


# ----------------------------------------------------------------------------- the behaviour, flown
@pytest.fixture(scope="module")
def scenario():
    """A quick-booting field; a radar 100 m south looking north; an intruder circling 150 m north."""
    from chaser_bt.geo import GeoPoint
    from sitl.world.radar import RadarConfig
    from sitl.world.scenario import BootParams, Scenario, ScriptedTarget
    from sitl.world.targets import CirclePath

    radar = RadarConfig(GeoPoint(42.5436, -71.6105, 81.0), pitch_rad=np.radians(10.0), pd=1.0)
    return Scenario("ground-stream", GeoPoint(42.5445, -71.6105, 80.0), boot=BootParams(1.0, 2.0, 3.0), radar=radar,
                    targets=(ScriptedTarget("intruder", CirclePath((0.0, 150.0, 30.0), 30.0, 5.0)),))


class _StillCamera:
    """A FrameSource: the same scene at every tick, numbered."""

    def __init__(self) -> None:
        self.index = 0

    def read(self, t: float):
        from chaser_bt.vision.frame_source import Frame

        self.index += 1
        return Frame(t, _scene(), self.index)

    def close(self) -> None:
        """Nothing to release."""


def _drain(ground) -> tuple[dict[str, list], list]:
    """Everything waiting on the non-blocking ground socket: the JSON messages by type, and the whole video frames."""
    kinds: dict[str, list] = {}
    assembler, frames = FrameAssembler(), []
    while True:
        try:
            msg = parse_datagram(ground.recv(65535))
        except BlockingIOError:
            return kinds, frames
        if isinstance(msg, dict):
            kinds.setdefault(msg["type"], []).append(msg)
        elif (whole := assembler.add(msg)) is not None:
            frames.append(whole)


def _stream_tree(port: int, vision: bool = True, video_hz: float = 5):
    """A tree that streams to the ground on ``port`` (video at ``video_hz``), reading the camera through a
    VisionPipeline or not."""
    from chaser_bt.tree import load_tree_text

    pipeline = "        - ForceSuccess: {child: {VisionPipeline: {}}}\n" if vision else ""
    return load_tree_text(f"""
version: 1
trees:
  Main:
    ReactiveSequence:
      children:
{pipeline}        - StreamToGround: {{host: 127.0.0.1, port: {port}, video_hz: {video_hz}, jpeg_quality: 80}}
""", source="<test>")


def _set_up_at_rest(tree, clock, camera) -> py_trees.trees.BehaviourTree:
    """The tree set up with ``clock`` and ``camera``, no link, and the aircraft level 20 m over home."""
    from types import SimpleNamespace

    from scipy.spatial.transform import Rotation

    from chaser_bt.vehicle.state import VehicleState

    bt = py_trees.trees.BehaviourTree(tree.root)
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
    bb.set("/vehicle/state", VehicleState(position_enu=np.array([0.0, 0.0, 20.0]), velocity_enu=np.zeros(3),
                                          attitude=Rotation.identity()))
    bt.setup(link=SimpleNamespace(frame=None), clock=clock, camera=camera)
    return bt


def _still_camera_sensor():
    """The still scene through a pipeline whose detector always finds the drone in the middle."""
    from chaser_bt.vision.camera import CameraModel
    from chaser_bt.vision.detection import Detection
    from chaser_bt.vision.pipeline import CameraSensor, PipelineConfig, VisionPipeline

    detector = lambda image: [Detection((250.0, 180.0, 330.0, 240.0), 0.9, 0, "s1000")]  # noqa: E731
    return CameraSensor(_StillCamera(), VisionPipeline(CameraModel(width_px=640, height_px=480), detector,
                                                       PipelineConfig(detect_every=1, tracker_kinds=(), focus=False)))


def test_stream_to_ground_sends_status_tracks_cue_estimate_and_boxed_video_and_keeps_running(scenario):
    from chaser_bt.mission.runner import MissionRunner
    from chaser_bt.radar.feed import RadarFeed, RadarNoise
    from chaser_bt.radar.geometry import RadarPose
    from chaser_bt.radar.stream import QueueDatagramSource
    from sitl.bench.in_process import InProcessVehicle

    ground = _listener()
    ground.setblocking(False)
    port = ground.getsockname()[1]
    vehicle = InProcessVehicle(scenario, seed=7)
    assert vehicle.run_until(lambda: vehicle.link.frame is not None and vehicle.link.state.attitude is not None, 30.0)
    radar_cfg = scenario.radar
    datagrams = QueueDatagramSource()
    vehicle.sim.add_radar_consumer(datagrams.push)
    pose = RadarPose.from_geodetic(vehicle.link.frame, radar_cfg.position, radar_cfg.yaw_rad, radar_cfg.pitch_rad,
                                   radar_cfg.roll_rad)
    radar = RadarFeed(datagrams, pose, noise=RadarNoise(radar_cfg.sigma_range_m, radar_cfg.sigma_az_rad,
                                                        radar_cfg.sigma_el_rad))
    camera = _still_camera_sensor()
    tree = _stream_tree(port)
    runner = MissionRunner(tree, vehicle.link, vehicle.clock, rate_hz=10.0,
                           resources={"camera": camera, "radar": radar})
    py_trees.blackboard.Blackboard.set("/target/cue", TargetCue(t=0.0, position_enu=np.array([100.0, 50.0, 30.0]),
                                                                 source="radar", track_id=3))
    from chaser_bt.find import Find
    py_trees.blackboard.Blackboard.set("/sar/find", Find(t=1.0, position_enu=np.array([20.0, -5.0, 0.0]), geodetic=None,
                                                         std_m=0.5, confidence=0.8, fixes=6))
    t0 = vehicle.sim.time_s
    vehicle.run_until(lambda: (runner.tick_if_due() and False), 2.0)
    assert runner.status == py_trees.common.Status.RUNNING
    assert vehicle.sim.time_s - t0 == pytest.approx(2.0, abs=0.05)
    kinds, frames = _drain(ground)
    ground.close()
    runner.stop()
    assert 19 <= len(kinds["status"]) <= 21  # one a tick at 10 Hz
    status = kinds["status"][-1]
    assert status["origin"]["lat_deg"] == pytest.approx(vehicle.link.frame.origin.lat_deg)
    assert status["mode"] == vehicle.link.state.mode and status["armed"] is False
    tracks = kinds["tracks"][-1]["tracks"]  # the intruder; the ownship is on the ground, out of the radar's view
    assert len(kinds["tracks"]) == len(kinds["status"]) and len(tracks) == 1 and tracks[0]["ownship"] is False
    intruder = np.asarray(scenario.targets[0].path.position_enu(vehicle.sim.time_s))
    assert np.linalg.norm(np.array(tracks[0]["position_enu"]) - intruder) < 15.0
    assert len(kinds["cue"]) == 1 and kinds["cue"][0]["track_id"] == 3  # sent once: it did not change
    assert len(kinds["find"]) == 1 and kinds["find"][0]["position_enu"] == [20.0, -5.0, 0.0] and kinds["find"][0]["fixes"] == 6
    assert kinds["find"][0]["t_measured"] == 1.0
    assert len(kinds["estimate"]) >= 15 and kinds["estimate"][-1]["source"] == "vision"
    assert 9 <= len(frames) <= 11  # 5 Hz of video over 2 s
    image = cv2.imdecode(np.frombuffer(frames[-1][2], np.uint8), cv2.IMREAD_COLOR)
    assert image.shape == (480, 640, 3) and (image[210, 248:253, 2] > 180).any()  # the box, drawn in red
    seqs = [m["seq"] for ms in kinds.values() for m in ms]
    assert sorted(seqs) == list(range(len(seqs)))  # nothing lost on loopback


def test_stream_to_ground_sends_the_boxed_video_of_a_threaded_camera():
    """A real flight's camera runs in a PerceptionWorker: the video is its latest processed frame and box."""
    from chaser_bt.clock import WallClock
    from chaser_bt.vision.camera import CameraModel
    from chaser_bt.vision.detection import Detection
    from chaser_bt.vision.perception import PerceptionWorker
    from chaser_bt.vision.pipeline import CameraSensor, PipelineConfig, VisionPipeline

    ground = _listener()
    port = ground.getsockname()[1]
    detector = lambda image: [Detection((250.0, 180.0, 330.0, 240.0), 0.9, 0, "s1000")]  # noqa: E731
    clock = WallClock()
    worker = PerceptionWorker(CameraSensor(_StillCamera(), VisionPipeline(
        CameraModel(width_px=640, height_px=480), detector,
        PipelineConfig(detect_every=1, tracker_kinds=(), confirm_hits=1, focus=False))), clock, max_fps=50.0)
    tree = _stream_tree(port, video_hz=20)
    bt = _set_up_at_rest(tree, clock, worker)
    assembler, frames = FrameAssembler(), []
    try:
        deadline = time.monotonic() + 20.0
        while not frames and time.monotonic() < deadline:
            bt.tick()
            time.sleep(0.05)
            try:
                while True:
                    msg = parse_datagram(ground.recv(65535))
                    if not isinstance(msg, dict) and (whole := assembler.add(msg)) is not None:
                        frames.append(whole)
            except (BlockingIOError, socket.timeout):
                pass
            ground.settimeout(0.01)
    finally:
        worker.stop()
        bt.shutdown()
        ground.close()
    assert frames, "no video from the threaded camera"
    image = cv2.imdecode(np.frombuffer(frames[-1][2], np.uint8), cv2.IMREAD_COLOR)
    assert image.shape == (480, 640, 3) and (image[210, 248:253, 2] > 180).any()  # the box, drawn in red


@pytest.mark.parametrize("pipeline", [False, True], ids=["without VisionPipeline", "with VisionPipeline"])
def test_the_video_carries_frames_only_when_a_vision_pipeline_is_in_the_tree(pipeline):
    """docs/ground.md: the camera's frames are those a VisionPipeline reads; without one (the doc's
    HoverAndStream) the stream is status messages and no video."""
    from chaser_bt.clock import FunctionClock

    ground = _listener()
    ground.setblocking(False)
    port = ground.getsockname()[1]
    camera = _still_camera_sensor()
    tree = _stream_tree(port, vision=pipeline)
    now = [0.0]
    clock = FunctionClock(lambda: now[0])
    bt = _set_up_at_rest(tree, clock, camera)
    for _ in range(20):  # 2 s at 10 Hz
        bt.tick()
        now[0] += 0.1
    bt.shutdown()
    kinds, frames = _drain(ground)
    ground.close()
    assert "status" in kinds
    assert (9 <= len(frames) <= 11) if pipeline else frames == []  # 5 Hz of video over 2 s, or none


def test_the_tree_example_in_the_docs_validates():
    from chaser_bt.tree import validate_tree_text

    example = re.search(r"## In a tree.*?```yaml\n(.*?)```", DOC.read_text(), re.S)
    assert example, "docs/ground.md lost its tree example"
    assert validate_tree_text(example.group(1), source="docs/ground.md") == []
