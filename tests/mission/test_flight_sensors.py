"""Real-flight sensors for `chaser-bt run`: radar pose file, radar over UDP into the mission frame, camera file."""

from __future__ import annotations

import json
import math
import socket
import time
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from chaser_bt.clock import ManualClock
from chaser_bt.geo import GeoPoint, LocalFrame
from chaser_bt.mission.flight_sensors import (
    FlightSensorError,
    FlightSensorOptions,
    build_flight_sensors,
    close_flight_sensors,
    load_radar_pose,
)
from chaser_bt.vision.perception import PerceptionWorker
from chaser_bt.vision.pipeline import CameraSensor

HOME = GeoPoint(42.5445, -71.6105, 80.0)


class _Link:
    """Just what build_flight_sensors touches on a VehicleLink: its ENU frame and listeners."""

    def __init__(self, frame: LocalFrame | None) -> None:
        self.frame, self.target_sysid, self.listeners = frame, 1, []

    def add_listener(self, on_receive=None, on_send=None) -> None:
        self.listeners.append(on_receive)


def _pose_file(tmp_path, **fields):
    data = {"lat_deg": HOME.lat_deg, "lon_deg": HOME.lon_deg, "alt_m": 80.0, "yaw_deg": 90.0, "pitch_deg": 0.0, "roll_deg": 0.0}
    data.update(fields)
    path = tmp_path / "pose.json"
    path.write_text(json.dumps(data))
    return path


def test_pose_file_reads_degrees_into_radians(tmp_path):
    point, (yaw, pitch, roll) = load_radar_pose(_pose_file(tmp_path, pitch_deg=10.0))
    assert point == HOME
    assert (yaw, pitch, roll) == pytest.approx((math.pi / 2, math.radians(10.0), 0.0))


@pytest.mark.parametrize("content, expected", [
    ("{not json", "pose.json:1"),
    ("[1, 2]", "expected a JSON object"),
    (json.dumps({"lat_deg": 1.0, "lon_deg": "x", "yaw_deg": 0}), "field 'lon_deg'"),
    (json.dumps({"lat_deg": 1.0, "lon_deg": 2.0}), "field 'yaw_deg'"),
])
def test_bad_pose_file_names_file_and_field(tmp_path, content, expected):
    path = tmp_path / "pose.json"
    path.write_text(content)
    with pytest.raises(FlightSensorError, match=expected):
        load_radar_pose(path)


def test_radar_needs_a_pose_and_a_home(tmp_path):
    with pytest.raises(FlightSensorError, match="--radar-pose"):
        build_flight_sensors(_Link(LocalFrame(HOME)), ManualClock(), FlightSensorOptions(radar_listen="127.0.0.1:0"))
    with pytest.raises(FlightSensorError, match="home"):
        build_flight_sensors(_Link(None), ManualClock(),
                             FlightSensorOptions(radar_listen="127.0.0.1:0", radar_pose_file=_pose_file(tmp_path)))
    with pytest.raises(FlightSensorError, match="HOST:PORT"):
        build_flight_sensors(_Link(LocalFrame(HOME)), ManualClock(),
                             FlightSensorOptions(radar_listen="nowhere", radar_pose_file=_pose_file(tmp_path)))


def test_radar_datagram_over_udp_lands_in_the_mission_frame(tmp_path):
    # Radar at home looking east (yaw 90 deg compass); a report 100 m straight ahead, level, is 100 m east.
    link = _Link(LocalFrame(HOME))
    res = build_flight_sensors(link, ManualClock(), FlightSensorOptions(
        radar_listen="127.0.0.1:0", radar_pose_file=_pose_file(tmp_path), radar_time_offset_s=5.0, telemetry=False))
    feed = res["radar"]
    scan = {"schema": "chaser-bt/radar-scan", "version": 1, "radar_id": "r", "seq": 1, "t": 10.0,
            "tracks": [{"id": 7, "range_m": 100.0, "az_rad": 0.0, "el_rad": 0.0, "confidence": 0.9}]}
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(json.dumps(scan).encode(), ("127.0.0.1", feed.source.port))
    deadline = time.monotonic() + 5.0
    picture = feed.update(15.0)
    while 7 not in picture.tracks and time.monotonic() < deadline:
        time.sleep(0.01)
        picture = feed.update(15.0)
    track = picture.tracks[7]
    assert track.t == pytest.approx(15.0)  # radar time 10 + offset 5
    np.testing.assert_allclose(track.position_enu, [100.0, 0.0, 0.0], atol=1e-6)
    feed.source.close()


def test_camera_from_a_video_file_and_telemetry_listener(tmp_path):
    path = str(tmp_path / "clip.avi")
    writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"MJPG"), 10, (160, 120))
    for i in range(3):
        writer.write(np.full((120, 160, 3), 40 * i, np.uint8))
    writer.release()
    link = _Link(LocalFrame(HOME))
    res = build_flight_sensors(link, ManualClock(), FlightSensorOptions(camera=path))
    camera = res["camera"]
    assert isinstance(camera, PerceptionWorker)  # a flight's camera runs beside the tick by default
    assert camera.max_fps == pytest.approx(10.0)  # a file is read at its own frame rate
    assert (camera.pipeline.camera.width_px, camera.pipeline.camera.height_px) == (160, 120)
    assert camera.sensor.source.read(0.0).image.shape == (120, 160, 3)
    assert len(link.listeners) == 1 and "target_telemetry" in res
    camera.start()
    close_flight_sensors(res)
    assert not camera.running and camera.health(0.0) == "perception worker stopped"
    inline = build_flight_sensors(link, ManualClock(), FlightSensorOptions(camera=path, perception="inline", telemetry=False))
    assert isinstance(inline["camera"], CameraSensor)
    assert (inline["camera"].pipeline.camera.mount, inline["camera"].pipeline.camera.tilt_rad) == ("fixed", math.radians(10))
    held = build_flight_sensors(link, ManualClock(), FlightSensorOptions(
        camera=path, perception="inline", telemetry=False, camera_mount="stabilised", camera_tilt_deg=20.0))
    assert (held["camera"].pipeline.camera.mount, held["camera"].pipeline.camera.tilt_rad) == ("stabilised", math.radians(20))
    with pytest.raises(FlightSensorError, match="--camera"):
        build_flight_sensors(link, ManualClock(), FlightSensorOptions(camera=str(tmp_path / "missing.avi"), telemetry=False))
    with pytest.raises(FlightSensorError, match="perception must be one of thread, inline"):
        FlightSensorOptions(camera=path, perception="process")
