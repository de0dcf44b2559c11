"""The channels of a flight log and how each message is encoded (MCAP and the live Foxglove view).

Our own records are JSON with a JSON schema (Foxglove shows them in its Raw Messages and Plot
panels); what Foxglove draws natively uses its own protobuf schemas from ``foxglove.messages``
(``foxglove.SceneUpdate`` for the 3-D view, ``foxglove.Grid`` for the belief map,
``foxglove.CompressedImage`` and ``foxglove.ImageAnnotations`` for the video with boxes,
``foxglove.FrameTransform`` for the ownship). A flight therefore opens in Foxglove with no conversion.

Channels that replay needs (:data:`REPLAY_TOPICS`) are recorded losslessly: the raw MAVLink bytes
the link read, the radar datagrams the mission read, and (when asked) the camera frames as PNG.
"""

from __future__ import annotations

import base64
import dataclasses
import enum
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from foxglove import messages as fg
from scipy.spatial.transform import Rotation

__all__ = [
    "ChannelSpec", "CHANNELS", "REPLAY_TOPICS", "PROFILE", "FORMAT_VERSION",
    "TOPIC_MAVLINK_READ", "TOPIC_MAVLINK_IN", "TOPIC_MAVLINK_OUT", "TOPIC_TREE", "TOPIC_RETASK", "TOPIC_BLACKBOARD",
    "TOPIC_RADAR_DATAGRAMS", "TOPIC_RADAR_PICTURE", "TOPIC_TARGET", "TOPIC_BELIEF", "TOPIC_CAMERA",
    "TOPIC_CAMERA_BOXES", "TOPIC_SCENE_RADAR", "TOPIC_SCENE_TARGET", "TOPIC_TF",
    "jsonable", "json_bytes", "b64", "unb64", "timestamp", "ns",
]

PROFILE = "chaser-bt"
FORMAT_VERSION = 1

TOPIC_MAVLINK_READ = "/mavlink/read"  # raw bytes the link read, per poll, with the link's clock (replay)
TOPIC_MAVLINK_IN = "/mavlink/in"  # every decoded message from the vehicle side
TOPIC_MAVLINK_OUT = "/mavlink/out"  # every message the mission sent
TOPIC_TREE = "/tree/status"  # one per tick: status changes, root status, tip and its feedback
TOPIC_RETASK = "/tree/retask"  # every retask offered in flight, taken or not, with both trees' hashes (and its subtree)
TOPIC_BLACKBOARD = "/blackboard"  # every blackboard write
TOPIC_RADAR_DATAGRAMS = "/radar/datagrams"  # the datagrams the radar feed read, per read (replay)
TOPIC_RADAR_PICTURE = "/radar/picture"  # the feed's picture: tracks and the correlator's association
TOPIC_TARGET = "/target/estimate"  # target cues and estimates written to the blackboard
TOPIC_BELIEF = "/search/belief"  # the search belief summed over altitude, decimated
TOPIC_CAMERA = "/camera/image"  # camera frames, JPEG and decimated, or every frame as PNG
TOPIC_CAMERA_BOXES = "/camera/boxes"  # the vision pipeline's tracked box on each recorded frame
TOPIC_SCENE_RADAR = "/scene/radar"  # radar tracks in 3-D (ownship blue, others red)
TOPIC_SCENE_TARGET = "/scene/target"  # the current cue / estimate in 3-D
TOPIC_TF = "/tf"  # ENU -> ownship transform

REPLAY_TOPICS = (TOPIC_MAVLINK_READ, TOPIC_RADAR_DATAGRAMS, TOPIC_CAMERA)


@dataclass(frozen=True)
class ChannelSpec:
    """One channel: topic, schema (name, encoding, text) and message encoding."""

    topic: str
    schema_name: str
    schema_encoding: str  # "jsonschema" | "protobuf"
    schema_data: bytes
    message_encoding: str  # "json" | "protobuf"


def _json_channel(topic: str, name: str, properties: dict[str, Any]) -> ChannelSpec:
    schema = {"title": name, "type": "object", "properties": properties}
    return ChannelSpec(topic, name, "jsonschema", json.dumps(schema).encode(), "json")


def _foxglove_channel(topic: str, cls: Any) -> ChannelSpec:
    s = cls.get_schema()
    return ChannelSpec(topic, s.name, s.encoding, bytes(s.data), "protobuf")


_NUM, _STR, _INT = {"type": "number"}, {"type": "string"}, {"type": "integer"}
_ANY: dict[str, Any] = {}
_VEC = {"type": "array", "items": _NUM}
_MAV = {"type": {"type": "string"}, "sysid": _INT, "compid": _INT, "fields": {"type": "object"}}

