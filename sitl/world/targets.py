"""Scripted target paths: what a radar (or a camera) sees fly when no MAVLink vehicle flies it.

A :class:`TargetPath` is anything with ``position_enu(t)`` and ``velocity_enu(t)`` (ENU metres and
m/s in the scenario's frame, ``t`` simulator seconds). Three shapes cover the paper's flights:
circles (:class:`CirclePath`), polylines flown at constant speed (:class:`WaypointPath`, with
:func:`circle_points` and :func:`downrange_and_back_points` to build them) and a schedule that
switches between paths at given times (:class:`ScheduledPath`). Full intruders that fly physics
and send their own MAVLink implement the same protocol. :class:`StaticPoint` is a target that does
not move (a person waiting for rescue), placed at random around its nominal point per seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["TargetPath", "CirclePath", "WaypointPath", "ScheduledPath", "StaticPoint", "circle_points",
           "downrange_and_back_points"]


@runtime_checkable
class TargetPath(Protocol):
    """Where a target is and how fast it moves at time ``t``."""

    def position_enu(self, t: float) -> np.ndarray: ...

    def velocity_enu(self, t: float) -> np.ndarray: ...


@dataclass(frozen=True)
class CirclePath:
    """A horizontal circle flown at constant speed, counter-clockwise unless ``clockwise``.

    ``phase_rad`` is the ENU angle of the start point from the centre at ``t0_s``.
    """

    center_enu: tuple[float, float, float]
    radius_m: float
    speed_mps: float
    clockwise: bool = False
    phase_rad: float = 0.0
    t0_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.radius_m > 0 or self.speed_mps < 0:
            raise ValueError("circle radius must be > 0 and speed >= 0")

    def _angle(self, t: float) -> float:
        sign = -1.0 if self.clockwise else 1.0
        return self.phase_rad + sign * self.speed_mps / self.radius_m * (t - self.t0_s)

    def position_enu(self, t: float) -> np.ndarray:
        a = self._angle(t)
        c = self.center_enu
        return np.array([c[0] + self.radius_m * math.cos(a), c[1] + self.radius_m * math.sin(a), c[2]])

    def velocity_enu(self, t: float) -> np.ndarray:
        a = self._angle(t)
        sign = -1.0 if self.clockwise else 1.0
        return sign * self.speed_mps * np.array([-math.sin(a), math.cos(a), 0.0])


@dataclass(frozen=True)
class WaypointPath:
    """A polyline flown at constant speed from ``t0_s``; holds its ends unless ``loop``."""

    points_enu: tuple[tuple[float, float, float], ...]
    speed_mps: float
    loop: bool = False
    t0_s: float = 0.0
    _cum: np.ndarray = field(init=False, repr=False, compare=False)
    _pts: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        pts = np.asarray(self.points_enu, float)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2 or not np.all(np.isfinite(pts)):
            raise ValueError("a waypoint path needs at least two finite ENU points")
        if not self.speed_mps > 0:
            raise ValueError("waypoint speed must be > 0")
        if self.loop:
            pts = np.vstack([pts, pts[:1]])
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        object.__setattr__(self, "_pts", pts)
        object.__setattr__(self, "_cum", np.concatenate([[0.0], np.cumsum(seg)]))

    @property
    def length_m(self) -> float:
        return float(self._cum[-1])

    def _locate(self, t: float) -> tuple[int, float, bool]:
        s = self.speed_mps * (t - self.t0_s)
        total = self._cum[-1]
        moving = True
        if self.loop and total > 0:
            s %= total
        elif s <= 0.0 or s >= total:
            s, moving = min(max(s, 0.0), total), False
        i = int(np.clip(np.searchsorted(self._cum, s, side="right") - 1, 0, len(self._cum) - 2))
        seg = self._cum[i + 1] - self._cum[i]
        return i, (s - self._cum[i]) / seg if seg > 0 else 0.0, moving

    def position_enu(self, t: float) -> np.ndarray:
        i, f, _ = self._locate(t)
        return self._pts[i] + f * (self._pts[i + 1] - self._pts[i])

    def velocity_enu(self, t: float) -> np.ndarray:
        i, _, moving = self._locate(t)
        d = self._pts[i + 1] - self._pts[i]
        n = np.linalg.norm(d)
        return d / n * self.speed_mps if moving and n > 0 else np.zeros(3)


@dataclass(frozen=True)
class ScheduledPath:
    """Fly ``segments[k][1]`` from time ``segments[k][0]`` until the next segment starts."""

    segments: tuple[tuple[float, TargetPath], ...]

    def __post_init__(self) -> None:
        starts = [s for s, _ in self.segments]
        if not starts or starts != sorted(starts):
            raise ValueError("a schedule needs at least one segment, in order of start time")

    def _path(self, t: float) -> TargetPath:
        current = self.segments[0][1]
        for start, path in self.segments:
            if t >= start:
                current = path
        return current

    def position_enu(self, t: float) -> np.ndarray:
        return self._path(t).position_enu(t)

    def velocity_enu(self, t: float) -> np.ndarray:
        return self._path(t).velocity_enu(t)


#: How far a lying person's body origin is above the ground: the torso's half-depth (m).
LYING_LIFT_M = 0.16


@dataclass(frozen=True)
class StaticPoint:
    """A target that stays at ``position_enu`` (a person on the ground: feet at the point).

    ``scatter_m`` > 0 marks the point as nominal: :meth:`placed` draws the actual point uniformly
    in the horizontal disc of that radius around it (a seeded campaign puts the person somewhere
    else each run). ``heading_rad`` is the ENU direction the body's x axis faces; ``lying`` rolls
    the body 90 deg onto the ground (the camera models stand up body +z), its origin raised by the
    torso's half-depth (:data:`LYING_LIFT_M`, as the person datasets draw it) so it lies on the ground.
    """

    position: tuple[float, float, float]
    scatter_m: float = 0.0
    heading_rad: float = 0.0
    lying: bool = False

    def __post_init__(self) -> None:
        if len(self.position) != 3 or not all(math.isfinite(x) for x in self.position):
            raise ValueError(f"a static point needs 3 finite ENU coordinates, got {self.position!r}")
        if not (math.isfinite(self.scatter_m) and self.scatter_m >= 0.0):
            raise ValueError(f"scatter_m must be >= 0, got {self.scatter_m}")

    def placed(self, rng: np.random.Generator) -> StaticPoint:
        """The point drawn for one run: uniform in the scatter disc, any heading; itself without scatter."""
        if self.scatter_m == 0.0:
            return self
        r = self.scatter_m * math.sqrt(rng.uniform())  # sqrt: uniform over the disc's area
        a = rng.uniform(0.0, 2.0 * math.pi)
        e, n, u = self.position
        return StaticPoint((e + r * math.cos(a), n + r * math.sin(a), u), 0.0, rng.uniform(-math.pi, math.pi), self.lying)

    def position_enu(self, t: float) -> np.ndarray:
        return np.array(self.position, dtype=float) + (LYING_LIFT_M if self.lying else 0.0) * np.array([0.0, 0.0, 1.0])

    def velocity_enu(self, t: float) -> np.ndarray:
        return np.zeros(3)

    def attitude(self, t: float) -> Rotation:
        """Body (FLU) -> ENU: the heading, then rolled 90 deg onto the ground when ``lying``."""
        return Rotation.from_euler("ZX", [self.heading_rad, math.pi / 2 if self.lying else 0.0])


def circle_points(center_enu, radius_m: float, n: int = 36, phase_rad: float = 0.0,
                  clockwise: bool = False, laps: int = 1) -> list[tuple[float, float, float]]:
    """Points of ``laps`` circles (an n-gon each), starting and ending at ``phase_rad``."""
    sign = -1.0 if clockwise else 1.0
    a = phase_rad + sign * np.linspace(0.0, 2.0 * math.pi * laps, n * laps + 1)
    c = np.asarray(center_enu, float)
    return [(c[0] + radius_m * math.cos(x), c[1] + radius_m * math.sin(x), c[2]) for x in a]


def downrange_and_back_points(start_enu, direction_rad: float, distance_m: float = 100.0,
                              turn_radius_m: float = 5.0, n_turn: int = 12) -> list[tuple[float, float, float]]:
    """Out ``distance_m`` along ENU angle ``direction_rad``, a half-circle turn, and back beside the outbound leg."""
    s = np.asarray(start_enu, float)
    u = np.array([math.cos(direction_rad), math.sin(direction_rad), 0.0])
    left = np.array([-u[1], u[0], 0.0])
    far = s + distance_m * u
    centre = far + turn_radius_m * left
    pts = [tuple(s), tuple(far)]
    for k in range(1, n_turn):
        a = -math.pi / 2 + math.pi * k / n_turn  # from the right of the turn centre round to its left
        pts.append(tuple(centre + turn_radius_m * (math.cos(a) * u + math.sin(a) * left)))
    back = s + 2 * turn_radius_m * left
    pts += [tuple(far + 2 * turn_radius_m * left), tuple(back)]
    return [tuple(float(x) for x in p) for p in pts]
