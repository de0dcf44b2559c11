"""The mission's sensors on a real flight: the ground radar over UDP, a camera through OpenCV, the
target's telemetry on the vehicle link — the same resources a rehearsal hands the tree, built from
what the operator names on ``chaser-bt run`` instead of from a simulator.

The camera's pipeline runs beside the tick by default (``perception="thread"``: a
:class:`~chaser_bt.vision.perception.PerceptionWorker`, docs/vision.md), or inside it (``"inline"``).
:func:`close_flight_sensors` stops and closes what was built, on every way out of a flight.

The radar's pose comes from a calibration (``chaser-bt calibrate --json`` writes it, appendix A);
its scan times plus ``time_offset_s`` are mission time (docs/radar.md).
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from chaser_bt.geo import GeoPoint
from chaser_bt.ground.auth import StreamVerifier
from chaser_bt.ground.uplink import UplinkReceiver
from chaser_bt.mission.resources import missing_resources
from chaser_bt.radar.feed import RadarFeed
from chaser_bt.radar.geometry import RadarPose
from chaser_bt.radar.stream import RadarStreamReader, UdpDatagramSource
from chaser_bt.target_telemetry import TargetTelemetry
from chaser_bt.vehicle.signing import SigningKeyError, load_key

__all__ = ["FlightSensorOptions", "FlightSensorError", "PERCEPTION_MODES", "RESOURCE_FLAGS", "build_flight_sensors",
           "check_camera_file", "check_sensors", "close_flight_sensors", "load_radar_pose"]

log = logging.getLogger(__name__)

#: Where the camera pipeline runs on a flight: its own threads beside the tick, or inside the tick.
PERCEPTION_MODES = ("thread", "inline")

_POSE_FIELDS = ("lat_deg", "lon_deg", "alt_m", "yaw_deg", "pitch_deg", "roll_deg")


class FlightSensorError(ValueError):
    """A sensor cannot be set up as asked (bad pose file, camera that does not open): bad input."""


@dataclass(frozen=True)
class FlightSensorOptions:
    """What the operator connected. ``radar_listen`` is ``HOST:PORT`` to receive radar datagrams on;
    ``camera`` a video file, stream URL or device index (as ``cv2.VideoCapture`` takes it);
    ``perception`` one of :data:`PERCEPTION_MODES`."""

    radar_listen: str | None = None
    radar_pose_file: Path | None = None
    radar_time_offset_s: float = 0.0
    radar_key_file: Path | None = None  # the radar's datagrams are believed only signed with this key
    radar_hosts: frozenset[str] | None = None  # ... and only from these addresses
    uplink_listen: str | None = None  # HOST:PORT the operator's signed designations arrive on
    uplink_key_file: Path | None = None  # required with uplink_listen: the uplink is never unsigned
    uplink_hosts: frozenset[str] = frozenset()  # believed sources (empty: any that signs)
    camera: str | None = None
    camera_size: tuple[int, int] | None = None
    camera_mount: str = "fixed"  # a chaser_bt.vision.camera.MOUNTS name
    camera_tilt_deg: float = 10.0  # down, below the body's forward axis (fixed) or the horizon (stabilised)
    telemetry: bool = True
    perception: str = "thread"

    def __post_init__(self) -> None:
        if self.perception not in PERCEPTION_MODES:
            raise FlightSensorError(f"perception must be one of {', '.join(PERCEPTION_MODES)}, got {self.perception!r}")


#: How an operator gives ``chaser-bt run`` each resource a leaf may require.
RESOURCE_FLAGS = {
    "radar": "--radar HOST:PORT and --radar-pose FILE.json",
    "camera": "--camera SOURCE (a video file, stream URL or device index)",
}


def check_sensors(tree: Any, options: FlightSensorOptions) -> None:
    """Refuse, before anything connects, a tree whose leaves need a sensor ``options`` does not give.

    Raises:
        FlightSensorError: naming each missing sensor, the nodes that need it and the flag to give.
    """
    given = {name for name, on in (("radar", options.radar_listen is not None),
                                   ("camera", options.camera is not None),
                                   ("target_telemetry", options.telemetry)) if on}
    missing = missing_resources(tree.root, given, how=RESOURCE_FLAGS, what=f"tree {tree.name}")
    if missing is not None:
        raise FlightSensorError(str(missing))
    if options.radar_listen is not None:  # every radar option read now, not after the vehicle answered
        if options.radar_pose_file is None:
            raise FlightSensorError("--radar needs --radar-pose FILE (the output of `chaser-bt calibrate --json`)")
        _host_port(options.radar_listen)
        load_radar_pose(options.radar_pose_file)
        _radar_verifier(options.radar_key_file)
    _uplink_key(options)
    if options.camera is not None:
        check_camera_file(options.camera)


def check_camera_file(camera: str) -> None:
    """Refuse a ``--camera`` that names a folder, or a file OpenCV cannot read a frame from (empty, not a
    video). A device index, a device node or a stream URL is not opened here: that would take the camera."""
    if camera.isdigit():  # a device index, as _camera reads it
        return
    path = Path(camera)
    if path.is_dir():
        raise FlightSensorError(f"--camera {camera}: is a folder, not a video file")
    if not path.is_file():
        return
    if path.stat().st_size == 0:
        raise FlightSensorError(f"--camera {camera}: the file is empty, not a video")
    import cv2

    capture = cv2.VideoCapture(str(path))
    try:
        readable = capture.isOpened() and capture.read()[0]
    finally:
        capture.release()
    if not readable:
        raise FlightSensorError(f"--camera {camera}: not a video or image OpenCV can read")


def _uplink_key(options: FlightSensorOptions) -> bytes | None:
    """The uplink's key, or None without an uplink; an uplink without a key, or a bad key, is refused."""
    if options.uplink_listen is None:
        return None
    if options.uplink_key_file is None:
        raise FlightSensorError("--uplink needs --uplink-key FILE (the uplink is never unsigned)")
    _host_port(options.uplink_listen, "--uplink")
    try:
        return load_key(options.uplink_key_file)
    except SigningKeyError as exc:
        raise FlightSensorError(f"--uplink-key: {exc}") from None


