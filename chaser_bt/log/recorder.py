"""Recording a flight: everything a mission sees and decides, into MCAP (and the live view).

:func:`attach_recorder` hooks a :class:`Recorder` onto a mission that is set up and about to tick
(``chaser-bt run|rehearse --record FILE.mcap``). It observes, without changing what the mission does:

- the vehicle link: every decoded MAVLink message in and out (its listeners), and for replay the raw
  bytes each :meth:`~chaser_bt.vehicle.VehicleLink.poll` read with the link's clock at that poll;
- the runner: the tree's status changes and the running leaf after every tick;
- the blackboard: every write, through py_trees' activity stream (target cues and estimates also
  as 3-D markers, the search belief, decimated, as a ``foxglove.Grid``);
- the ``radar`` resource (a RadarFeed): the datagrams it reads and the picture it makes of them,
  correlator association included;
- the ``camera`` resource (a CameraSensor): its frames, JPEG and decimated for viewing, or every
  frame as PNG for replay (``frame_format="png"``, ``frame_period_s=0``), and the tracked box; of a
  threaded camera (a :class:`~chaser_bt.vision.perception.PerceptionWorker`) the frames it processed
  and their boxes, taken from its latest result after each tick (records are written on the tick's
  thread only).

Records are stamped with mission time (``log_time`` in ns). Crash safety: the MCAP file is written
in small chunks and flushed to the operating system at least once a second of wall time (at the
first record after the second is up; every poll writes one), so a SIGKILL loses at most that last
second; :func:`chaser_bt.log.replay.read_log` reads such an unfinished file.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Protocol, Sequence

import cv2
import numpy as np
import py_trees
from foxglove import messages as fg
from mcap.writer import CompressionType, Writer

from chaser_bt.cue import TargetCue
from chaser_bt.log import schemas as S
from chaser_bt.mission.runner import MissionRunner
from chaser_bt.vehicle import VehicleLink

if TYPE_CHECKING:  # chaser_bt.search is slow to import; a belief is recognised by its shape
    from chaser_bt.search.belief import BeliefGrid

__all__ = ["LogSink", "McapSink", "TopicSink", "Recorder", "attach_recorder"]

log = logging.getLogger(__name__)

_BB_WRITES = {"WRITE", "INITIALISED", "UNSET"}
_NOT_REPLAYED = {"BAD_DATA", "COMMAND_ACK", "STATUSTEXT", "PARAM_VALUE"}  # answers and news, not state
_ACTIVITY_MAX = 100_000  # drained every tick and poll; only a runaway tree fills it


class LogSink(Protocol):
    """Where records go: an MCAP file, the live server."""

    def write(self, spec: S.ChannelSpec, t_ns: int, data: bytes) -> None: ...

    def close(self) -> None: ...


class TopicSink:
    """Keeps one topic's records (their bytes) in memory: what ``chaser-bt replay`` compares with a log."""

    def __init__(self, topic: str) -> None:
        self.topic = topic
        self.records: list[bytes] = []

    def write(self, spec: S.ChannelSpec, t_ns: int, data: bytes) -> None:
        if spec.topic == self.topic:
            self.records.append(data)

    def close(self) -> None:
        """Nothing to release: the records stay readable after the recorder closes."""


class McapSink:
    """An MCAP file written crash-safe: zstd chunks flushed at least every ``flush_period_s`` of wall time.

    Args:
        path: the file (created or replaced).
        metadata: MCAP metadata records written first (name -> string map).
        flush_period_s: at most this much wall time between flushes.
        wall: wall clock for the flush period (injectable for tests).
    """

    def __init__(self, path: str | Path, metadata: Mapping[str, Mapping[str, str]] | None = None, *,
                 flush_period_s: float = 1.0, wall: Callable[[], float] = time.monotonic) -> None:
        self.path = Path(path)
        self._fh = self.path.open("wb")
        self._writer = Writer(self._fh, chunk_size=256 * 1024, compression=CompressionType.ZSTD)
        self._writer.start(profile=S.PROFILE, library="chaser-bt")
        for name, data in (metadata or {}).items():
            self._writer.add_metadata(name, dict(data))
        self._channels: dict[str, int] = {}
        self._schemas: dict[tuple[str, str], int] = {}
        self._seq = 0
        self._wall = wall
        self._period = flush_period_s
        self._last_flush = wall()
        self._writer.flush()
        self.closed = False

    def write(self, spec: S.ChannelSpec, t_ns: int, data: bytes) -> None:
        if self.closed:
            return
        cid = self._channels.get(spec.topic)
        if cid is None:
            key = (spec.schema_name, spec.schema_encoding)
            sid = self._schemas.get(key)
            if sid is None:
                sid = self._writer.register_schema(spec.schema_name, spec.schema_encoding, spec.schema_data)
                self._schemas[key] = sid
            cid = self._channels[spec.topic] = self._writer.register_channel(spec.topic, spec.message_encoding, sid)
        self._seq += 1
        self._writer.add_message(cid, log_time=t_ns, data=data, publish_time=t_ns, sequence=self._seq)
        now = self._wall()
        if now - self._last_flush >= self._period:
            self._writer.flush()  # ends the chunk and hands it to the OS: survives a SIGKILL
            self._last_flush = now

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self._writer.finish()
        self._fh.close()


