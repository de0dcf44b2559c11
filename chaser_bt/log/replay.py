"""Reading a flight log back, replaying its sensor data into a tree, and turning it into a FlightTrace.

:func:`read_log` reads an MCAP file written by :mod:`chaser_bt.log.recorder`, finished or not: a
file cut short by a crash is read up to its last whole chunk (``FlightLog.truncated`` says so).

:func:`replay` flies a tree on a recorded flight with no vehicle: the raw MAVLink bytes the link
read go, poll by poll and on the link's recorded clock, into a fresh :class:`VehicleLink` over a
pipe (its commands go nowhere); the radar datagrams go into a fresh :class:`RadarFeed` (the
correlator runs again, the recorded one or another); recorded camera frames go to a camera built
by the caller (the detector runs again). The tree ticks where the recorded mission would have, so
the same tree on the same log reproduces the recorded status changes and associations exactly;
a changed tree or correlator shows what it would have done.

:func:`flight_trace` turns a log into the :class:`FlightTrace` the paper's figures draw.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import cv2
import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.records import Channel, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from scipy.spatial.transform import Rotation

from chaser_bt.clock import FunctionClock
from chaser_bt.geo import GeoPoint
from chaser_bt.log import schemas as S
from chaser_bt.log.trace import BeliefSnapshot, FlightTrace, TraceEvent
from chaser_bt.mission.outcome import PHASE_KEY as _PHASE_KEY
from chaser_bt.mission.runner import MissionRunner, StatusChange
from chaser_bt.tree import MissionTree, reset_blackboard
from chaser_bt.vehicle import CommandEnvelope, LinkConfig, VehicleError, VehicleLink
from chaser_bt.vehicle.telemetry_check import TelemetryLimits
from chaser_bt.vehicle.pipe import byte_pipe
from chaser_bt.vision.frame_source import Frame

__all__ = ["LogError", "LogMessage", "FlightLog", "read_log", "ReplayResult", "replay", "recorded_status_changes",
           "recorded_associations", "recorded_camera_factory", "flight_trace"]


class LogError(ValueError):
    """A log that cannot be used; the message names the file and what is wrong."""


@dataclass(frozen=True)
class LogMessage:
    """One record: topic, mission time (s), file order, payload and its schema name."""

    topic: str
    t: float
    sequence: int
    data: bytes
    schema_name: str

    def json(self) -> Any:
        return json.loads(self.data)


@dataclass
class FlightLog:
    """A recorded flight: its metadata, every record in file order, schemas, and whether it was cut short."""

    path: Path
    metadata: dict[str, dict[str, str]]
    messages: list[LogMessage]
    schemas: dict[str, tuple[str, bytes]]  # schema name -> (encoding, data)
    channels: dict[str, str]  # topic -> schema name
    truncated: bool = False
    problem: str = ""

    def topic(self, topic: str) -> list[LogMessage]:
        return [m for m in self.messages if m.topic == topic]

    @property
    def meta(self) -> dict[str, str]:
        return self.metadata.get("chaser_bt", {})

    def decode(self, msg: LogMessage) -> Any:
        """The payload: JSON as Python data, protobuf as a protobuf message."""
        encoding, data = self.schemas[msg.schema_name]
        if encoding == "jsonschema":
            return msg.json()
        return _protobuf_class(msg.schema_name, data).FromString(msg.data)


def read_log(path: str | Path) -> FlightLog:
    """Read the log at ``path``; a file cut short is read up to its last whole record.

    Raises:
        LogError: not a file, or not an MCAP file.
    """
    path = Path(path)
    if not path.is_file():
        raise LogError(f"{path}: is a folder, not a log file" if path.is_dir() else f"{path}: no such log file")
    if path.stat().st_size == 0:
        raise LogError(f"{path}: empty file, not an MCAP log")
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    metadata: dict[str, dict[str, str]] = {}
    messages: list[LogMessage] = []
    truncated, problem, header = False, "", False
    with path.open("rb") as fh:
        try:
            for rec in StreamReader(fh, validate_crcs=True).records:
                if isinstance(rec, Header):
                    header = True
                elif isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, Metadata):
                    metadata[rec.name] = dict(rec.metadata)
                elif isinstance(rec, Message):
                    ch = channels[rec.channel_id]
                    messages.append(LogMessage(ch.topic, rec.log_time / 1e9, rec.sequence, bytes(rec.data),
                                               schemas[ch.schema_id].name if ch.schema_id else ""))
        except Exception as exc:  # a crash leaves a partial chunk or a missing footer: keep what came before
            if not header:
                raise LogError(f"{path}: not a readable MCAP log ({type(exc).__name__}: {exc})") from exc
            truncated, problem = True, f"{type(exc).__name__}: {exc}"
    messages.sort(key=lambda m: m.sequence)
    return FlightLog(
        path, metadata, messages,
        {s.name: (s.encoding, bytes(s.data)) for s in schemas.values()},
        {c.topic: schemas[c.schema_id].name if c.schema_id else "" for c in channels.values()},
        truncated, problem,
    )


_PROTOBUF_CLASSES: dict[str, Any] = {}


def _protobuf_class(name: str, descriptor_set: bytes) -> Any:
    cls = _PROTOBUF_CLASSES.get(name)
    if cls is None:
        pool = descriptor_pool.DescriptorPool()
        fds = descriptor_pb2.FileDescriptorSet.FromString(descriptor_set)
        for f in fds.file:
            pool.Add(f)
        cls = _PROTOBUF_CLASSES[name] = message_factory.GetMessageClass(pool.FindMessageTypeByName(name))
    return cls


# --- what the recording says ---------------------------------------------------------------------
def recorded_status_changes(log: FlightLog) -> list[StatusChange]:
    """The tree's status changes as recorded (ticks and the final stop), in order."""
    out = []
    for m in log.topic(S.TOPIC_TREE):
        rec = m.json()
        out += [StatusChange(rec["t"], c["node"], c["old"], c["new"]) for c in rec["changes"]]
    return out


