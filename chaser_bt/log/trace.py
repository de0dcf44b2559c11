"""A flight's trace: the per-tick time series that the paper's figures and the campaign report draw.

One :class:`FlightTrace` per flight, sampled at the mission's tick rate. A rehearsal fills it while
it flies (``target_enu`` there is the simulator's truth, used for scoring only); a recorded flight
log can be turned into the same shape (``target_enu`` then comes from the target's telemetry or the
camera estimate, named in ``target_source``). Plots and statistics take a trace, never a simulator.

Stored as one compressed ``.npz`` file: arrays as they are, the rest as JSON in ``meta``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["FlightTrace", "TraceEvent", "BeliefSnapshot"]


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


@dataclass
class FlightTrace:
    """Per-tick samples of one flight (all arrays share the first axis, length ``len(trace)``).

    ``target_enu`` is NaN where the target's position is unknown; ``in_fov`` and ``detected`` are
    NaN where they were not scored (no target, or not in autonomous flight). ``phase`` is the
    mission's own label of what it is doing (e.g. the chase state), ``tip`` the running leaf.
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
        """Write the trace to ``path`` (``.npz``)."""
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
        with path.open("wb") as fh:
            np.savez_compressed(fh, meta=np.array(json.dumps(meta)), **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> FlightTrace:
        """Read a trace written by :meth:`save`."""
        with np.load(Path(path), allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            beliefs = [BeliefSnapshot(t, z[f"belief{i}_x"], z[f"belief{i}_y"], z[f"belief{i}_mass"])
                       for i, t in enumerate(meta["belief_t"])]
            return cls(
                t=z["t"], ownship_enu=z["ownship_enu"], ownship_yaw_rad=z["ownship_yaw_rad"], target_enu=z["target_enu"],
                in_fov=z["in_fov"], detected=z["detected"], mode=meta["mode"], phase=meta["phase"], tip=meta["tip"],
                events=[TraceEvent(float(t), n, d) for t, n, d in meta["events"]], beliefs=beliefs,
                target_source=meta["target_source"], desired_range_m=meta["desired_range_m"],
                desired_elevation_rad=meta["desired_elevation_rad"], meta=meta["meta"],
            )
