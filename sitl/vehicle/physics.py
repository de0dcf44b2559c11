"""Rigid-body multicopter physics: a point mass with a lagged attitude, wind, ground and battery.

The model is what a flight controller's outer loops see of a multicopter. Roll and pitch follow
their commands with a first-order lag (the closed attitude loop), the yaw rate likewise, and the
total thrust follows its command with a rotor spin-up lag, clipped between idle and maximum.
Thrust acts along the body's up axis; drag is linear plus quadratic in the air-relative
velocity; the wind is a mean plus first-order Gauss-Markov gusts (a Dryden-like coloured
noise). The ground is flat at the frame's origin altitude. The battery drains with a current
that scales as thrust^1.5 (momentum theory) and sags by its internal resistance.

Speed matters more than generality here (a rehearsal runs at 100x real time), so the state is
plain floats and the step uses ``math`` on scalars: numpy's per-call overhead on 3-vectors
would cost more than the whole step. Lags are integrated with their exact discrete solution,
so the response does not depend on the step size. The default rate is 50 Hz (see
:data:`PHYSICS_DT`).

Angles follow MAVLink: roll, pitch, yaw of the FRD body in NED (yaw = compass heading).
Positions and velocities are ENU metres in the simulator's local frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sitl.vehicle.airframe import GRAVITY, AirframeParams, lipo_cell_ocv

__all__ = ["PHYSICS_DT", "WindParams", "NormalStream", "Wind", "Battery", "MulticopterPhysics"]

# 50 Hz: the attitude lag (0.15 s) spans 7 steps and is integrated exactly; the outer position
# and velocity loops (bandwidth ~2 rad/s) and the 10-50 Hz telemetry need no more, and it
# halves the cost of 100 Hz. Larger steps given to step() are split into steps of this size.
PHYSICS_DT = 0.02


@dataclass(frozen=True)
class WindParams:
    """Wind: a mean plus gusts.

    Attributes:
        speed_mps: mean horizontal wind speed.
        direction_deg: where the wind blows FROM, compass degrees (meteorological convention).
        gust_std_mps: standard deviation of each horizontal gust component (vertical: half).
        gust_tau_s: correlation time of the gusts.
    """

    speed_mps: float = 0.0
    direction_deg: float = 0.0
    gust_std_mps: float = 0.0
    gust_tau_s: float = 2.0

    def __post_init__(self) -> None:
        if self.speed_mps < 0.0:
            raise ValueError(f"speed_mps must be >= 0, got {self.speed_mps}")
        if self.gust_std_mps < 0.0:
            raise ValueError(f"gust_std_mps must be >= 0, got {self.gust_std_mps}")
        if not self.gust_tau_s > 0.0:
            raise ValueError(f"gust_tau_s must be > 0, got {self.gust_tau_s}")

    def mean_enu(self) -> tuple[float, float]:
        """Mean wind velocity (east, north), m/s: it blows towards direction + 180 deg."""
        d = math.radians(self.direction_deg)
        return -self.speed_mps * math.sin(d), -self.speed_mps * math.cos(d)


class NormalStream:
    """Standard normal samples drawn from a seeded Generator in blocks (one draw call per block)."""

    def __init__(self, rng: np.random.Generator, block: int = 8192) -> None:
        self._rng = rng
        self._block = block
        self._buf: list[float] = []
        self._i = 0

    def take(self) -> float:
        """The next N(0, 1) sample."""
        if self._i >= len(self._buf):
            self._buf = self._rng.standard_normal(self._block).tolist()
            self._i = 0
        x = self._buf[self._i]
        self._i += 1
        return x


class Wind:
    """Mean wind plus first-order Gauss-Markov gusts on each axis."""

    def __init__(self, params: WindParams, normals: NormalStream) -> None:
        self.params = params
        self._normals = normals
        self._mean_e, self._mean_n = params.mean_enu()
        self.gust = [0.0, 0.0, 0.0]
        self._dt = -1.0
        self._a = 0.0
        self._b = (0.0, 0.0, 0.0)

    def step(self, dt: float) -> tuple[float, float, float]:
        """Advance the gusts by ``dt``; return the wind velocity (east, north, up), m/s."""
        if dt != self._dt:
            p = self.params
            self._dt = dt
            self._a = math.exp(-dt / p.gust_tau_s)
            s = math.sqrt(1.0 - self._a * self._a)
            self._b = (p.gust_std_mps * s, p.gust_std_mps * s, 0.5 * p.gust_std_mps * s)
        g = self.gust
        if self.params.gust_std_mps > 0.0:
            a, b, take = self._a, self._b, self._normals.take
            g[0] = a * g[0] + b[0] * take()
            g[1] = a * g[1] + b[1] * take()
            g[2] = a * g[2] + b[2] * take()
        return self._mean_e + g[0], self._mean_n + g[1], g[2]


class Battery:
    """A LiPo pack: coulomb counting, open-circuit voltage from charge, resistive sag.

    ``voltage_drop_v`` is an extra sag a scripted fault may apply (a failing cell).
    """

    def __init__(self, airframe: AirframeParams) -> None:
        self._cells = airframe.battery_cells
        self._capacity_mah = airframe.battery_capacity_mah
        self._r = airframe.battery_resistance_ohm
        self.current_a = 0.0
        self.consumed_mah = 0.0
        self.voltage_drop_v = 0.0

    def drain(self, current_a: float, dt: float) -> None:
        """Draw ``current_a`` for ``dt`` seconds."""
        self.current_a = current_a
        self.consumed_mah += current_a * dt / 3.6

    @property
    def soc(self) -> float:
        """State of charge, 0..1."""
        return max(0.0, 1.0 - self.consumed_mah / self._capacity_mah)

    @property
    def voltage_v(self) -> float:
        """Terminal voltage under the present load."""
        v = self._cells * lipo_cell_ocv(self.soc) - self.current_a * self._r - self.voltage_drop_v
        return max(0.0, v)


class MulticopterPhysics:
    """State and integration of the simulated multicopter.

    Commands (set by the flight controller before each :meth:`step`): ``roll_cmd``, ``pitch_cmd``
    (rad), ``yaw_rate_cmd`` (rad/s, clockwise positive as MAVLink), ``thrust_cmd`` (N) and
    ``motors_on`` (False = disarmed, rotors stopped).
    """

    def __init__(self, airframe: AirframeParams, wind: Wind, yaw: float = 0.0) -> None:
        self.airframe = airframe
        self.wind = wind
        self.battery = Battery(airframe)
        # ENU position and velocity, m and m/s
        self.px = self.py = self.pz = 0.0
        self.vx = self.vy = self.vz = 0.0
        # attitude (NED/FRD Euler, rad), its rates (rad/s)
        self.roll = self.pitch = 0.0
        self.yaw = yaw
        self.roll_rate = self.pitch_rate = self.yaw_rate = 0.0
        self.thrust = 0.0
        self.wind_enu = (0.0, 0.0, 0.0)
        self.on_ground = True
        self.crashed = False
        self.roll_cmd = self.pitch_cmd = self.yaw_rate_cmd = 0.0
        self.thrust_cmd = 0.0
        self.motors_on = False
        self._dt = -1.0
        self._k_att = self._k_yaw = self._k_motor = 0.0

    def _set_dt(self, dt: float) -> None:
        a = self.airframe
        self._dt = dt
        self._k_att = 1.0 - math.exp(-dt / a.attitude_tau_s)
        self._k_yaw = 1.0 - math.exp(-dt / a.yaw_rate_tau_s)
        self._k_motor = 1.0 - math.exp(-dt / a.motor_tau_s)

    def motor_current_a(self, thrust: float) -> float:
        """Current drawn by the rotors producing ``thrust`` N (thrust^1.5 law)."""
        a = self.airframe
        if thrust <= 0.0:
            return 0.0
        r = thrust / a.hover_thrust_n
        return a.hover_current_a * r * math.sqrt(r)

    def step(self, dt: float) -> None:
        """Advance the state by ``dt`` seconds (one integration step; keep dt <= PHYSICS_DT)."""
        if dt != self._dt:
            self._set_dt(dt)
        a = self.airframe
        # rotors: thrust follows its command with the spin-up lag, clipped to idle..max
        if self.motors_on:
            cmd = min(max(self.thrust_cmd, a.idle_thrust_n), a.max_thrust_n)
        else:
            cmd = 0.0
        self.thrust += (cmd - self.thrust) * self._k_motor
        thrust = self.thrust
        # attitude: first-order lag towards the commanded angles / yaw rate
        old_roll, old_pitch = self.roll, self.pitch
        if self.on_ground:
            roll = pitch = 0.0
        else:
            roll = old_roll + (self.roll_cmd - old_roll) * self._k_att
            pitch = old_pitch + (self.pitch_cmd - old_pitch) * self._k_att
        self.roll, self.pitch = roll, pitch
        self.roll_rate = (roll - old_roll) / dt
        self.pitch_rate = (pitch - old_pitch) / dt
        self.yaw_rate += (self.yaw_rate_cmd - self.yaw_rate) * self._k_yaw
        if self.on_ground and thrust < a.hover_thrust_n:
            self.yaw_rate = 0.0
        self.yaw = (self.yaw + self.yaw_rate * dt + math.pi) % (2.0 * math.pi) - math.pi
        # thrust along body up, in ENU (x east, y north, z up)
        cr, sr = math.cos(roll), math.sin(roll)
        cp, sp = math.cos(pitch), math.sin(pitch)
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        t_m = thrust / a.mass_kg
        a_north = -t_m * (cy * sp * cr + sy * sr)
        a_east = -t_m * (sy * sp * cr - cy * sr)
        a_up = t_m * cp * cr - GRAVITY
        # drag on the air-relative velocity
        we, wn, wu = self.wind_enu = self.wind.step(dt)
        rx, ry, rz = self.vx - we, self.vy - wn, self.vz - wu
        sh = math.sqrt(rx * rx + ry * ry)
        kh = (a.drag_lin_h + a.drag_quad_h * sh) / a.mass_kg
        kv = (a.drag_lin_v + a.drag_quad_v * abs(rz)) / a.mass_kg
        self.vx += (a_east - kh * rx) * dt
        self.vy += (a_north - kh * ry) * dt
        self.vz += (a_up - kv * rz) * dt
        old_px, old_py = self.px, self.py
        self.px += self.vx * dt
        self.py += self.vy * dt
        self.pz += self.vz * dt
        # ground contact: flat ground at z = 0; resting when thrust cannot lift the weight
        if self.pz <= 0.0:
            if not self.on_ground and self.vz < -a.crash_speed_mps:
                self.crashed = True
            self.pz = 0.0
            if self.vz < 0.0:
                self.vz = 0.0
            if thrust * cp * cr <= a.hover_thrust_n:
                # resting on the gear: friction holds it where it was
                self.on_ground = True
                self.vx = self.vy = self.vz = 0.0
                self.px, self.py = old_px, old_py
            else:
                self.on_ground = False
        else:
            self.on_ground = False
        # battery
        current = a.avionics_current_a + (self.motor_current_a(thrust) if self.motors_on else 0.0)
        self.battery.drain(current, dt)