def recorded_associations(log: FlightLog) -> list[dict]:
    """The correlator's association at every radar picture as recorded."""
    return [_association_row(m.json()) for m in log.topic(S.TOPIC_RADAR_PICTURE)]


def _association_row(pic: dict) -> dict:
    return {"t": pic["t"], "associated_id": pic["associated_id"], "ownship_ids": list(pic["ownship_ids"]),
            "unassociated_ids": list(pic["unassociated_ids"])}


# --- replay ---------------------------------------------------------------------------------------
@dataclass
class ReplayResult:
    """What the tree did on the recorded flight."""

    status_changes: list[StatusChange]
    associations: list[dict]
    ticks: int
    root: str  # the root's last status
    ended: str  # why replay stopped: "root SUCCESS", "end of log", a vehicle error
    frames: int = 0
    datagrams: int = 0
    polls: int = 0
    correlator: str = ""  # the correlator that ran ("" without radar)

    def to_dict(self) -> dict:
        return {"ticks": self.ticks, "root": self.root, "ended": self.ended, "polls": self.polls,
                "correlator": self.correlator,
                "datagrams": self.datagrams, "frames": self.frames,
                "status_changes": [[c.t, c.node, c.old, c.new] for c in self.status_changes],
                "associations": self.associations}


@dataclass
class _Segment:
    """One recorded poll and what the mission read from its sensors before the next one."""

    mono_s: float
    t: float
    data: bytes
    tick: bool = True  # False for the preamble: the link's state when recording began
    datagrams: list[bytes] = field(default_factory=list)
    frames: list[LogMessage] = field(default_factory=list)  # decoded only when a camera replays them


class _ReplayFrameSource:
    """Hands out the recorded frames, each once, when the mission asks at or after its time.

    Frame times are stored in whole nanoseconds; a frame taken at the very time the mission asked for
    (a simulated camera) gets that time back bit for bit, so time-dependent filters replay exactly.
    A lagged camera (:class:`~chaser_bt.vision.lagged_camera.LaggedCamera`) takes a shot at one tick
    and develops it at the next: the frame recorded for that shot, if one was.
    """

    def __init__(self) -> None:
        self.pending: list[Frame] = []

    def read(self, t: float) -> Frame | None:
        ready = [f for f in self.pending if f.t <= t + 1e-9]
        if not ready:
            return None
        self.pending = [f for f in self.pending if f.t > t + 1e-9]
        frame = ready[-1]
        return Frame(t, frame.image, frame.index) if abs(frame.t - t) <= 1e-9 else frame

    def shot(self, t: float, regions: Any = None) -> float:
        return t

    def develop(self, shot: float, regions: Any = None) -> Frame | None:
        """The frame recorded for the shot taken at ``shot`` (None: not recorded; a log may keep only some)."""
        frame = self.read(shot)
        return frame if frame is not None and frame.t == shot else None


