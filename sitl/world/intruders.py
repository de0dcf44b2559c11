"""Intruders: drones that fly like a DJI Phantom 4 and send their own MAVLink position.

The paper tuned its follow controller in SITL against a target flying a rectangle with a pause at
each corner (section 5, figure "Rectangular flight path PID test") and chose its chase geometry
for a Phantom 4 (section 3.2: 20 m/s horizontal, 6 m/s up, 5 m/s down). Each :class:`Intruder`
here is a point mass whose velocity follows what its *pilot* asks for, within the Phantom's
speed and acceleration limits (:class:`IntruderLimits`); pilots:

- :class:`RectanglePilot`: corner to corner, stopping and pausing at each (the paper's case);
- :class:`CirclePilot`: a horizontal circle at constant speed;
- :class:`FigureEightPilot`: a figure eight (lemniscate of Gerono) at constant speed;
- :class:`RandomWaypointsPilot`: random points in a box, random speeds and pauses;
- :class:`EvasivePilot`: an evasive pilot: cruising broken by sudden dashes at full speed, climbs
  and dives at the vertical limits, and stops, kept inside a box.

Like the paper's target, each intruder also sends its position over MAVLink under its own system
id (HEARTBEAT at 1 Hz, GLOBAL_POSITION_INT at ``telemetry_hz``), which the simulator writes to
every port beside the vehicle's own stream (:class:`IntruderTelemetry`). The heartbeat says
MAV_TYPE_QUADROTOR / MAV_AUTOPILOT_GENERIC. Random pilots draw from the generator they are given,
so the same seed flies the same path. An intruder also implements the
:class:`sitl.world.targets.TargetPath` protocol for its present state, so the radar sees it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from chaser_bt.geo import LocalFrame, NearbyGeodetic

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

__all__ = [
    "IntruderLimits", "Pilot", "RectanglePilot", "CirclePilot", "FigureEightPilot", "RandomWaypointsPilot",
    "EvasivePilot", "IntruderSpec", "Intruder", "IntruderTelemetry", "TRAJECTORY_KINDS",
]

TRAJECTORY_KINDS = ("rectangle", "circle", "figure_eight", "random_waypoints", "evasive")


@dataclass(frozen=True)
class IntruderLimits:
    """Speed and acceleration limits (m/s, m/s^2); defaults: a DJI Phantom 4 in sport mode."""

    speed_h_mps: float = 20.0
    speed_up_mps: float = 6.0
    speed_down_mps: float = 5.0
    accel_h_mps2: float = 8.0  # ~40 deg tilt
    accel_v_mps2: float = 4.0

    def __post_init__(self) -> None:
        for name, v in self.__dict__.items():
            if not v > 0.0:
                raise ValueError(f"intruder limit {name} must be > 0, got {v}")


class Pilot(Protocol):
    """Decides the velocity the intruder wants now."""

    def desired_velocity(self, t: float, pos: np.ndarray, vel: np.ndarray, limits: IntruderLimits) -> np.ndarray: ...


def _toward(pos: np.ndarray, goal: np.ndarray, speed: float, limits: IntruderLimits) -> np.ndarray:
    """Velocity to fly to ``goal`` at ``speed`` and stop there (decelerating within the limits)."""
    d = goal - pos
    dist = float(np.linalg.norm(d))
    if dist < 1e-6:
        return np.zeros(3)
    a = min(limits.accel_h_mps2, limits.accel_v_mps2)
    v = min(speed, math.sqrt(2.0 * 0.5 * a * dist), 1.5 * dist)  # stop with margin, no overshoot near
    return d / dist * v


@dataclass
class RectanglePilot:
    """Fly the corners in order at ``speed_mps`` (looping), halting ``pause_s`` at each corner."""

    corners: tuple[tuple[float, float, float], ...]
    speed_mps: float = 8.0
    pause_s: float = 5.0
    arrive_m: float = 0.5
    _i: int = 0
    _pause_until: float | None = None

    def desired_velocity(self, t, pos, vel, limits):
        if self._pause_until is not None:
            if t < self._pause_until:
                return np.zeros(3)
            self._pause_until = None
            self._i = (self._i + 1) % len(self.corners)
        goal = np.asarray(self.corners[self._i], float)
        if np.linalg.norm(goal - pos) < self.arrive_m and np.linalg.norm(vel) < 0.5:
            self._pause_until = t + self.pause_s
            return np.zeros(3)
        return _toward(pos, goal, self.speed_mps, limits)


def _track(pos: np.ndarray, ref_pos: np.ndarray, ref_vel: np.ndarray, gain: float = 1.0) -> np.ndarray:
    """Follow a moving reference point: its velocity plus a pull towards it."""
    return ref_vel + gain * (ref_pos - pos)


@dataclass
class CirclePilot:
    """A horizontal circle at constant speed (counter-clockwise unless ``clockwise``), from ``t0``."""

    center: tuple[float, float, float]
    radius_m: float = 40.0
    speed_mps: float = 8.0
    clockwise: bool = False
    phase_rad: float = 0.0
    t0: float = 0.0

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        s = -1.0 if self.clockwise else 1.0
        w = s * self.speed_mps / self.radius_m
        a = self.phase_rad + w * max(t - self.t0, 0.0)
        c = np.asarray(self.center, float)
        p = c + self.radius_m * np.array([math.cos(a), math.sin(a), 0.0])
        v = self.radius_m * w * np.array([-math.sin(a), math.cos(a), 0.0]) if t >= self.t0 else np.zeros(3)
        return p, v

    def desired_velocity(self, t, pos, vel, limits):
        return _track(pos, *self.reference(t))


@dataclass
class FigureEightPilot:
    """A figure eight ``x = a sin s, y = a sin s cos s`` (``a`` = half its length), rotated by
    ``heading_rad`` (ENU angle of its long axis), flown at about ``speed_mps``, from ``t0``."""

    center: tuple[float, float, float]
    half_length_m: float = 60.0
    speed_mps: float = 8.0
    heading_rad: float = 0.0
    t0: float = 0.0
    _s: float = 0.0
    _t_last: float | None = None

    def _point(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        a = self.half_length_m
        x, y = a * math.sin(s), a * math.sin(s) * math.cos(s)
        dx, dy = a * math.cos(s), a * math.cos(2.0 * s)
        ch, sh = math.cos(self.heading_rad), math.sin(self.heading_rad)
        p = np.asarray(self.center, float) + np.array([ch * x - sh * y, sh * x + ch * y, 0.0])
        return p, np.array([ch * dx - sh * dy, sh * dx + ch * dy, 0.0])

    def desired_velocity(self, t, pos, vel, limits):
        if self._t_last is not None and t > self.t0:
            _, d = self._point(self._s)
            self._s += self.speed_mps / max(float(np.linalg.norm(d)), 1e-3) * (t - self._t_last)
        self._t_last = t
        p, d = self._point(self._s)
        v = d / max(float(np.linalg.norm(d)), 1e-3) * self.speed_mps if t > self.t0 else np.zeros(3)
        return _track(pos, p, v)


@dataclass
class RandomWaypointsPilot:
    """Random points in a box around ``center``, each at a random speed, with random pauses."""

    rng: np.random.Generator
    center: tuple[float, float, float]
    half_extent_m: float = 80.0
    alt_min_m: float = 15.0
    alt_max_m: float = 45.0
    speed_min_mps: float = 3.0
    speed_max_mps: float = 15.0
    pause_max_s: float = 4.0
    _goal: np.ndarray | None = None
    _speed: float = 0.0
    _pause_until: float | None = None

    def _next(self) -> None:
        c = np.asarray(self.center, float)
        e, n = c[:2] + self.rng.uniform(-self.half_extent_m, self.half_extent_m, 2)
        self._goal = np.array([e, n, self.rng.uniform(self.alt_min_m, self.alt_max_m)])
        self._speed = float(self.rng.uniform(self.speed_min_mps, self.speed_max_mps))

    def desired_velocity(self, t, pos, vel, limits):
        if self._pause_until is not None:
            if t < self._pause_until:
                return np.zeros(3)
            self._pause_until = None
            self._goal = None
        if self._goal is None:
            self._next()
        if np.linalg.norm(self._goal - pos) < 1.0:
            self._pause_until = t + float(self.rng.uniform(0.0, self.pause_max_s))
            return np.zeros(3)
        return _toward(pos, self._goal, self._speed, limits)


@dataclass
class EvasivePilot:
    """An evasive pilot: manoeuvres of random kind and length, inside a box.

    Kinds: ``cruise`` (5-10 m/s in a random direction, 3-8 s), ``dash`` (full horizontal speed,
    1.5-4 s), ``climb`` / ``dive`` (full vertical speed, 1.5-3 s, with the cruise velocity kept),
    ``stop`` (hover 1-3 s). Outside the box, or about to leave its altitude band, the direction
    turns back towards the centre.
    """

    rng: np.random.Generator
    center: tuple[float, float, float]
    half_extent_m: float = 120.0
    alt_min_m: float = 15.0
    alt_max_m: float = 60.0
    cruise_speed_mps: float = 8.0
    _until: float = -math.inf
    _v: np.ndarray = field(default_factory=lambda: np.zeros(3))
    kind: str = "stop"

    def _choose(self, t: float, pos: np.ndarray, vel: np.ndarray, limits: IntruderLimits) -> None:
        r = self.rng
        kind = r.choice(["cruise", "cruise", "dash", "climb", "dive", "stop"])
        c = np.asarray(self.center, float)
        heading = r.uniform(-math.pi, math.pi)
        off = pos[:2] - c[:2]
        if np.max(np.abs(off)) > 0.7 * self.half_extent_m:  # head back into the box
            back = math.atan2(-off[1], -off[0])
            heading = back + r.uniform(-0.6, 0.6)
        u = np.array([math.cos(heading), math.sin(heading), 0.0])
        cruise = self.cruise_speed_mps * r.uniform(0.6, 1.25)
        if kind == "cruise":
            self._v, dur = cruise * u, r.uniform(3.0, 8.0)
        elif kind == "dash":
            self._v, dur = limits.speed_h_mps * u, r.uniform(1.5, 4.0)
        elif kind in ("climb", "dive"):
            room_up, room_down = self.alt_max_m - pos[2], pos[2] - self.alt_min_m
            up = kind == "climb" if min(room_up, room_down) > 15.0 else room_up > room_down
            vz = limits.speed_up_mps if up else -limits.speed_down_mps
            dur = r.uniform(1.5, 3.0)
            dur = min(dur, max(room_up if up else room_down, 1.0) / abs(vz))
            self._v = np.array([vel[0], vel[1], vz])
            kind = "climb" if up else "dive"
        else:
            self._v, dur = np.zeros(3), r.uniform(1.0, 3.0)
        self.kind = str(kind)
        self._until = t + float(dur)

    def desired_velocity(self, t, pos, vel, limits):
        if t >= self._until:
            self._choose(t, pos, vel, limits)
        v = self._v.copy()
        if (pos[2] > self.alt_max_m and v[2] > 0) or (pos[2] < self.alt_min_m and v[2] < 0):
            v[2] = 0.0
        return v


@dataclass(frozen=True)
class IntruderSpec:
    """An intruder as the scenario describes it (see ``sitl/scenarios/README.md``).

    ``trajectory`` is one of :data:`TRAJECTORY_KINDS` and ``params`` its keys (SI units, radians);
    the intruder hovers at ``start_enu`` until ``start_s``.
    """

    name: str
    sysid: int
    start_enu: tuple[float, float, float]
    trajectory: str
    params: dict = field(default_factory=dict)
    start_s: float = 0.0
    telemetry_hz: float = 5.0
    limits: IntruderLimits = IntruderLimits()
    airframe: str = "phantom"  # what the camera renders (sitl/world/camera/models.py): phantom or s1000

    def make_pilot(self, rng: np.random.Generator) -> Pilot:
        p = dict(self.params)
        center = tuple(p.pop("center", self.start_enu))
        if self.trajectory == "rectangle":
            return RectanglePilot(tuple(tuple(c) for c in p.pop("corners")), **p)
        if self.trajectory == "circle":
            return CirclePilot(center, t0=self.start_s, **p)
        if self.trajectory == "figure_eight":
            return FigureEightPilot(center, t0=self.start_s, **p)
        if self.trajectory == "random_waypoints":
            return RandomWaypointsPilot(rng, center, **p)
        if self.trajectory == "evasive":
            return EvasivePilot(rng, center, **p)
        raise ValueError(f"intruder {self.name}: unknown trajectory {self.trajectory!r}")


class Intruder:
    """One flying intruder: its state, its pilot, its telemetry transmitter."""

    def __init__(self, spec: IntruderSpec, rng: np.random.Generator, frame: LocalFrame) -> None:
        self.spec = spec
        self.pilot = spec.make_pilot(rng)
        self.pos = np.asarray(spec.start_enu, float).copy()
        self.vel = np.zeros(3)
        self.telemetry = IntruderTelemetry(spec.sysid, spec.telemetry_hz, frame)

    @property
    def name(self) -> str:
        return self.spec.name

    def step(self, t: float, dt: float) -> None:
        """Advance to time ``t`` (the end of a step of ``dt``)."""
        lim = self.spec.limits
        want = np.zeros(3) if t < self.spec.start_s else np.asarray(
            self.pilot.desired_velocity(t, self.pos, self.vel, lim), float)
        h = math.hypot(want[0], want[1])
        if h > lim.speed_h_mps:
            want[:2] *= lim.speed_h_mps / h
        want[2] = min(max(want[2], -lim.speed_down_mps), lim.speed_up_mps)
        dv = want - self.vel
        dh = math.hypot(dv[0], dv[1])
        if dh > lim.accel_h_mps2 * dt:
            dv[:2] *= lim.accel_h_mps2 * dt / dh
        dv[2] = min(max(dv[2], -lim.accel_v_mps2 * dt), lim.accel_v_mps2 * dt)
        v0 = self.vel
        self.vel = v0 + dv
        self.pos = self.pos + 0.5 * (v0 + self.vel) * dt

    # TargetPath protocol, for the radar: the present state (the radar asks at the present time)
    def position_enu(self, t: float) -> np.ndarray:
        return self.pos.copy()

    def velocity_enu(self, t: float) -> np.ndarray:
        return self.vel.copy()

    def telemetry_bytes(self, t: float) -> bytes:
        """MAVLink due at time ``t`` (HEARTBEAT, GLOBAL_POSITION_INT), encoded, or ``b""``."""
        return self.telemetry.due(t, self.pos, self.vel)


class IntruderTelemetry:
    """The intruder's own MAVLink transmitter: its system id, HEARTBEAT 1 Hz, GLOBAL_POSITION_INT.

    The first heartbeat goes out 1 s after boot, so a ground station that locks onto the first
    autopilot it hears meets the chaser (which speaks at once) first.
    """

    def __init__(self, sysid: int, rate_hz: float, frame: LocalFrame) -> None:
        self._mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=1)
        self._frame = frame
        self._geodesy = NearbyGeodetic(frame)
        self._period = 1.0 / rate_hz
        self._next_hb = 1.0
        self._next_pos = 1.0
        self.sent = 0

    def _pack(self, msg) -> bytes:
        data = msg.pack(self._mav)
        self._mav.seq = (self._mav.seq + 1) & 0xFF
        self.sent += 1
        return data

    def due(self, t: float, pos: np.ndarray, vel: np.ndarray) -> bytes:
        out = b""
        if t >= self._next_hb - 1e-9:
            self._next_hb += 1.0
            out += self._pack(mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_GENERIC, 0, 0, mavlink2.MAV_STATE_ACTIVE, 3))
        if t >= self._next_pos - 1e-9:
            self._next_pos += self._period
            g = self._geodesy(pos)
            home_alt = self._frame.origin.alt_m
            hdg = math.degrees(math.atan2(vel[0], vel[1])) % 360.0 if math.hypot(vel[0], vel[1]) > 0.3 else None
            out += self._pack(mavlink2.MAVLink_global_position_int_message(
                int(round(t * 1000.0)) & 0xFFFFFFFF, round(g.lat_deg * 1e7), round(g.lon_deg * 1e7),
                round(g.alt_m * 1000.0), round((g.alt_m - home_alt) * 1000.0),
                _cms(vel[1]), _cms(vel[0]), _cms(-vel[2]), 65535 if hdg is None else round(hdg * 100) % 36000))
        return out


def _cms(v: float) -> int:
    return int(min(max(round(v * 100.0), -32768), 32767))
