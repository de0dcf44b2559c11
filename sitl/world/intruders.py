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

Beside its trajectory pilot an intruder may fly scripted *manoeuvres* (:class:`Manoeuvre`: a turn,
a dash, a climb, a dive at a set time): :class:`ManoeuvrePilot` wraps the pilot and, while one is in
force, asks for the manoeuvre's velocity instead (the same limits apply); after it the pilot resumes.

Birds placed near a target or an intruder (:class:`BirdSpec`, :class:`BirdFlock`) are seen by the
radar and drawn by the rendered camera at the same place.

Like the paper's target, each intruder also sends its position over MAVLink under its own system
id (HEARTBEAT at 1 Hz, GLOBAL_POSITION_INT at ``telemetry_hz``), which the simulator writes to
every port beside the vehicle's own stream (:class:`IntruderTelemetry`). The heartbeat says
MAV_TYPE_QUADROTOR / MAV_AUTOPILOT_GENERIC. Random pilots draw from the generator they are given,
so the same seed flies the same path. An intruder also implements the
:class:`sitl.world.targets.TargetPath` protocol for its present state, so the radar sees it.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from chaser_bt.geo import LocalFrame, NearbyGeodetic
from sitl.world.camera.distractors import BIRD_LOOKS, BirdPose
from sitl.world.radar.config import RadarSignature

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

__all__ = [
    "IntruderLimits", "Pilot", "RectanglePilot", "CirclePilot", "FigureEightPilot", "RandomWaypointsPilot",
    "EvasivePilot", "IntruderSpec", "Intruder", "IntruderTelemetry", "TRAJECTORY_KINDS", "MANOEUVRE_KINDS",
    "Manoeuvre", "ManoeuvrePilot", "BirdSpec", "BirdFlock", "MAX_FLOCK",
]

log = logging.getLogger(__name__)

TRAJECTORY_KINDS = ("rectangle", "circle", "figure_eight", "random_waypoints", "evasive")
MANOEUVRE_KINDS = ("turn", "dash", "climb", "dive")
MAX_FLOCK = 30  # birds in one flock at most


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


def _enu_heading(compass_deg: float) -> float:
    """ENU angle (from east, counter-clockwise, rad) of a compass heading (from north, clockwise, deg)."""
    return math.radians(90.0 - compass_deg)


@dataclass(frozen=True)
class Manoeuvre:
    """A scripted manoeuvre from ``at_s`` (see ``sitl/scenarios/README.md``).

    - ``turn``: the commanded heading swings at a constant rate, the shorter way, from the heading at
      ``at_s`` to ``heading_deg`` (compass), reaching it at ``at_s + duration_s``; horizontal speed
      ``speed_mps`` (default: the speed at ``at_s``); altitude held.
    - ``dash``: at once ``heading_deg`` at ``speed_mps`` (default: the horizontal speed limit) for
      ``duration_s``; altitude held.
    - ``climb`` / ``dive``: to ``to_alt_m`` (ENU up) at ``speed_mps`` up / down (default: the vertical
      limit), slowing to arrive, keeping the horizontal velocity of ``at_s``; done within 0.5 m of
      ``to_alt_m`` or after ``duration_s`` if given, whichever is first (at once if the intruder is
      already past ``to_alt_m`` in that direction).
    """

    at_s: float
    kind: str
    duration_s: float | None = None
    heading_deg: float | None = None
    speed_mps: float | None = None
    to_alt_m: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in MANOEUVRE_KINDS:
            raise ValueError(f"manoeuvre kind {self.kind!r}: one of {', '.join(MANOEUVRE_KINDS)}")
        needs = ("heading_deg", "duration_s") if self.kind in ("turn", "dash") else ("to_alt_m",)
        missing = [k for k in needs if getattr(self, k) is None]
        if missing:
            raise ValueError(f"a {self.kind} manoeuvre needs {', '.join(missing)}")

    @property
    def end_s(self) -> float | None:
        """When it ends by the clock (a climb or dive may end sooner); None: when its altitude is reached."""
        return None if self.duration_s is None else self.at_s + self.duration_s


#: A climb or dive is done within this of its altitude.
ARRIVE_ALT_M = 0.5