CHANNELS: dict[str, ChannelSpec] = {c.topic: c for c in (
    _json_channel(TOPIC_MAVLINK_READ, "chaser_bt.MavlinkRead",
                  {"mono_s": _NUM, "t": _NUM, "data_b64": _STR, "preamble": {"type": "boolean"}}),
    _json_channel(TOPIC_MAVLINK_IN, "chaser_bt.MavlinkMessage", _MAV),
    _json_channel(TOPIC_MAVLINK_OUT, "chaser_bt.MavlinkMessage", _MAV),
    _json_channel(TOPIC_TREE, "chaser_bt.TreeTick", {
        "t": _NUM, "tick": _INT, "root": _STR, "tip": _STR,
        "changes": {"type": "array", "items": {"type": "object", "properties": {"node": _STR, "old": _STR, "new": _STR}}},
    }),
    _json_channel(TOPIC_RETASK, "chaser_bt.Retask", {
        "t": _NUM, "accepted": {"type": "boolean"}, "origin": _STR, "name": _STR, "old_hash": _STR,
        "new_hash": _STR, "message": _STR, "subtree": {"type": ["string", "null"]},  # null: the whole tree
    }),
    _json_channel(TOPIC_BLACKBOARD, "chaser_bt.BlackboardWrite",
                  {"key": _STR, "client": _STR, "activity": _STR, "value": _ANY}),
    _json_channel(TOPIC_RADAR_DATAGRAMS, "chaser_bt.RadarDatagrams",
                  {"t": _NUM, "datagrams_b64": {"type": "array", "items": _STR}}),
    _json_channel(TOPIC_RADAR_PICTURE, "chaser_bt.RadarPicture", {
        "t": _NUM, "last_scan_t": _NUM, "associated_id": _INT,
        "ownship_ids": {"type": "array", "items": _INT}, "unassociated_ids": {"type": "array", "items": _INT},
        "tracks": {"type": "array", "items": {"type": "object", "properties": {
            "id": _INT, "t": _NUM, "position_enu": _VEC, "velocity_enu": _VEC, "confidence": _NUM}}},
        "counts": {"type": "object"},
    }),
    _json_channel(TOPIC_TARGET, "chaser_bt.TargetEstimate", {
        "key": _STR, "t": _NUM, "source": _STR, "track_id": _INT, "position_enu": _VEC, "velocity_enu": _VEC,
        "covariance_enu": {"type": "array", "items": _VEC}, "range_m": _NUM, "confidence": _NUM,
    }),
    _foxglove_channel(TOPIC_BELIEF, fg.Grid),
    _foxglove_channel(TOPIC_CAMERA, fg.CompressedImage),
    _foxglove_channel(TOPIC_CAMERA_BOXES, fg.ImageAnnotations),
    _foxglove_channel(TOPIC_SCENE_RADAR, fg.SceneUpdate),
    _foxglove_channel(TOPIC_SCENE_TARGET, fg.SceneUpdate),
    _foxglove_channel(TOPIC_TF, fg.FrameTransform),
)}


# --- JSON values -------------------------------------------------------------------------------
_MAX_ARRAY = 64  # bigger arrays are summarised (shape, dtype); the belief has its own channel


def jsonable(value: Any, depth: int = 0) -> Any:
    """``value`` as plain JSON data: dataclasses as dicts, arrays as lists, NaN/inf as None.

    Anything else becomes its ``repr`` (shortened): a log must never fail on a value it cannot show.
    """
    if depth > 6:
        return repr(value)[:200]
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, enum.Enum):
        return value.name
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.ndarray):
        if value.size > _MAX_ARRAY:
            return {"shape": list(value.shape), "dtype": str(value.dtype)}
        return jsonable(value.tolist(), depth + 1)
    if isinstance(value, Rotation):
        return {"quat_xyzw": [float(q) for q in value.as_quat()]}
    if isinstance(value, (bytes, bytearray)):
        return {"b64": b64(bytes(value))}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: jsonable(getattr(value, f.name), depth + 1) for f in dataclasses.fields(value)
                if not f.name.startswith("_")}
    if isinstance(value, Mapping):
        return {str(k): jsonable(v, depth + 1) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)) or type(value).__name__ == "deque":
        items = sorted(value) if isinstance(value, (set, frozenset)) else list(value)
        return [jsonable(v, depth + 1) for v in items[:_MAX_ARRAY * 4]]
    return repr(value)[:200]


def json_bytes(value: Any) -> bytes:
    """Compact strict JSON (no NaN) of :func:`jsonable` ``(value)``."""
    return json.dumps(jsonable(value), separators=(",", ":"), allow_nan=False).encode()


def b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def unb64(text: str) -> bytes:
    return base64.b64decode(text.encode("ascii"))


def ns(t_s: float) -> int:
    """Seconds to integer nanoseconds (MCAP log time)."""
    return int(round(t_s * 1e9))


def timestamp(t_s: float) -> fg.Timestamp:
    t_ns = max(ns(t_s), 0)
    return fg.Timestamp(sec=t_ns // 1_000_000_000, nsec=t_ns % 1_000_000_000)