def load_radar_pose(path: Path) -> tuple[GeoPoint, tuple[float, float, float]]:
    """The radar's geodetic position and (yaw, pitch, roll) in radians from a ``calibrate --json`` file."""
    try:
        data = json.loads(Path(path).read_text())
    except OSError as exc:
        raise FlightSensorError(f"{path}: {exc.strerror or exc}") from None
    except json.JSONDecodeError as exc:
        raise FlightSensorError(f"{path}:{exc.lineno}: not JSON ({exc.msg})") from None
    except UnicodeDecodeError:
        raise FlightSensorError(f"{path}: not a text file (expected the JSON of `chaser-bt calibrate --json`)") from None
    except ValueError as exc:  # an integer of thousands of digits: int() refuses it
        raise FlightSensorError(f"{path}: not a radar pose: {str(exc).split(':')[0]}") from None
    except RecursionError:
        raise FlightSensorError(f"{path}: not a radar pose: JSON nested too deeply") from None
    if not isinstance(data, dict):
        raise FlightSensorError(f"{path}: expected a JSON object with {', '.join(_POSE_FIELDS)}")
    values = {}
    for name in _POSE_FIELDS:
        v = data.get(name, 0.0 if name in ("alt_m", "pitch_deg", "roll_deg") else None)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not _finite(v):
            raise FlightSensorError(f"{path}: field {name!r}: expected a finite number, got {v!r}")
        values[name] = float(v)
    point = GeoPoint(values["lat_deg"], values["lon_deg"], values["alt_m"])
    return point, tuple(math.radians(values[k]) for k in ("yaw_deg", "pitch_deg", "roll_deg"))


def _finite(v: float) -> bool:
    """``math.isfinite``, false (not OverflowError) for an integer too large for a float."""
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


def _host_port(text: str, flag: str = "--radar") -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise FlightSensorError(f"{flag} {text!r}: expected HOST:PORT such as 0.0.0.0:4950")
    return host or "0.0.0.0", int(port)