@dataclass
class ManoeuvrePilot:
    """A pilot flying scripted manoeuvres over another: while one is in force (:class:`Manoeuvre`) the
    desired velocity is the manoeuvre's, otherwise ``pilot``'s. The inner pilot is not asked during a
    manoeuvre: it resumes afterwards from where the intruder is then. A manoeuvre starting ends the
    one before it."""

    pilot: Pilot
    manoeuvres: tuple[Manoeuvre, ...]
    _k: int = -1  # the latest manoeuvre started
    _done: bool = True
    _h0: float = 0.0  # at the manoeuvre's start: heading (ENU rad), horizontal speed and velocity
    _speed0: float = 0.0
    _vh0: np.ndarray = field(default_factory=lambda: np.zeros(2))

    @property
    def active(self) -> Manoeuvre | None:
        """The manoeuvre in force at the last call, or None."""
        return None if self._done or self._k < 0 else self.manoeuvres[self._k]

    def desired_velocity(self, t, pos, vel, limits):
        ms = self.manoeuvres
        while self._k + 1 < len(ms) and ms[self._k + 1].at_s <= t:
            self._k += 1
            self._begin(ms[self._k], pos, vel)
        if not self._done:
            v = self._command(ms[self._k], t, pos, limits)
            if v is not None:
                return v
            self._done = True
        return self.pilot.desired_velocity(t, pos, vel, limits)

    def _begin(self, m: Manoeuvre, pos: np.ndarray, vel: np.ndarray) -> None:
        self._done = False
        self._vh0 = np.asarray(vel[:2], float).copy()
        self._speed0 = float(math.hypot(vel[0], vel[1]))
        self._h0 = math.atan2(vel[1], vel[0]) if self._speed0 > 0.3 else _enu_heading(m.heading_deg or 0.0)
        if m.kind in ("climb", "dive") and (pos[2] > m.to_alt_m if m.kind == "climb" else pos[2] < m.to_alt_m):
            log.warning("%s at %.1f s to %.1f m: already past it at %.1f m, skipped", m.kind, m.at_s, m.to_alt_m, pos[2])
            self._done = True

    def _command(self, m: Manoeuvre, t: float, pos: np.ndarray, limits: IntruderLimits) -> np.ndarray | None:
        """The manoeuvre's velocity at ``t``, or None once it is over."""
        if m.end_s is not None and t >= m.end_s:
            return None
        if m.kind in ("turn", "dash"):
            h1 = _enu_heading(m.heading_deg)
            if m.kind == "turn":
                turn = (h1 - self._h0 + math.pi) % (2.0 * math.pi) - math.pi
                h = self._h0 + turn * min((t - m.at_s) / m.duration_s, 1.0)
                speed = self._speed0 if m.speed_mps is None else m.speed_mps
            else:
                h, speed = h1, limits.speed_h_mps if m.speed_mps is None else m.speed_mps
            return np.array([speed * math.cos(h), speed * math.sin(h), 0.0])
        dz = m.to_alt_m - float(pos[2])
        if abs(dz) < ARRIVE_ALT_M:
            return None
        limit = limits.speed_up_mps if dz > 0 else limits.speed_down_mps
        speed = min(limit if m.speed_mps is None else m.speed_mps, math.sqrt(limits.accel_v_mps2 * abs(dz)), 1.5 * abs(dz))
        return np.array([self._vh0[0], self._vh0[1], math.copysign(speed, dz)])


@dataclass(frozen=True)
class IntruderSpec:
    """An intruder as the scenario describes it (see ``sitl/scenarios/README.md``).

    ``trajectory`` is one of :data:`TRAJECTORY_KINDS` and ``params`` its keys (SI units, radians);
    the intruder hovers at ``start_enu`` until ``start_s``. ``manoeuvres`` (in time order) are flown
    over the trajectory (:class:`ManoeuvrePilot`); ``radar`` is how the ground radar sees it.
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
    manoeuvres: tuple[Manoeuvre, ...] = ()
    radar: RadarSignature | None = None

    def make_pilot(self, rng: np.random.Generator) -> Pilot:
        """The trajectory's pilot, wrapped in a :class:`ManoeuvrePilot` when there are manoeuvres."""
        pilot = self._trajectory_pilot(rng)
        return ManoeuvrePilot(pilot, self.manoeuvres) if self.manoeuvres else pilot

    def _trajectory_pilot(self, rng: np.random.Generator) -> Pilot:
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


# -- birds near a target: one object for the radar and the camera alike ------------------------------