class Recorder:
    """Turns what a mission sees and decides into records on every sink (see the module docstring).

    Args:
        sinks: where records go.
        clock: mission time for stamps (the runner's clock).
        belief_period_s: at most one belief map per this much mission time.
        frame_period_s: at most one camera frame per this much mission time (0: every frame).
        frame_format: ``"jpeg"`` (lossy, small) or ``"png"`` (lossless: replay re-runs the detector exactly).
    """

    def __init__(self, sinks: Sequence[LogSink], clock: Callable[[], float], *, belief_period_s: float = 1.0,
                 frame_period_s: float = 0.2, frame_format: str = "jpeg") -> None:
        if frame_format not in ("jpeg", "png"):
            raise ValueError(f"frame_format must be 'jpeg' or 'png', got {frame_format!r}")
        self.sinks = list(sinks)
        self._clock = clock
        self.belief_period_s = belief_period_s
        self.frame_period_s = frame_period_s
        self.frame_format = frame_format
        self.counts: dict[str, int] = {}
        self.errors = 0
        self._t = 0.0
        self._last_belief_t = -math.inf
        self._last_frame_t = -math.inf
        self._last_picture_t: float | None = None
        self._recorded_frame: Any = None
        self._camera_worker: Any = None
        self._worker_result: Any = None
        self._rx = bytearray()
        self._undo: list[Callable[[], None]] = []
        self._runner: MissionRunner | None = None
        self._logged_changes = 0
        self._own_activity_stream = False
        self.closed = False

    # -- writing ----------------------------------------------------------------------------------
    def now(self) -> float:
        """Mission time for a stamp: the clock, held at its last value while it has none, never backwards."""
        t = self._clock()
        if math.isfinite(t) and t > self._t:
            self._t = t
        return self._t

    def write(self, topic: str, data: bytes, t: float | None = None) -> None:
        """One record on ``topic`` (a key of :data:`~chaser_bt.log.schemas.CHANNELS`) at mission time ``t`` (now)."""
        if self.closed:
            return
        spec = S.CHANNELS[topic]
        t_ns = S.ns(self.now() if t is None else max(t, 0.0))
        for sink in self.sinks:
            sink.write(spec, t_ns, data)
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def _guarded(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        """``fn`` that logs and counts its errors instead of raising: recording must never stop a flight."""
        def call(*args: Any, **kwargs: Any) -> Any:
            try:
                return fn(*args, **kwargs)
            except Exception:
                self.errors += 1
                if self.errors <= 3:
                    log.exception("recorder: %s failed", getattr(fn, "__name__", fn))
                return None
        return call

    # -- attaching --------------------------------------------------------------------------------
    def attach(self, runner: MissionRunner, link: VehicleLink, resources: Mapping[str, Any]) -> Recorder:
        """Observe ``runner``, ``link`` and the ``radar``/``camera`` resources (see the module docstring)."""
        self._runner = runner
        self._logged_changes = len(runner.tick_log)
        runner.on_tick(self._guarded(self._on_tick))
        runner.on_retask(self._guarded(lambda r: self.write(S.TOPIC_RETASK, S.json_bytes(r.as_dict()), r.t)))
        link.add_listener(on_receive=self._guarded(self._on_mavlink_in), on_send=self._guarded(self._on_mavlink_out))
        self._guarded(self._record_preamble)(link)
        self._wrap_link(link)
        if py_trees.blackboard.Blackboard.activity_stream is None:
            py_trees.blackboard.Blackboard.enable_activity_stream(maximum_size=_ACTIVITY_MAX)
            self._own_activity_stream = True
        else:
            py_trees.blackboard.Blackboard.activity_stream.maximum_size = max(
                py_trees.blackboard.Blackboard.activity_stream.maximum_size, _ACTIVITY_MAX)
        radar = resources.get("radar")
        if radar is not None and hasattr(radar, "source") and hasattr(radar, "update"):
            self._wrap_radar(radar)
        camera = resources.get("camera")
        if camera is not None and callable(getattr(camera, "latest", None)):
            self._camera_worker = camera  # its frames are read in its own thread: recorded from its results
        elif camera is not None and hasattr(camera, "source") and hasattr(camera, "pipeline"):
            self._wrap_camera(camera)
        return self

    def _replace(self, obj: Any, name: str, value: Any) -> None:
        """Set ``obj.name`` (an instance attribute shadowing the method), undone by :meth:`close`."""
        had = name in vars(obj)
        old = vars(obj).get(name)
        setattr(obj, name, value)
        self._undo.append(lambda: setattr(obj, name, old) if had else delattr(obj, name))

    def _wrap_link(self, link: VehicleLink) -> None:
        """Record every read from the vehicle and the link time of each poll (the link's wire tap)."""
        self._undo.append(link.add_wire_tap(self._rx.extend, self._guarded(self._on_poll)))

    def _record_preamble(self, link: VehicleLink) -> None:
        """The latest message of each type the link already had from its vehicle, as a read that
        replay feeds in before the first recorded poll (and does not tick after): the replayed link
        then knows the vehicle, its home and its state, as the recorded one did when recording began."""
        if link.target_sysid is None:
            return
        state = getattr(link.conn, "sysid_state", {}).get(link.target_sysid)
        if state is None:
            return
        msgs = [m for m in state.messages.values() if hasattr(m, "get_msgbuf") and m.get_type() not in _NOT_REPLAYED
                and (link.target_compid is None or m.get_srcComponent() == link.target_compid)]
        order = {"HEARTBEAT": 0, "HOME_POSITION": 1}
        msgs.sort(key=lambda m: (order.get(m.get_type(), 2), m.get_type()))
        data = b"".join(bytes(m.get_msgbuf()) for m in msgs)
        t = self._clock()
        self.write(S.TOPIC_MAVLINK_READ, S.json_bytes(
            {"mono_s": link.now(), "t": t if math.isfinite(t) else None, "data_b64": S.b64(data), "preamble": True}))

    def _wrap_radar(self, feed: Any) -> None:
        self._replace(feed, "source", _RecordingDatagramSource(feed.source, self))
        feed_update = feed.update

        def update(t: float, *args: Any, **kwargs: Any) -> Any:
            picture = feed_update(t, *args, **kwargs)
            if picture.t != self._last_picture_t:
                self._last_picture_t = picture.t
                self._guarded(self._on_radar_picture)(picture)
            return picture

        self._replace(feed, "update", update)

    def _wrap_camera(self, sensor: Any) -> None:
        self._replace(sensor, "source", _RecordingFrameSource(sensor.source, self))
        self._camera = sensor

    # -- observers --------------------------------------------------------------------------------
    def _on_poll(self, mono: float) -> None:
        t = self._clock()
        data = bytes(self._rx)
        self._rx.clear()
        self.write(S.TOPIC_MAVLINK_READ, S.json_bytes(
            {"mono_s": mono, "t": t if math.isfinite(t) else None, "data_b64": S.b64(data)}))
        self._drain_blackboard()

    def _on_mavlink_in(self, msg: Any) -> None:
        self.write(S.TOPIC_MAVLINK_IN, _mavlink_json(msg))

    def _on_mavlink_out(self, msg: Any) -> None:
        self.write(S.TOPIC_MAVLINK_OUT, _mavlink_json(msg))

    def _on_tick(self, changes: list) -> None:
        self._log_tree(ticked=True)
        self._drain_blackboard()
        self._record_worker_result()
        self._log_camera_boxes()

    def _log_tree(self, ticked: bool) -> None:
        runner = self._runner
        if runner is None:
            return
        new = runner.tick_log[self._logged_changes:]
        self._logged_changes = len(runner.tick_log)
        if not ticked and not new:
            return
        self.write(S.TOPIC_TREE, S.json_bytes({
            "t": self.now(), "tick": runner.ticks if ticked else None, "root": runner.status.name,
            "tip": runner.tip_message(), "changes": [{"node": c.node, "old": c.old, "new": c.new} for c in new],
        }))

    def _drain_blackboard(self) -> None:
        stream = py_trees.blackboard.Blackboard.activity_stream
        if stream is None:
            return
        items, stream.data = stream.data, []
        for item in items:
            if item.activity_type not in _BB_WRITES:
                continue
            value = item.current_value
            self.write(S.TOPIC_BLACKBOARD, S.json_bytes(
                {"key": item.key, "client": item.client_name, "activity": item.activity_type, "value": value}))
            if isinstance(value, TargetCue):
                self._log_target(item.key, value)
            belief = getattr(value, "belief", None)  # a SearchSnapshot: its BeliefGrid
            if hasattr(belief, "spec") and hasattr(belief, "p"):
                self._log_belief(getattr(value, "t", self.now()), belief)

    def _log_target(self, key: str, cue: TargetCue) -> None:
        fields = S.jsonable(cue)
        self.write(S.TOPIC_TARGET, S.json_bytes({"key": key, **fields}))
        colour = fg.Color(r=1.0, g=0.6, b=0.0, a=0.9)
        entity = fg.SceneEntity(
            timestamp=S.timestamp(cue.t), frame_id="enu", id=key, lifetime=fg.Duration(sec=2, nsec=0),
            spheres=[fg.SpherePrimitive(pose=_pose(cue.position_enu), size=fg.Vector3(x=3.0, y=3.0, z=3.0), color=colour)],
            texts=[fg.TextPrimitive(pose=_pose(np.asarray(cue.position_enu) + (0.0, 0.0, 4.0)), billboard=True,
                                    font_size=14.0, scale_invariant=True, color=colour, text=f"{key} ({cue.source})")],
        )
        self.write(S.TOPIC_SCENE_TARGET, fg.SceneUpdate(entities=[entity]).encode())

    def _log_belief(self, t: float, belief: BeliefGrid) -> None:
        if t - self._last_belief_t < self.belief_period_s:
            return
        self._last_belief_t = t
        self.write(S.TOPIC_BELIEF, belief_grid(t, belief).encode())

    def _on_radar_picture(self, picture: Any) -> None:
        a = picture.association
        tracks = sorted(picture.tracks.values(), key=lambda tr: tr.track_id)
        self.write(S.TOPIC_RADAR_PICTURE, S.json_bytes({
            "t": picture.t, "last_scan_t": picture.last_scan_t,
            "associated_id": None if a is None else a.associated_id,
            "ownship_ids": sorted(picture.ownship_ids), "unassociated_ids": [] if a is None else list(a.unassociated_ids),
            "tracks": [{"id": tr.track_id, "t": tr.t, "position_enu": tr.position_enu, "velocity_enu": tr.velocity_enu,
                        "confidence": tr.confidence} for tr in tracks],
            "counts": picture.counts,
        }))
        own = picture.ownship_ids
        entities = [fg.SceneEntity(
            timestamp=S.timestamp(tr.t), frame_id="enu", id=f"radar/{tr.track_id}", lifetime=fg.Duration(sec=1, nsec=0),
            spheres=[fg.SpherePrimitive(pose=_pose(tr.position_enu), size=fg.Vector3(x=2.0, y=2.0, z=2.0),
                                        color=fg.Color(r=0.1, g=0.4, b=1.0, a=0.8) if tr.track_id in own
                                        else fg.Color(r=1.0, g=0.1, b=0.1, a=0.8))],
        ) for tr in tracks]
        self.write(S.TOPIC_SCENE_RADAR, fg.SceneUpdate(entities=entities).encode())

    def _record_datagrams(self, datagrams: list[bytes]) -> None:
        if datagrams:
            self.write(S.TOPIC_RADAR_DATAGRAMS, S.json_bytes(
                {"t": self.now(), "datagrams_b64": [S.b64(bytes(d)) for d in datagrams]}))

    def _record_frame(self, frame: Any) -> None:
        if frame.t - self._last_frame_t < self.frame_period_s:
            return
        self._last_frame_t = frame.t
        ok, buf = cv2.imencode(".png" if self.frame_format == "png" else ".jpg", frame.image,
                               [] if self.frame_format == "png" else [cv2.IMWRITE_JPEG_QUALITY, 80])
        if not ok:
            raise ValueError(f"could not encode frame {frame.index} as {self.frame_format}")
        self._recorded_frame = frame
        self.write(S.TOPIC_CAMERA, fg.CompressedImage(timestamp=S.timestamp(frame.t), frame_id="camera",
                                                      data=buf.tobytes(), format=self.frame_format).encode(), t=frame.t)

    def _record_worker_result(self) -> None:
        """A threaded camera's latest processed frame (decimated like the others) and its box, once each."""
        worker = self._camera_worker
        result = None if worker is None else worker.latest()
        if result is None or result is self._worker_result:
            return
        self._worker_result = result
        self._record_frame(result.frame)
        if self._recorded_frame is result.frame:
            self._recorded_frame = None
            self._write_boxes(result.frame, result.box)

    def _log_camera_boxes(self) -> None:
        sensor = getattr(self, "_camera", None)
        if sensor is None or sensor.last_frame is None or sensor.last_frame is not self._recorded_frame:
            return
        frame, track = sensor.last_frame, sensor.pipeline.track
        self._recorded_frame = None  # one annotation per recorded frame
        self._write_boxes(frame, None if track is None else track.box)

    def _write_boxes(self, frame: Any, box: Any) -> None:
        points = []
        if box is not None:
            x0, y0, x1, y1 = (float(v) for v in box)
            points.append(fg.PointsAnnotation(
                timestamp=S.timestamp(frame.t), type=fg.PointsAnnotationType.LineLoop, thickness=2.0,
                outline_color=fg.Color(r=0.0, g=1.0, b=0.0, a=1.0),
                points=[fg.Point2(x=x0, y=y0), fg.Point2(x=x1, y=y0), fg.Point2(x=x1, y=y1), fg.Point2(x=x0, y=y1)]))
        self.write(S.TOPIC_CAMERA_BOXES, fg.ImageAnnotations(points=points).encode(), t=frame.t)

    def log_pose(self, state: Any) -> None:
        """The ownship as a ``/tf`` transform ENU -> ownship (called every tick)."""
        pos = np.asarray(state.position_enu, float)
        if not np.all(np.isfinite(pos)):
            return
        q = state.attitude.as_quat() if state.attitude is not None else (0.0, 0.0, 0.0, 1.0)
        self.write(S.TOPIC_TF, fg.FrameTransform(
            timestamp=S.timestamp(self.now()), parent_frame_id="enu", child_frame_id="ownship",
            translation=fg.Vector3(x=float(pos[0]), y=float(pos[1]), z=float(pos[2])),
            rotation=fg.Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))).encode())

    # -- closing ----------------------------------------------------------------------------------
    def close(self) -> None:
        """Write what the stop changed in the tree, undo the hooks, finish every sink. Idempotent."""
        if self.closed:
            return
        self._guarded(self._log_tree)(ticked=False)
        self._guarded(self._drain_blackboard)()
        self.closed = True
        for undo in reversed(self._undo):
            undo()
        self._undo.clear()
        if self._own_activity_stream:
            py_trees.blackboard.Blackboard.disable_activity_stream()
        for sink in self.sinks:
            try:
                sink.close()
            except Exception:
                log.exception("recorder: closing %s failed", sink)

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _RecordingDatagramSource:
    """A radar datagram source that shows the recorder every batch it hands out."""

    def __init__(self, source: Any, recorder: Recorder) -> None:
        self.inner, self._recorder = source, recorder

    def receive(self) -> list[bytes]:
        out = self.inner.receive()
        self._recorder._guarded(self._recorder._record_datagrams)(out)
        return out

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