def _segments(log: FlightLog) -> tuple[list[_Segment], int]:
    segs: list[_Segment] = []
    pending_dg: list[bytes] = []  # read before the first poll: given with it
    pending_fr: list[LogMessage] = []
    frames = 0
    for m in log.messages:
        if m.topic == S.TOPIC_MAVLINK_READ:
            rec = m.json()
            t = rec.get("t")
            segs.append(_Segment(float(rec["mono_s"]), math.nan if t is None else float(t), S.unb64(rec["data_b64"]),
                                 tick=not rec.get("preamble", False)))
            segs[-1].datagrams += pending_dg
            segs[-1].frames += pending_fr
            pending_dg, pending_fr = [], []
        elif m.topic == S.TOPIC_RADAR_DATAGRAMS:
            (segs[-1].datagrams if segs else pending_dg).extend(S.unb64(d) for d in m.json()["datagrams_b64"])
        elif m.topic == S.TOPIC_CAMERA:
            (segs[-1].frames if segs else pending_fr).append(m)
            frames += 1
    return segs, frames


def _frame(log: FlightLog, msg: LogMessage, index: int) -> Frame:
    img = log.decode(msg)
    image = cv2.imdecode(np.frombuffer(img.data, np.uint8), cv2.IMREAD_COLOR)
    return Frame(img.timestamp.seconds + img.timestamp.nanos * 1e-9, image, index)


def _link_config(meta: dict[str, str]) -> LinkConfig:
    known = {f.name for f in dataclasses.fields(LinkConfig)}
    raw = {k: v for k, v in json.loads(meta["link_config"]).items() if k in known}
    if raw.get("origin") is not None:
        raw["origin"] = GeoPoint(**raw["origin"])
    raw["stream_rates_hz"] = dict(raw.get("stream_rates_hz", {}))
    for name, kind in (("envelope", CommandEnvelope), ("telemetry_limits", TelemetryLimits)):
        if isinstance(raw.get(name), dict):  # the flight's own limits, so a replay drops what it dropped
            raw[name] = kind(**raw[name])
    return LinkConfig(**raw)


def _radar_feed(meta: dict[str, str], correlator: str | None):
    from chaser_bt.radar.feed import (  # only replays with radar need it
        RadarFeed,
        RadarNoise,
    )
    from chaser_bt.radar.geometry import RadarPose
    from chaser_bt.radar.stream import QueueDatagramSource

    raw = json.loads(meta["radar_feed"])
    pose = RadarPose(np.asarray(raw["position_enu"], float), Rotation.from_quat(raw["quat_xyzw"]))
    return RadarFeed(QueueDatagramSource(maxlen=1_000_000), pose, noise=RadarNoise(**raw["noise"]),
                     correlator=correlator or raw["correlator"] or "gated", time_offset_s=raw["time_offset_s"],
                     track_timeout_s=raw["track_timeout_s"])


def recorded_camera_factory(log: FlightLog) -> Callable[[Any], Any] | None:
    """A factory for the ``camera`` resource as recorded (camera model and pipeline settings, the
    shipped detector), or None when the log has no camera."""
    if "camera" not in log.meta:
        return None
    from chaser_bt.vision.camera import (
        CameraModel,  # vision (and torch) only for logs with a camera
    )
    from chaser_bt.vision.detector.inference import Detector
    from chaser_bt.vision.pipeline import CameraSensor, PipelineConfig, VisionPipeline

    raw = json.loads(log.meta["camera"])
    model = CameraModel(**{k: tuple(v) if isinstance(v, list) else v for k, v in raw["model"].items()})
    config = PipelineConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in raw["pipeline"].items()})
    lag_frames = raw.get("lag_frames", 0)
    if lag_frames not in (0, 1):
        raise LogError(f"{log.path}: camera lag_frames {lag_frames!r}: replay knows 0 (inline) and 1 (a rehearsal's)")

    def build(source: Any) -> Any:
        pipeline = VisionPipeline(model, Detector(threads=1), config)
        if lag_frames:  # a rehearsal's camera: each frame processed in the tick after its own
            from chaser_bt.vision.lagged_camera import LaggedCamera

            return LaggedCamera(source, pipeline, stale_after_s=float(raw["stale_after_s"]))
        return CameraSensor(source, pipeline)

    return build