class Anchor(Protocol):
    """What a bird keeps station by: a scripted target's path or an intruder (its present state)."""

    def position_enu(self, t: float) -> np.ndarray: ...

    def velocity_enu(self, t: float) -> np.ndarray: ...


@dataclass(frozen=True)
class BirdSpec:
    """A bird (``count`` 1) or a flock near the target or intruder ``near``, present from ``start_s``
    until ``end_s`` (None: to the end); see :class:`BirdFlock` for how it flies.

    ``radar.rcs_m2`` is one bird's cross-section; the radar sees a flock as one object of ``count``
    times it (:attr:`flock_signature`).
    """

    near: str
    offset_enu: tuple[float, float, float]
    count: int = 1
    spread_m: float = 5.0
    speed_mps: float = 8.0
    start_s: float = 0.0
    end_s: float | None = None
    radar: RadarSignature | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.count <= MAX_FLOCK:
            raise ValueError(f"bird count {self.count}: 1..{MAX_FLOCK}")
        if not (self.spread_m > 0.0 and self.speed_mps > 0.0):
            raise ValueError(f"bird spread_m and speed_mps must be > 0, got {self.spread_m}, {self.speed_mps}")

    def present(self, t: float) -> bool:
        return t >= self.start_s and (self.end_s is None or t < self.end_s)

    @property
    def flock_signature(self) -> RadarSignature | None:
        """The whole flock's radar signature: the birds' cross-sections add (incoherently)."""
        r = self.radar
        if r is None or r.rcs_m2 is None or self.count == 1:
            return r
        return RadarSignature(r.rcs_m2 * self.count, r.pd, r.drop_per_s)


class BirdFlock:
    """One ``birds`` entry in flight.

    The flock's centre circles its *station point*, the anchor's position plus ``offset_enu``, at
    radius ``spread_m`` and speed ``speed_mps`` (relative to the anchor, whose velocity it shares),
    in a direction and from a phase drawn from ``rng``: a bird keeping near the target, never more
    than ``spread_m`` from the station point. A flock's birds sit at fixed offsets from the centre
    (1 sigma ``spread_m`` across, 0.4 of it up and down; their mean is the centre). The radar sees the
    centre as one object named :attr:`label`; the camera draws every bird (:meth:`poses`), flapping,
    in one of the looks of :data:`sitl.world.camera.distractors.BIRD_LOOKS`.
    """

    def __init__(self, spec: BirdSpec, label: str, anchor: Anchor, rng: np.random.Generator) -> None:
        self.spec = spec
        self.label = label
        self.anchor = anchor
        self._phase0 = float(rng.uniform(0.0, 2.0 * math.pi))
        self._turn = 1.0 if rng.random() < 0.5 else -1.0  # counter-clockwise or clockwise
        (span, flap_hz), colour = BIRD_LOOKS[int(rng.integers(len(BIRD_LOOKS)))]
        n = spec.count
        off = rng.normal(0.0, spec.spread_m, (n, 3)) * np.array([1.0, 1.0, 0.4]) if n > 1 else np.zeros((1, 3))
        self.offsets = off - off.mean(axis=0)
        self._span = span * rng.uniform(0.85, 1.15, n)
        self._flap_hz = flap_hz * rng.uniform(0.8, 1.2, n)
        self._flap_phase = rng.uniform(0.0, 2.0 * math.pi, n)
        self._colour = colour

    def present(self, t: float) -> bool:
        return self.spec.present(t)

    def centre(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The flock's centre at ``t`` (ENU position, velocity): what the radar sees."""
        s = self.spec
        w = self._turn * s.speed_mps / s.spread_m
        a = self._phase0 + w * (t - s.start_s)
        station = np.asarray(self.anchor.position_enu(t), float) + np.asarray(s.offset_enu, float)
        pos = station + s.spread_m * np.array([math.cos(a), math.sin(a), 0.0])
        vel = np.asarray(self.anchor.velocity_enu(t), float) + s.spread_m * w * np.array([-math.sin(a), math.cos(a), 0.0])
        return pos, vel

    def poses(self, t: float) -> tuple[BirdPose, ...]:
        """Every bird at ``t``, for the camera."""
        pos, vel = self.centre(t)
        v = tuple(float(x) for x in vel)
        return tuple(BirdPose(tuple(float(x) for x in pos + d), v, float(span), float(hz), float(ph), self._colour)
                     for d, span, hz, ph in zip(self.offsets, self._span, self._flap_hz, self._flap_phase))