class _RecordingFrameSource:
    """A frame source that shows the recorder every frame it hands out."""

    reads_regions = False  # the log keeps whole frames, whatever the camera could read out

    def __init__(self, source: Any, recorder: Recorder) -> None:
        self.inner, self._recorder = source, recorder

    def read(self, t: float) -> Any:
        return self._shown(self.inner.read(t))

    def develop(self, shot: Any, regions: Any = None) -> Any:
        """A source whose shots are developed a tick later (a rehearsal's lagged camera): the frame
        is recorded when developed, the tick that processes it."""
        return self._shown(self.inner.develop(shot, regions))

    def _shown(self, frame: Any) -> Any:
        if frame is not None:
            self._recorder._guarded(self._recorder._record_frame)(frame)
        return frame

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def _mavlink_json(msg: Any) -> bytes:
    fields = msg.to_dict()
    mtype = fields.pop("mavpackettype", msg.get_type())
    return S.json_bytes({"type": mtype, "sysid": msg.get_srcSystem(), "compid": msg.get_srcComponent(), "fields": fields})


def _pose(p: Any) -> fg.Pose:
    x, y, z = (float(v) for v in p)
    return fg.Pose(position=fg.Vector3(x=x, y=y, z=z), orientation=fg.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))


def belief_grid(t: float, belief: BeliefGrid) -> fg.Grid:
    """The belief summed over altitude as a ``foxglove.Grid`` in the ``enu`` frame (float32 ``mass``)."""
    spec = belief.spec
    mass = belief.p.reshape(spec.shape).sum(axis=2)  # (east, north)
    nx, ny = mass.shape
    # Grid rows run along the pose's y (north), columns along x (east); the origin is a cell corner.
    data = np.ascontiguousarray(mass.T, dtype="<f4").tobytes()
    ox, oy, oz = spec.origin_enu
    half = 0.5 * spec.spacing_m
    return fg.Grid(
        timestamp=S.timestamp(t), frame_id="enu", pose=_pose((ox - half, oy - half, oz)), column_count=nx,
        cell_size=fg.Vector2(x=spec.spacing_m, y=spec.spacing_m), row_stride=4 * nx, cell_stride=4,
        fields=[fg.PackedElementField(name="mass", offset=0, type=fg.PackedElementFieldNumericType.Float32)], data=data,
    )