def replay(log: FlightLog, tree: MissionTree, *, correlator: str | None = None,
           camera_factory: Callable[[Any], Any] | None = None, rate_hz: float | None = None,
           on_start: Callable[[MissionRunner, VehicleLink, dict], None] | None = None) -> ReplayResult:
    """Tick ``tree`` on the recorded flight ``log`` (module docstring); what it did.

    Args:
        correlator: run this correlator (``"gated"``, ``"alg1"``) instead of the recorded one.
        camera_factory: builds the ``camera`` resource (a CameraSensor) around the replayed frame
            source; needed only for trees with vision behaviours.
        rate_hz: tick rate; the recorded one by default.
        on_start: called as ``on_start(runner, link, resources)`` after the tree's setup, before the
            first poll (e.g. to record the replay with :func:`~chaser_bt.log.recorder.attach_recorder`).

    Raises:
        LogError: the log lacks what replay needs (its metadata or its MAVLink reads).
    """
    meta = log.meta
    if "link_config" not in meta:
        raise LogError(f"{log.path}: no chaser_bt metadata: not a chaser-bt flight log")
    segments, n_frames = _segments(log)
    if not segments:
        raise LogError(f"{log.path}: no {S.TOPIC_MAVLINK_READ} records: nothing to replay")
    reset_blackboard()
    mono = [float(meta.get("link_opened_mono_s", segments[0].mono_s))]
    now = [math.nan]
    vehicle_end, ground_end = byte_pipe()
    link = VehicleLink.over_pipe(ground_end, _link_config(meta), monotonic=lambda: mono[0])
    clock = FunctionClock(lambda: now[0])
    resources: dict[str, Any] = {}
    associations: list[dict] = []
    feed = None
    if "radar_feed" in meta:
        feed = _radar_feed(meta, correlator)
        feed_update = feed.update

        def update(t: float, *args: Any, **kwargs: Any):
            picture = feed_update(t, *args, **kwargs)
            if not associations or associations[-1]["t"] != picture.t:
                a = picture.association
                associations.append({"t": picture.t, "associated_id": None if a is None else a.associated_id,
                                     "ownship_ids": sorted(picture.ownship_ids),
                                     "unassociated_ids": [] if a is None else list(a.unassociated_ids)})
            return picture

        feed.update = update  # type: ignore[method-assign]
        resources["radar"] = feed
    frames = _ReplayFrameSource()
    if camera_factory is not None:
        resources["camera"] = camera_factory(frames)
    runner = MissionRunner(tree, link, clock, rate_hz=rate_hz or float(meta.get("rate_hz", 10.0)), resources=resources)
    runner.setup()
    if on_start is not None:
        on_start(runner, link, resources)
    ended, n_dg, n_fr = "end of log", 0, 0
    for seg in segments:
        if feed is not None:
            for d in seg.datagrams:
                feed.source.push(d)
        n_dg += len(seg.datagrams)
        if camera_factory is not None:
            frames.pending += [_frame(log, m, n_fr + k) for k, m in enumerate(seg.frames)]
        n_fr += len(seg.frames)
        mono[0] = seg.mono_s
        vehicle_end.write(seg.data)
        try:
            link.poll()
        except VehicleError as exc:  # as the recorded mission did: stop there
            runner.stop(str(exc))
            ended = str(exc)
            break
        finally:
            vehicle_end.read()  # what the mission sent: nowhere to go
        now[0] = seg.t
        if seg.tick and runner.tick_if_due() and runner.finished:
            ended = f"root {runner.status.name}"
            runner.stop(ended)
            break
    return ReplayResult(list(runner.tick_log), associations, runner.ticks, runner.status.name, ended,
                        frames=n_frames, datagrams=n_dg, polls=len(segments),
                        correlator="" if feed is None else feed.correlator.name)


# --- FlightTrace ----------------------------------------------------------------------------------
_TARGET_KEYS = ("/target/telemetry", "/target/estimate", "/target/cue")  # in order of preference
_TARGET_STALE_S = 2.0
_VALIDATED_KEY = "/radar/validated_track"


class _Held:
    """Sample-and-hold over time-ordered ``(t, value)`` pairs, read at increasing times."""

    def __init__(self, series: list[tuple[float, Any]]) -> None:
        self.series, self._i = series, -1

    def at(self, t: float) -> tuple[float, Any] | None:
        while self._i + 1 < len(self.series) and self.series[self._i + 1][0] <= t + 1e-9:
            self._i += 1
        return self.series[self._i] if self._i >= 0 else None


