"""Recorded calibration flights: a JSON-lines file of radar scans and the drone's GPS (docs/radar.md).

Format ``chaser-bt/radar-calibration`` version 1, one JSON object per line::

    {"type": "header", "format": "chaser-bt/radar-calibration", "version": 1,
     "radar_guess": {"lat_deg": .., "lon_deg": .., "alt_m": .., "yaw_deg": .., "pitch_deg": .., "roll_deg": ..}}
    {"type": "scan", "scan": {<a radar datagram, docs/radar.md>}}
    {"type": "gps", "t": 12.4, "lat_deg": .., "lon_deg": .., "alt_m": ..}

Times of scans and GPS fixes are on one clock. The guess is the handheld-GPS position and compass
attitude the paper starts from; the calibration frame is ENU at the guessed position.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pymap3d

from chaser_bt.geo import GeoPoint, LocalFrame
from chaser_bt.radar.calibration import (CalibrationResult, TrackBins, bin_tracks, fit_best_track,
                                         fit_longest_track, fit_six_dof)
from chaser_bt.radar.geometry import rae_to_xyz
from chaser_bt.radar.report import RadarScan, ScanFormatError, scan_from_dict, scan_to_dict

__all__ = ["FORMAT", "VERSION", "CalibrationRecording", "RecordingError", "load_recording", "write_recording",
           "recording_tracks", "calibrate_recording", "METHODS"]

FORMAT = "chaser-bt/radar-calibration"
VERSION = 1
METHODS = ("longest", "best", "six")


class RecordingError(ValueError):
    """A calibration file that cannot be used; the message names file, line and field."""


@dataclass(frozen=True)
class CalibrationRecording:
    """A calibration flight: the pose guess, the radar's scans, the drone's GPS."""

    guess_position: GeoPoint
    guess_ypr_rad: tuple[float, float, float]
    scans: tuple[RadarScan, ...]
    gps_t: np.ndarray
    gps_lla: np.ndarray  # (n, 3) lat_deg, lon_deg, alt_m


def write_recording(path: str | Path, rec: CalibrationRecording) -> None:
    """Write ``rec`` in the JSON-lines format."""
    y, p, r = (math.degrees(a) for a in rec.guess_ypr_rad)
    g = rec.guess_position
    lines = [{"type": "header", "format": FORMAT, "version": VERSION,
              "radar_guess": {"lat_deg": g.lat_deg, "lon_deg": g.lon_deg, "alt_m": g.alt_m,
                              "yaw_deg": y, "pitch_deg": p, "roll_deg": r}}]
    events = [(s.t, 0, {"type": "scan", "scan": scan_to_dict(s)}) for s in rec.scans]
    events += [(float(t), 1, {"type": "gps", "t": float(t), "lat_deg": float(a), "lon_deg": float(b), "alt_m": float(c)})
               for t, (a, b, c) in zip(rec.gps_t, rec.gps_lla)]
    lines += [e for _, _, e in sorted(events, key=lambda x: (x[0], x[1]))]
    Path(path).write_text("".join(json.dumps(x, separators=(",", ":")) + "\n" for x in lines), encoding="utf-8")


def _num(d: dict, key: str, where: str) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise RecordingError(f"{where}: {key}: expected a finite number, got {v!r}")
    return float(v)


def load_recording(path: str | Path) -> CalibrationRecording:
    """Read and check a calibration file; every problem names the file, line and field."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise RecordingError(f"{p}: cannot read: {e}") from e
    header = None
    scans: list[RadarScan] = []
    gps: list[tuple[float, float, float, float]] = []
    for n, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        where = f"{p}:{n}"
        try:
            obj = json.loads(line)
        except ValueError as e:
            raise RecordingError(f"{where}: not JSON: {e}") from None
        kind = obj.get("type") if isinstance(obj, dict) else None
        if header is None:
            if kind != "header" or obj.get("format") != FORMAT:
                raise RecordingError(f"{where}: expected the header line {{\"type\": \"header\", \"format\": \"{FORMAT}\"}}")
            if obj.get("version") != VERSION:
                raise RecordingError(f"{where}: version: expected {VERSION}, got {obj.get('version')!r}")
            guess = obj.get("radar_guess")
            if not isinstance(guess, dict):
                raise RecordingError(f"{where}: radar_guess: expected an object")
            w = f"{where}: radar_guess"
            try:
                pos = GeoPoint(_num(guess, "lat_deg", w), _num(guess, "lon_deg", w), _num(guess, "alt_m", w))
            except ValueError as e:
                raise RecordingError(f"{w}: {e}") from None
            header = (pos, tuple(math.radians(_num(guess, k, w)) for k in ("yaw_deg", "pitch_deg", "roll_deg")))
        elif kind == "scan":
            try:
                scans.append(scan_from_dict(obj.get("scan")))
            except ScanFormatError as e:
                raise RecordingError(f"{where}: scan: {e}") from None
        elif kind == "gps":
            gps.append((_num(obj, "t", where), _num(obj, "lat_deg", where), _num(obj, "lon_deg", where),
                        _num(obj, "alt_m", where)))
        else:
            raise RecordingError(f"{where}: type: expected 'scan' or 'gps', got {kind!r}")
    if header is None:
        raise RecordingError(f"{p}: empty file (expected a header line)")
    if len(gps) < 2:
        raise RecordingError(f"{p}: expected GPS fixes (lines of type 'gps'), found {len(gps)}")
    g = np.array(sorted(gps))
    return CalibrationRecording(header[0], header[1], tuple(sorted(scans, key=lambda s: s.t)), g[:, 0], g[:, 1:])


def recording_tracks(rec: CalibrationRecording, bin_s: float = 0.5) -> tuple[LocalFrame, list[TrackBins]]:
    """The calibration frame (ENU at the guessed radar position) and every track's bins."""
    frame = LocalFrame(rec.guess_position)
    o = rec.guess_position
    e, n, u = pymap3d.geodetic2enu(rec.gps_lla[:, 0], rec.gps_lla[:, 1], rec.gps_lla[:, 2], o.lat_deg, o.lon_deg, o.alt_m)
    gps_enu = np.stack([e, n, u], axis=1)
    rows = [(s.t, r.track_id, r.range_m, r.az_rad, r.el_rad) for s in rec.scans for r in s.tracks]
    if not rows:
        return frame, []
    a = np.array(rows, float)
    xyz = rae_to_xyz(a[:, 2], a[:, 3], a[:, 4])
    return frame, bin_tracks(a[:, 0], a[:, 1].astype(np.int64), xyz, rec.gps_t, gps_enu, bin_s)


def calibrate_recording(rec: CalibrationRecording, method: str = "six") -> tuple[CalibrationResult, GeoPoint]:
    """Fit ``rec`` with ``method`` (longest | best | six); the result (calibration frame) and the radar's position."""
    frame, tracks = recording_tracks(rec)
    if method == "longest":
        res = fit_longest_track(tracks, np.zeros(3), rec.guess_ypr_rad)
    elif method == "best":
        res = fit_best_track(tracks, np.zeros(3), rec.guess_ypr_rad)
    elif method == "six":
        res = fit_six_dof(tracks)
    else:
        raise ValueError(f"unknown calibration method {method!r}; choose one of {', '.join(METHODS)}")
    return res, frame.to_geodetic(res.pose.position_enu)