def attach_recorder(runner: MissionRunner, link: VehicleLink, resources: Mapping[str, Any], path: str | Path | None, *,
                    sinks: Sequence[LogSink] = (), frame_format: str = "jpeg", frame_period_s: float = 0.2,
                    flush_period_s: float = 1.0) -> Recorder:
    """Record the mission of ``runner`` (set up, before its first tick) to the MCAP file ``path``.

    ``sinks`` adds more outputs (e.g. :class:`chaser_bt.log.live.LiveSink`); ``path`` None records to
    those only. Close the returned recorder when the mission has stopped.
    """
    meta = _metadata(runner, link, resources)
    all_sinks: list[LogSink] = list(sinks)
    if path is not None:
        all_sinks.insert(0, McapSink(path, {"chaser_bt": meta}, flush_period_s=flush_period_s))
    recorder = Recorder(all_sinks, runner.clock.now, frame_format=frame_format, frame_period_s=frame_period_s)
    recorder.attach(runner, link, resources)
    runner.on_tick(recorder._guarded(lambda _changes: recorder.log_pose(link.state)))
    return recorder


def _metadata(runner: MissionRunner, link: VehicleLink, resources: Mapping[str, Any]) -> dict[str, str]:
    """What replay needs besides the records: tick rate, link configuration, radar feed settings."""
    meta = {
        "format_version": str(S.FORMAT_VERSION),
        "tree": runner.tree.name,
        "rate_hz": repr(1.0 / runner.period_s),
        # Never the signing key: a log is shared; replay reads signed bytes without checking them.
        "link_config": S.json_bytes({k: v for k, v in S.jsonable(link.config).items() if k != "signing"}).decode(),
        "link_signed": str(getattr(link.config, "signing", None) is not None).lower(),
        "link_opened_mono_s": repr(float(link.opened_at_s)),  # the link's clock when it opened (its timers start there)
        "recorded_at_unix_s": repr(time.time()),
    }
    radar = resources.get("radar")
    if radar is not None and hasattr(radar, "pose"):
        meta["radar_feed"] = S.json_bytes({
            "position_enu": radar.pose.position_enu, "quat_xyzw": radar.pose.rotation.as_quat(),
            "noise": radar.noise, "correlator": getattr(radar.correlator, "name", ""),
            "time_offset_s": radar.time_offset_s, "track_timeout_s": radar.track_timeout_s,
        }).decode()
    camera = resources.get("camera")
    pipeline = getattr(camera, "pipeline", None)
    if pipeline is not None and hasattr(pipeline, "camera") and hasattr(pipeline, "config"):
        camera_meta = {"model": pipeline.camera, "pipeline": pipeline.config}
        if getattr(camera, "lag_frames", 0):  # a rehearsal's camera: replay processes each frame a tick late too
            camera_meta.update(lag_frames=camera.lag_frames, stale_after_s=camera.stale_after_s)
        meta["camera"] = S.json_bytes(camera_meta).decode()
    return meta
