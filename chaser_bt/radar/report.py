"""The radar's datagram: one JSON object per UDP datagram, one datagram per scan (docs/radar.md).

Version 1 of the schema::

    {"schema": "chaser-bt/radar-scan", "version": 1, "radar_id": "echoguard-1", "seq": 412,
     "t": 123.25,
     "tracks": [{"id": 7, "range_m": 212.4, "az_rad": -0.113, "el_rad": 0.094,
                 "vel_mps": [1.2, -4.0, 0.1], "confidence": 0.93}, ...]}

Positions are in the radar's own frame (:mod:`chaser_bt.radar.geometry`); ``vel_mps`` is the
track's velocity in that frame (optional), ``confidence`` the radar's belief that the track is
a real object, in [0, 1]. ``seq`` increases by one per scan; ``t`` is the radar's clock, seconds.
:func:`decode_scan` checks everything and raises :class:`ScanFormatError` with a reason
category, which the stream reader counts.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "SCHEMA",
    "SCHEMA_VERSION",
    "MAX_DATAGRAM_BYTES",
    "MAX_TRACKS",
    "TrackReport",
    "RadarScan",
    "ScanFormatError",
    "encode_scan",
    "decode_scan",
    "scan_to_dict",
    "scan_from_dict",
]

SCHEMA = "chaser-bt/radar-scan"
SCHEMA_VERSION = 1
#: Larger datagrams are refused unread (a scan of MAX_TRACKS tracks encodes to about 20 kB).
MAX_DATAGRAM_BYTES = 32768
MAX_TRACKS = 200


class ScanFormatError(ValueError):
    """A datagram that is not a valid scan; ``reason`` is one of malformed, oversized, wrong_version."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class TrackReport:
    """One track in one scan, in the radar's frame.

    Args:
        track_id: the radar's id for the track (not stable across drops and swaps).
        range_m, az_rad, el_rad: measured position (azimuth positive right, elevation up).
        velocity: (3,) m/s in the radar frame, or None when the radar gives none.
        confidence: the radar's belief that the track is a real object, 0..1.
    """

    track_id: int
    range_m: float
    az_rad: float
    el_rad: float
    velocity: np.ndarray | None = None
    confidence: float = 1.0


@dataclass(frozen=True)
class RadarScan:
    """Every track the radar reports at one scan time ``t`` (radar clock, s)."""

    t: float
    seq: int
    tracks: tuple[TrackReport, ...]
    radar_id: str = "radar"


def scan_to_dict(scan: RadarScan) -> dict[str, Any]:
    """The version-1 JSON object of ``scan``."""
    tracks = []
    for r in scan.tracks:
        d: dict[str, Any] = {"id": int(r.track_id), "range_m": round(float(r.range_m), 4),
                             "az_rad": round(float(r.az_rad), 7), "el_rad": round(float(r.el_rad), 7),
                             "confidence": round(float(r.confidence), 4)}
        if r.velocity is not None:
            d["vel_mps"] = [round(float(v), 4) for v in r.velocity]
        tracks.append(d)
    return {"schema": SCHEMA, "version": SCHEMA_VERSION, "radar_id": scan.radar_id, "seq": int(scan.seq),
            "t": float(scan.t), "tracks": tracks}


def encode_scan(scan: RadarScan) -> bytes:
    """``scan`` as one UTF-8 JSON datagram."""
    return json.dumps(scan_to_dict(scan), separators=(",", ":")).encode("utf-8")


def decode_scan(data: bytes) -> RadarScan:
    """Parse and check one datagram; raises :class:`ScanFormatError`, never anything else."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ScanFormatError("malformed", f"expected bytes, got {type(data).__name__}")
    if len(data) > MAX_DATAGRAM_BYTES:
        raise ScanFormatError("oversized", f"{len(data)} bytes > {MAX_DATAGRAM_BYTES}")
    try:
        obj = json.loads(bytes(data).decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise ScanFormatError("malformed", f"not UTF-8 JSON: {e}") from None
    return scan_from_dict(obj)


def _finite(d: dict, key: str, where: str) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ScanFormatError("malformed", f"{where}{key}: expected a finite number, got {v!r}")
    return float(v)


def scan_from_dict(obj: Any) -> RadarScan:
    """Check a parsed JSON object against the schema; raises :class:`ScanFormatError`."""
    if not isinstance(obj, dict):
        raise ScanFormatError("malformed", "expected a JSON object")
    if obj.get("schema") != SCHEMA:
        raise ScanFormatError("malformed", f"schema: expected {SCHEMA!r}, got {obj.get('schema')!r}")
    version = obj.get("version")
    if version != SCHEMA_VERSION or isinstance(version, bool):
        raise ScanFormatError("wrong_version", f"version: expected {SCHEMA_VERSION}, got {version!r}")
    seq = obj.get("seq")
    if isinstance(seq, bool) or not isinstance(seq, int) or seq < 0:
        raise ScanFormatError("malformed", f"seq: expected an integer >= 0, got {seq!r}")
    t = _finite(obj, "t", "")
    radar_id = obj.get("radar_id", "radar")
    if not isinstance(radar_id, str):
        raise ScanFormatError("malformed", f"radar_id: expected a string, got {radar_id!r}")
    raw = obj.get("tracks")
    if not isinstance(raw, list):
        raise ScanFormatError("malformed", f"tracks: expected a list, got {type(raw).__name__}")
    if len(raw) > MAX_TRACKS:
        raise ScanFormatError("oversized", f"{len(raw)} tracks > {MAX_TRACKS}")
    tracks = []
    for i, d in enumerate(raw):
        where = f"tracks[{i}]."
        if not isinstance(d, dict):
            raise ScanFormatError("malformed", f"tracks[{i}]: expected an object")
        tid = d.get("id")
        if isinstance(tid, bool) or not isinstance(tid, int) or not -(2**63) <= tid < 2**63:
            raise ScanFormatError("malformed", f"{where}id: expected an integer, got {tid!r}")
        rng = _finite(d, "range_m", where)
        if rng < 0.0:
            raise ScanFormatError("malformed", f"{where}range_m: expected >= 0, got {rng}")
        az, el = _finite(d, "az_rad", where), _finite(d, "el_rad", where)
        if abs(az) > math.pi or abs(el) > math.pi / 2:
            raise ScanFormatError("malformed", f"{where}az_rad/el_rad: outside [-pi, pi] x [-pi/2, pi/2]")
        conf = _finite(d, "confidence", where) if "confidence" in d else 1.0
        if not 0.0 <= conf <= 1.0:
            raise ScanFormatError("malformed", f"{where}confidence: expected 0..1, got {conf}")
        vel = None
        if d.get("vel_mps") is not None:
            v = d["vel_mps"]
            if (not isinstance(v, list) or len(v) != 3
                    or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)):
                raise ScanFormatError("malformed", f"{where}vel_mps: expected 3 finite numbers, got {v!r}")
            vel = np.array(v, dtype=float)
        tracks.append(TrackReport(tid, rng, az, el, vel, conf))
    return RadarScan(t, seq, tuple(tracks), radar_id)
