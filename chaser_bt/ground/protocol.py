"""The ground stream's wire format, version 1 (docs/ground.md): what the chaser tells the ground.

The paper's fourth task (sections 1 and 2.2) is streaming the target estimate, the radar tracks and
the video with the detector's boxes to the ground. Every message is one UDP datagram of at most
:data:`MAX_DATAGRAM` bytes, so a plain script with ``socket`` and ``json`` reads it:

- **JSON messages** start with ``{``: one UTF-8 JSON object with ``"v": 1``, ``"type"``
  (``status``, ``estimate``, ``cue``, ``tracks``), ``"seq"`` (one counter per sender, to see
  losses) and ``"t"`` (mission time, s). Positions are ENU metres in the mission frame, whose
  geodetic origin each ``status`` carries; non-finite numbers are sent as ``null``.
- **Video chunks** start with the 4 bytes ``CBTV``: a 22-byte little-endian header
  (``<4sBBIHHd``: magic, version, flags, frame id, chunk index, chunk count, mission time) and a
  slice of one JPEG image with the boxes already drawn. A frame is whole when all ``chunk count``
  chunks of its ``frame id`` have arrived; a frame missing a chunk is dropped (UDP, no resend).

Pure functions: encoding and decoding here, sockets in :mod:`chaser_bt.ground.sender`.
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np

from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.find import Find

__all__ = [
    "VERSION", "MAX_DATAGRAM", "VIDEO_MAGIC", "VIDEO_HEADER", "Box", "VideoChunk", "FrameAssembler",
    "json_datagram", "parse_datagram", "status_message", "estimate_message", "cue_message", "tracks_message",
    "chunk_frame", "parse_chunk", "draw_boxes", "encode_jpeg",
]

VERSION = 1
MAX_DATAGRAM = 60_000  # below UDP's 65 507-byte limit with room to spare on every stack
VIDEO_MAGIC = b"CBTV"
VIDEO_HEADER = struct.Struct("<4sBBIHHd")  # magic, version, flags, frame id, chunk index, chunk count, t
BOX_COLOUR_BGR = (0, 0, 255)  # red: what the detector/tracker holds as the target


@dataclass(frozen=True)
class Box:
    """A box to draw on a frame: (x0, y0, x1, y1) pixels, a label (class and score)."""

    xyxy: tuple[float, float, float, float]
    label: str = ""


@dataclass(frozen=True)
class VideoChunk:
    """One decoded video datagram."""

    frame_id: int
    index: int
    count: int
    t: float
    payload: bytes


def _clean(value: Any) -> Any:
    """JSON-safe: numpy to Python, non-finite floats to None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_clean(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def json_datagram(kind: str, seq: int, t: float, body: dict[str, Any]) -> bytes:
    """One JSON message (``kind`` is its ``type``).

    Raises:
        ValueError: the encoded message would not fit one datagram.
    """
    msg = {"v": VERSION, "type": kind, "seq": int(seq), "t": t, **body}
    data = json.dumps(_clean(msg), separators=(",", ":"), allow_nan=False).encode("utf-8")
    if len(data) > MAX_DATAGRAM:
        raise ValueError(f"{kind} message of {len(data)} bytes exceeds one datagram ({MAX_DATAGRAM})")
    return data


def parse_datagram(data: bytes) -> dict[str, Any] | VideoChunk:
    """A JSON message as a dict, or a :class:`VideoChunk`.

    Raises:
        ValueError: neither (garbage, a truncated chunk, another version, nesting too deep for
            Python's JSON reader): the only error, whatever ``data`` holds.
    """
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ValueError(f"a datagram is bytes, not {type(data).__name__}")
    data = bytes(data)
    if data[:4] == VIDEO_MAGIC:
        return parse_chunk(data)
    try:
        msg = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
        raise ValueError(f"not a ground-stream datagram: {type(e).__name__}") from None
    if not isinstance(msg, dict) or msg.get("v") != VERSION or "type" not in msg:
        raise ValueError(f"not a version {VERSION} ground-stream message")
    return msg


def _vec(v: np.ndarray | None) -> list[float] | None:
    return None if v is None else [float(x) for x in np.asarray(v, float).ravel()]


def status_message(
    *, position_enu: np.ndarray, velocity_enu: np.ndarray, yaw_enu_rad: float, mode: str, armed: bool,
    alt_rel_m: float, origin: tuple[float, float, float] | None, counters: dict[str, int] | None = None,
) -> dict[str, Any]:
    """The ownship: where it is, how it flies, and the ENU frame's geodetic origin (lat, lon, alt)."""
    body: dict[str, Any] = {
        "position_enu": _vec(position_enu), "velocity_enu": _vec(velocity_enu), "yaw_enu_rad": yaw_enu_rad,
        "mode": mode, "armed": armed, "alt_rel_m": alt_rel_m,
        "origin": None if origin is None else {"lat_deg": origin[0], "lon_deg": origin[1], "alt_m": origin[2]},
    }
    if counters is not None:
        body["counters"] = dict(counters)
    return body


def cue_message(cue: TargetCue) -> dict[str, Any]:
    """Any target cue (radar, telemetry): position, 1-sigma per ENU axis, velocity, its own time."""
    return {
        "source": cue.source, "track_id": cue.track_id, "t_measured": cue.t, "position_enu": _vec(cue.position_enu),
        "sigma_enu_m": [math.sqrt(max(float(v), 0.0)) for v in np.diag(cue.covariance_enu)],
        "velocity_enu": _vec(cue.velocity_enu),
    }


def find_message(find: Find) -> dict[str, Any]:
    """A search-and-rescue find: :meth:`Find.to_dict` with its time as ``t_measured`` (``t`` is the send time)."""
    body = find.to_dict()
    body["t_measured"] = body.pop("t")
    return body


def estimate_message(est: TargetEstimate) -> dict[str, Any]:
    """The camera's estimate: a cue plus the line of sight, the range with its 1-sigma, the confidence."""
    return {**cue_message(est), "bearing_enu": _vec(est.bearing_enu), "range_m": est.range_m,
            "range_std_m": est.range_std_m, "confidence": est.confidence}


def tracks_message(tracks: Iterable[Any], ownship_ids: Iterable[int] = ()) -> dict[str, Any]:
    """Radar tracks (``chaser_bt.radar.feed.RadarTrack``-like), each flagged when it is our own drone."""
    own = set(ownship_ids)
    return {"tracks": [{
        "id": tr.track_id, "t_measured": tr.t, "position_enu": _vec(tr.position_enu),
        "velocity_enu": _vec(tr.velocity_enu), "confidence": tr.confidence, "ownship": tr.track_id in own,
    } for tr in tracks]}


def chunk_frame(jpeg: bytes, frame_id: int, t: float, max_datagram: int = MAX_DATAGRAM) -> list[bytes]:
    """Split one JPEG into video datagrams of at most ``max_datagram`` bytes.

    Raises:
        ValueError: ``max_datagram`` leaves no room for data, or the image needs more than 65 535 chunks.
    """
    room = max_datagram - VIDEO_HEADER.size
    if room <= 0:
        raise ValueError(f"max_datagram {max_datagram} leaves no room after the {VIDEO_HEADER.size}-byte header")
    count = max(1, -(-len(jpeg) // room))
    if count > 0xFFFF:
        raise ValueError(f"a {len(jpeg)}-byte frame needs {count} chunks (at most 65535)")
    fid = frame_id & 0xFFFFFFFF
    return [VIDEO_HEADER.pack(VIDEO_MAGIC, VERSION, 0, fid, k, count, float(t)) + jpeg[k * room:(k + 1) * room]
            for k in range(count)]


def parse_chunk(data: bytes) -> VideoChunk:
    """Decode one video datagram.

    Raises:
        ValueError: too short, wrong magic or version, or an index outside the count.
    """
    if len(data) < VIDEO_HEADER.size:
        raise ValueError(f"video chunk of {len(data)} bytes is shorter than its header")
    magic, version, _flags, fid, index, count, t = VIDEO_HEADER.unpack_from(data)
    if magic != VIDEO_MAGIC or version != VERSION:
        raise ValueError(f"not a version {VERSION} video chunk")
    if not index < count:
        raise ValueError(f"video chunk {index} of {count}")
    if not math.isfinite(t):
        raise ValueError(f"video chunk time {t}")
    return VideoChunk(fid, index, count, t, bytes(data[VIDEO_HEADER.size:]))


class FrameAssembler:
    """Reassembles video chunks into JPEG frames; keeps at most ``keep`` incomplete frames and at most
    ``max_frame_bytes`` of any one. A frame whose chunks disagree on their count, or that grows past
    the limit, is dropped (``dropped`` counts every frame given up)."""

    def __init__(self, keep: int = 4, max_frame_bytes: int = 16 << 20) -> None:
        self.keep = keep
        self.max_frame_bytes = max_frame_bytes
        self._parts: dict[int, tuple[int, dict[int, bytes]]] = {}  # frame id -> (chunk count, chunks)
        self.dropped = 0  # incomplete or inconsistent frames given up

    def add(self, chunk: VideoChunk) -> tuple[int, float, bytes] | None:
        """Take a chunk; (frame id, t, JPEG bytes) when it completes its frame."""
        count, parts = self._parts.setdefault(chunk.frame_id, (chunk.count, {}))
        if chunk.count != count:
            self._drop(chunk.frame_id)
            return None
        parts[chunk.index] = chunk.payload
        if len(parts) == count:
            del self._parts[chunk.frame_id]
            return chunk.frame_id, chunk.t, b"".join(parts[k] for k in range(count))
        if sum(len(p) for p in parts.values()) > self.max_frame_bytes:
            self._drop(chunk.frame_id)
        while len(self._parts) > self.keep:
            self._drop(min(self._parts))
        return None

    def _drop(self, frame_id: int) -> None:
        del self._parts[frame_id]
        self.dropped += 1


def draw_boxes(image: np.ndarray, boxes: Sequence[Box]) -> np.ndarray:
    """A copy of a BGR image with each box and its label drawn."""
    import cv2

    out = image.copy()
    h, w = out.shape[:2]
    thickness = max(2, round(min(h, w) / 240))
    for box in boxes:
        x0, y0, x1, y1 = (int(round(v)) for v in box.xyxy)
        cv2.rectangle(out, (x0, y0), (x1, y1), BOX_COLOUR_BGR, thickness)
        if box.label:
            cv2.putText(out, box.label, (x0, max(y0 - 4, 12)), cv2.FONT_HERSHEY_SIMPLEX, 0.5, BOX_COLOUR_BGR, 1,
                        cv2.LINE_AA)
    return out


def encode_jpeg(image: np.ndarray, quality: int) -> bytes:
    """JPEG bytes of a BGR image at ``quality`` (1-100).

    Raises:
        ValueError: quality outside 1..100 or an image OpenCV cannot encode.
    """
    import cv2

    if not 1 <= quality <= 100:
        raise ValueError(f"jpeg_quality {quality}: expected 1..100")
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError(f"cannot JPEG-encode an image of shape {image.shape}")
    return buf.tobytes()