def flight_trace(log: FlightLog) -> FlightTrace:
    """The per-tick trace of a recorded flight (a sample per tick with its running leaf).

    Ownship and mode from the vehicle state; phase from ``/mission/phase`` when the tree writes it,
    else the mode; target from the target's telemetry if the mission had it, else the camera
    estimate, else the radar cue, each held while at most 2 s old. Events: ``radar_validated``,
    ``airborne`` (armed and above 1 m), ``acquired`` (the first camera estimate), ``phase`` and
    ``mode`` changes. In-FOV and detection need the truth and stay NaN.
    """
    ticks = [(rec["t"], rec) for rec in (m.json() for m in log.topic(S.TOPIC_TREE)) if rec.get("tick") is not None]
    writes: dict[str, list[tuple[float, Any]]] = {}
    for m in log.topic(S.TOPIC_BLACKBOARD):
        rec = m.json()
        writes.setdefault(rec["key"], []).append((m.t, rec["value"]))
    events: list[TraceEvent] = []
    for key, name in ((_VALIDATED_KEY, "radar_validated"), ("/target/estimate", "acquired")):
        if writes.get(key):
            first_t, value = writes[key][0]
            events.append(TraceEvent(first_t, name, "" if name == "acquired" else str(value)))
    source = next((k for k in _TARGET_KEYS if writes.get(k)), "")
    targets = [(float(v.get("t") or t), np.array([np.nan if x is None else x for x in v["position_enu"]], float))
               for t, v in writes.get(source, []) if isinstance(v, dict) and v.get("position_enu")]
    state, target = _Held(writes.get("/vehicle/state", [])), _Held(targets)
    phase_key = _Held(writes.get(_PHASE_KEY, []))
    n = len(ticks)
    own, yaw, tgt = np.full((n, 3), np.nan), np.full(n, np.nan), np.full((n, 3), np.nan)
    modes, phases, tips = [""] * n, [""] * n, [""] * n
    airborne_seen = False
    for k, (t, rec) in enumerate(ticks):
        tips[k] = rec.get("tip", "")
        held = state.at(t)
        if held is not None and isinstance(held[1], dict):
            s = held[1]
            own[k] = [np.nan if v is None else v for v in s.get("position_enu") or (None,) * 3]
            yaw[k] = np.nan if s.get("yaw_enu_rad") is None else s["yaw_enu_rad"]
            modes[k] = s.get("mode") or ""
            if not airborne_seen and s.get("armed") and (s.get("alt_rel_m") or 0.0) > 1.0:
                airborne_seen = True
                events.append(TraceEvent(t, "airborne", f"{s['alt_rel_m']:.1f} m"))
        held = phase_key.at(t)
        phases[k] = str(held[1]) if held is not None else ("" if writes.get(_PHASE_KEY) else modes[k])
        held = target.at(t)
        if held is not None and t - held[0] <= _TARGET_STALE_S:
            tgt[k] = held[1]
        for name, labels in ((("phase", phases),) if writes.get(_PHASE_KEY) else ()) + (("mode", modes),):
            if labels[k] and (k == 0 or labels[k] != labels[k - 1]):
                events.append(TraceEvent(t, name, labels[k]))
    events.sort(key=lambda e: e.t)
    beliefs = []
    for m in log.topic(S.TOPIC_BELIEF):
        g = log.decode(m)
        mass = np.frombuffer(g.data, "<f4").reshape(-1, g.column_count).T  # back to (east, north)
        x0 = g.pose.position.x + 0.5 * g.cell_size.x  # the grid's origin is a cell corner
        y0 = g.pose.position.y + 0.5 * g.cell_size.y
        beliefs.append(BeliefSnapshot(m.t, x0 + g.cell_size.x * np.arange(mass.shape[0]),
                                      y0 + g.cell_size.y * np.arange(mass.shape[1]), mass.astype(float)))
    nan = np.full(n, np.nan)
    return FlightTrace(
        t=np.array([t for t, _ in ticks]), ownship_enu=own, ownship_yaw_rad=yaw, target_enu=tgt, in_fov=nan,
        detected=nan.copy(), mode=modes, phase=phases, tip=tips, events=events, beliefs=beliefs,
        target_source=source.rsplit("/", 1)[-1] or "none",
        meta={"log": str(log.path), "tree": log.meta.get("tree", ""), "truncated": log.truncated},
    )
