"""Which resources a tree's leaves require, read from the tree before anything flies."""

from __future__ import annotations

from pathlib import Path

import pytest

from chaser_bt.mission.flight_sensors import FlightSensorError, FlightSensorOptions, check_sensors
from chaser_bt.mission.resources import MissingResources, missing_resources, required_resources, used_resources
from chaser_bt.mission.runner import MissionRunner
from chaser_bt.tree import load_tree, load_tree_text

TREES = Path(__file__).resolve().parents[2] / "trees"


def _tree(body: str):
    return load_tree_text(f"version: 1\ntrees:\n  T:\n    {body}\n", source="<test>")


def test_required_resources_lists_each_leaf_that_needs_one_in_tree_order():
    tree = _tree("Sequence: {children: [RadarTrackValidated: {name: track}, VisionPipeline: {name: eye}, "
                 "RadarCue: {name: cue}, GoTo: {waypoint: [0, 0, 10]}]}")
    assert required_resources(tree.root) == {"radar": ["track", "cue"], "camera": ["eye"]}


def test_the_shipped_trees_require_what_their_docs_say():
    assert required_resources(load_tree(TREES / "patrol.yaml").root) == {}
    chase = required_resources(load_tree(TREES / "chase.yaml").root)
    assert set(chase) == {"radar", "camera"}
    assert set(required_resources(load_tree(TREES / "sar.yaml").root)) == {"camera"}


def test_used_resources_adds_what_a_leaf_takes_when_given():
    """The chase requires radar and camera and takes the uplink; it never reads the target's
    telemetry (the report's sensors leave it out); the telemetry variant does."""
    assert used_resources(load_tree(TREES / "chase.yaml").root) == {"radar", "camera", "uplink"}
    assert "target_telemetry" in used_resources(load_tree(TREES / "chase_telemetry.yaml").root)
    assert used_resources(load_tree(TREES / "patrol.yaml").root) == set()


def test_missing_resources_names_the_resource_its_nodes_and_how_to_give_it():
    tree = _tree("Sequence: {children: [RadarTrackValidated: {name: track}, VisionPipeline: {name: eye}]}")
    assert missing_resources(tree.root, {"radar", "camera"}) is None
    err = missing_resources(tree.root, {"camera"}, how={"radar": "--radar HOST:PORT"}, what="tree T")
    assert isinstance(err, MissingResources) and err.missing == {"radar": ["track"]}
    assert str(err) == "tree T needs a radar (needed by track): give --radar HOST:PORT"


def test_check_sensors_counts_only_what_the_operator_named(tmp_path):
    chase = load_tree(TREES / "chase.yaml")
    pose = tmp_path / "pose.json"
    pose.write_text('{"lat_deg": 42.5, "lon_deg": -71.6, "alt_m": 80, "yaw_deg": 0, "pitch_deg": 10, "roll_deg": 0}')
    with pytest.raises(FlightSensorError, match="--camera") as e:
        check_sensors(chase, FlightSensorOptions(radar_listen="0.0.0.0:4950", radar_pose_file=pose))
    assert "--radar" not in str(e.value)
    check_sensors(chase, FlightSensorOptions(radar_listen="0.0.0.0:4950", radar_pose_file=pose, camera="0"))


def test_every_radar_option_is_read_before_anything_connects(tmp_path):
    chase = load_tree(TREES / "chase.yaml")
    with pytest.raises(FlightSensorError, match="--radar needs --radar-pose"):
        check_sensors(chase, FlightSensorOptions(radar_listen="0.0.0.0:4950", camera="0"))
    binary = tmp_path / "pose.bin"
    binary.write_bytes(bytes(range(256)))
    with pytest.raises(FlightSensorError, match="not a text file"):
        check_sensors(chase, FlightSensorOptions(radar_listen="0.0.0.0:4950", radar_pose_file=binary, camera="0"))


def test_a_camera_file_that_is_no_video_is_refused_before_anything_connects(tmp_path):
    import cv2
    import numpy as np

    chase = load_tree(TREES / "chase.yaml")
    radar = dict(radar_listen="0.0.0.0:4950", radar_pose_file=tmp_path / "pose.json")
    (tmp_path / "pose.json").write_text('{"lat_deg": 1, "lon_deg": 2, "yaw_deg": 0}')
    (tmp_path / "garbage.dat").write_bytes(bytes(range(256)) * 16)
    (tmp_path / "empty.mp4").write_bytes(b"")
    for camera, why in (("garbage.dat", "not a video or image OpenCV can read"), ("empty.mp4", "the file is empty"),
                        ("", "is a folder")):
        with pytest.raises(FlightSensorError, match=f"--camera {tmp_path / camera}: {why}"):
            check_sensors(chase, FlightSensorOptions(camera=str(tmp_path / camera), **radar))
    video = str(tmp_path / "clip.avi")
    writer = cv2.VideoWriter(video, cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    for _ in range(3):
        writer.write(np.zeros((48, 64, 3), np.uint8))
    writer.release()
    for camera in (video, "0", "rtsp://192.0.2.1/stream"):  # a device or a stream is not opened before the flight
        check_sensors(chase, FlightSensorOptions(camera=camera, **radar))


def test_the_runner_refuses_to_set_up_a_tree_missing_a_resource():
    tree = _tree("VisionPipeline: {name: eye}")
    runner = MissionRunner(tree, link=None, clock=None)  # type: ignore[arg-type]
    with pytest.raises(MissingResources, match="needs a camera"):
        runner.setup()
