"""A flight's trace: the per-tick time series that the paper's figures and the campaign report draw.

One :class:`FlightTrace` per flight, sampled at the mission's tick rate. A rehearsal fills it while
it flies (``target_enu`` there is the simulator's truth, used for scoring only); a recorded flight
log can be turned into the same shape (``target_enu`` then comes from the target's telemetry or the
camera estimate, named in ``target_source``). Plots and statistics take a trace, never a simulator.

Stored as one compressed ``.npz`` file: arrays as they are, the rest as JSON in ``meta``. A
rehearsal's trace may also carry a few camera frames (:class:`CameraSnapshot`, JPEG-encoded, around
the acquisition) for the animated view (:mod:`chaser_bt.log.animation`); traces saved before frames
existed load with none.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["FlightTrace", "TraceEvent", "BeliefSnapshot", "CameraSnapshot"]


@dataclass(frozen=True)
class TraceEvent:
    """Something that happened once at mission time ``t`` (``radar_validated``, ``airborne``, ``acquired`` ...)."""

    t: float
    name: str
    detail: str = ""


@dataclass(frozen=True)
class BeliefSnapshot:
    """The search belief at ``t``, summed over altitude: ``mass[i, j]`` over cells ``x_m[i]``, ``y_m[j]`` (ENU)."""

    t: float
    x_m: np.ndarray
    y_m: np.ndarray
    mass: np.ndarray


@dataclass(frozen=True)
class CameraSnapshot:
    """One kept camera frame at mission time ``t``, downsampled and JPEG-encoded (``jpeg``: uint8 bytes
    of a BGR image), with the boxes scaled to it: ``track_box`` the vision pipeline's track, ``truth_box``
    the designated target's true box (x0, y0, x1, y1 pixels of the kept image; None: none).

    ``zoom_jpeg`` is an optional full-resolution crop around the target (the truth box, else the
    track's) and ``zoom_box`` where that crop lies in the kept image's pixels (x0, y0, x1, y1; None
    without a crop): a target a few pixels across in the downsampled frame is seen in it.
    ``scale`` is the kept image's size over the camera's.
    """

    t: float
    jpeg: np.ndarray
    track_box: tuple[float, float, float, float] | None = None
    truth_box: tuple[float, float, float, float] | None = None
    zoom_jpeg: np.ndarray | None = None
    zoom_box: tuple[float, float, float, float] | None = None
    scale: float = 1.0

    def image_bgr(self) -> np.ndarray:
        """The kept frame (BGR, uint8)."""
        return _decode(self.jpeg)

    def zoom_bgr(self) -> np.ndarray | None:
        """The full-resolution crop around the target (BGR, uint8), or None."""
        return None if self.zoom_jpeg is None or not len(self.zoom_jpeg) else _decode(self.zoom_jpeg)


def _decode(jpeg: np.ndarray) -> np.ndarray:
    import cv2  # only to look at kept frames

    image = cv2.imdecode(np.asarray(jpeg, np.uint8), cv2.IMREAD_COLOR)
    if image is None:
        raise ValueError("a kept camera frame is not a readable JPEG")
    return image


def _box_row(box) -> list[float]:
    return [math.nan] * 4 if box is None else [float(v) for v in box]


def _row_box(row: np.ndarray) -> tuple[float, float, float, float] | None:
    return None if not np.isfinite(row).all() else tuple(float(v) for v in row)


@dataclass
class FlightTrace:
    """Per-tick samples of one flight (all arrays share the first axis, length ``len(trace)``).

    ``target_enu`` is NaN where the target's position is unknown; ``in_fov`` and ``detected`` are
    NaN where they were not scored (no target, or not in autonomous flight). ``phase`` is the
    mission's own label of what it is doing (e.g. the chase state), ``tip`` the running leaf.
    ``frames``: a few camera frames a rehearsal kept (:class:`CameraSnapshot`; empty for a log).
    """

    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ownship_enu: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    ownship_yaw_rad: np.ndarray = field(default_factory=lambda: np.zeros(0))  # ENU yaw, 0 = east, CCW
    target_enu: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    in_fov: np.ndarray = field(default_factory=lambda: np.zeros(0))
    detected: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mode: list[str] = field(default_factory=list)
    phase: list[str] = field(default_factory=list)
    tip: list[str] = field(default_factory=list)
    events: list[TraceEvent] = field(default_factory=list)
    beliefs: list[BeliefSnapshot] = field(default_factory=list)
    target_source: str = "truth"
    desired_range_m: float = float("nan")
    desired_elevation_rad: float = float("nan")
    meta: dict = field(default_factory=dict)  # tree, scenario, seed, ... (JSON-serialisable)
    frames: list[CameraSnapshot] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.t.shape[0])

    # --- relative geometry (paper figures 7 and 9) -------------------------------------------
    @property
    def relative_enu(self) -> np.ndarray:
        """Target minus ownship, ENU metres (NaN where the target is unknown)."""
        return self.target_enu - self.ownship_enu

    @property
    def slant_range_m(self) -> np.ndarray:
        return np.linalg.norm(self.relative_enu, axis=1)

    @property
    def elevation_rad(self) -> np.ndarray:
        """Depression of the target seen from the ownship: positive when the target is below."""
        d = self.relative_enu
        return np.arctan2(-d[:, 2], np.hypot(d[:, 0], d[:, 1]))

    @property
    def azimuth_rad(self) -> np.ndarray:
        """Target bearing relative to the ownship's heading, wrapped to [-pi, pi) (0 = dead ahead)."""
        d = self.relative_enu
        rel = np.arctan2(d[:, 1], d[:, 0]) - self.ownship_yaw_rad
        return (rel + math.pi) % (2 * math.pi) - math.pi

    def first_event(self, name: str) -> TraceEvent | None:
        return next((e for e in self.events if e.name == name), None)

    # --- storage --------------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the trace to ``path`` (``.npz``), its kept camera frames included (``frames_*`` arrays)."""
        path = Path(path)
        meta = {
            "mode": self.mode, "phase": self.phase, "tip": self.tip,
            "events": [[e.t, e.name, e.detail] for e in self.events],
            "target_source": self.target_source,
            "desired_range_m": self.desired_range_m, "desired_elevation_rad": self.desired_elevation_rad,
            "meta": self.meta, "belief_t": [b.t for b in self.beliefs],
        }
        arrays = {name: getattr(self, name) for name in ("t", "ownship_enu", "ownship_yaw_rad", "target_enu", "in_fov", "detected")}
        for i, b in enumerate(self.beliefs):
            arrays[f"belief{i}_x"], arrays[f"belief{i}_y"], arrays[f"belief{i}_mass"] = b.x_m, b.y_m, b.mass
        if self.frames:
            arrays.update(_frame_arrays(self.frames))
        with path.open("wb") as fh:
            np.savez_compressed(fh, meta=np.array(json.dumps(meta)), **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> FlightTrace:
        """Read a trace written by :meth:`save` (one written before camera frames were kept has none)."""
        with np.load(Path(path), allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            beliefs = [BeliefSnapshot(t, z[f"belief{i}_x"], z[f"belief{i}_y"], z[f"belief{i}_mass"])
                       for i, t in enumerate(meta["belief_t"])]
            frames = _frames_from(z) if "frames_t" in z.files else []
            return cls(
                t=z["t"], ownship_enu=z["ownship_enu"], ownship_yaw_rad=z["ownship_yaw_rad"], target_enu=z["target_enu"],
                in_fov=z["in_fov"], detected=z["detected"], mode=meta["mode"], phase=meta["phase"], tip=meta["tip"],
                events=[TraceEvent(float(t), n, d) for t, n, d in meta["events"]], beliefs=beliefs,
                target_source=meta["target_source"], desired_range_m=meta["desired_range_m"],
                desired_elevation_rad=meta["desired_elevation_rad"], meta=meta["meta"], frames=frames,
            )


def _frame_arrays(frames: list[CameraSnapshot]) -> dict[str, np.ndarray]:
    """Kept frames as flat arrays: the JPEGs (and zoom crops) end to end with their offsets, the boxes NaN where None."""
    def packed(parts: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        offsets = np.cumsum([0] + [len(p) for p in parts]).astype(np.int64)
        data = np.concatenate(parts).astype(np.uint8) if parts else np.zeros(0, np.uint8)
        return data, offsets

    jpeg, jpeg_at = packed([np.asarray(f.jpeg, np.uint8) for f in frames])
    zoom, zoom_at = packed([np.zeros(0, np.uint8) if f.zoom_jpeg is None else np.asarray(f.zoom_jpeg, np.uint8) for f in frames])
    boxes = np.array([_box_row(f.track_box) + _box_row(f.truth_box) + _box_row(f.zoom_box) for f in frames], float)
    return {"frames_t": np.array([f.t for f in frames], float), "frames_jpeg": jpeg, "frames_jpeg_at": jpeg_at,
            "frames_zoom": zoom, "frames_zoom_at": zoom_at, "frames_boxes": boxes.reshape(-1, 12),
            "frames_scale": np.array([f.scale for f in frames], float)}


def _frames_from(z) -> list[CameraSnapshot]:
    t, jpeg, jpeg_at, zoom, zoom_at = (z[k] for k in ("frames_t", "frames_jpeg", "frames_jpeg_at", "frames_zoom", "frames_zoom_at"))
    boxes, scale = z["frames_boxes"], z["frames_scale"]
    frames = []
    for i in range(len(t)):
        crop = zoom[zoom_at[i]:zoom_at[i + 1]]
        frames.append(CameraSnapshot(
            float(t[i]), jpeg[jpeg_at[i]:jpeg_at[i + 1]].copy(), _row_box(boxes[i, 0:4]), _row_box(boxes[i, 4:8]),
            crop.copy() if len(crop) else None, _row_box(boxes[i, 8:12]), float(scale[i])))
    return frames