def build_flight_sensors(link: Any, clock: Any, options: FlightSensorOptions) -> dict[str, Any]:
    """Resources for :class:`~chaser_bt.mission.runner.MissionRunner` from ``options``.

    ``link`` must already know its ENU frame (the vehicle's home) when a radar is asked for: the
    radar's pose is placed in that frame.
    """
    resources: dict[str, Any] = {}
    if options.radar_listen is not None:
        if options.radar_pose_file is None:
            raise FlightSensorError("--radar needs --radar-pose FILE (the output of `chaser-bt calibrate --json`)")
        if link.frame is None:
            raise FlightSensorError("the vehicle has not reported its home position; the radar pose cannot be placed")
        point, (yaw, pitch, roll) = load_radar_pose(options.radar_pose_file)
        pose = RadarPose.from_geodetic(link.frame, point, yaw, pitch, roll)
        host, port = _host_port(options.radar_listen)
        reader = RadarStreamReader(verifier=_radar_verifier(options.radar_key_file))
        if options.radar_key_file is None and options.radar_hosts is None:
            log.warning("the radar feed on %s is open to anyone who can reach it: anyone can cue the mission "
                        "(--radar-key FILE signs it, --radar-from HOST pins its source)", options.radar_listen)
        source = UdpDatagramSource(host, port, allowed_hosts=options.radar_hosts, counts=reader.counts)
        resources["radar"] = RadarFeed(source, pose, time_offset_s=options.radar_time_offset_s, reader=reader)
    key = _uplink_key(options)
    if key is not None:
        host, port = _host_port(options.uplink_listen, "--uplink")
        try:
            resources["uplink"] = UplinkReceiver(host, port, key, allowed_hosts=options.uplink_hosts)
        except OSError as exc:
            raise FlightSensorError(f"--uplink {options.uplink_listen}: {exc.strerror or exc}") from None
    if options.camera is not None:
        resources["camera"] = _camera(options, clock)
    if options.telemetry:
        resources["target_telemetry"] = TargetTelemetry.attach(link, clock.now)
    return resources


def _radar_verifier(key_file: Path | None) -> StreamVerifier | None:
    if key_file is None:
        return None
    try:
        return StreamVerifier(load_key(key_file))
    except SigningKeyError as exc:
        raise FlightSensorError(f"--radar-key: {exc}") from None


def close_flight_sensors(resources: dict[str, Any]) -> None:
    """Stop and close every resource :func:`build_flight_sensors` made that can be (the camera's
    threads and source, the radar's socket). Never raises: it runs on the way out of a flight."""
    for name, resource in resources.items():
        close = getattr(resource, "close", None)
        if callable(close):
            try:
                close()
            except Exception:
                log.exception("closing the %s raised", name)


def _camera(options: FlightSensorOptions, clock: Any) -> Any:
    """The camera resource: a CameraSensor over the capture, in a PerceptionWorker unless inline."""
    import cv2

    from chaser_bt.vision.camera import CameraModel
    from chaser_bt.vision.detector.inference import Detector
    from chaser_bt.vision.frame_source import VideoCaptureSource
    from chaser_bt.vision.pipeline import CameraSensor, VisionPipeline

    target: str | int = int(options.camera) if options.camera.isdigit() else options.camera
    try:
        source = VideoCaptureSource(target, options.camera_size)
    except ValueError as exc:
        raise FlightSensorError(f"--camera: {exc}") from None
    if options.camera_size is not None:
        w, h = options.camera_size
    else:
        w = int(source.capture.get(3)) or 1920  # CAP_PROP_FRAME_WIDTH / HEIGHT
        h = int(source.capture.get(4)) or 1080
    # One intra-op thread for the detector (torch: process-wide; onnxruntime: its session).
    model = CameraModel(width_px=w, height_px=h, tilt_rad=math.radians(options.camera_tilt_deg), mount=options.camera_mount)
    sensor = CameraSensor(source, VisionPipeline(model, Detector(threads=1)))
    if options.perception == "inline":
        return sensor
    from chaser_bt.vision.perception import PerceptionWorker

    cv2.setNumThreads(1)  # the processing thread keeps to one core; the tick and the link have the other
    fps = float(source.capture.get(cv2.CAP_PROP_FPS) or 0.0)
    # A file is read at its own rate (it never blocks); a live camera blocks until its next frame anyway.
    return PerceptionWorker(sensor, clock, max_fps=fps if 1.0 <= fps <= 240.0 else 30.0)
