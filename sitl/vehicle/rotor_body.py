"""A motor-level multirotor for ArduPilot's JSON physics backend: PWM in, IMU out.

Where :mod:`sitl.vehicle.physics` models what a flight controller's *outer* loops see (a lagged
attitude), an autopilot flying its own attitude loops needs the rotors. Each motor's thrust follows
its PWM through a first-order spin-up lag and ArduPilot's thrust curve; the arms turn thrust
differences into roll and pitch torques, the props' drag into a yaw torque, and a rigid body with a
diagonal inertia integrates them in air that moves at :attr:`RotorBody.wind_ned`. A flat ground at
home stops the fall and holds the copter level while the thrust is below its weight.

The motor matrices are ArduPilot's (``libraries/AP_Motors/AP_MotorsMatrix.cpp``,
``setup_quad_matrix`` and ``setup_octa_matrix``): motor *i* sits at ``angle`` degrees clockwise
from the nose and its roll, pitch and yaw factors are ``cos(angle + 90°)``, ``cos(angle)`` and +1
for a counter-clockwise prop (``AP_MOTORS_MATRIX_YAW_FACTOR_CCW``), -1 for a clockwise one. Motor
*i* receives servo channel *i* (stock SERVOn_FUNCTION = Motor n). A counter-clockwise prop drags
the body clockwise seen from above: a positive yaw torque in FRD, as the yaw factor says.

The thrust curve is the one ArduPilot's output stage inverts (``AP_Motors_Thrust_Linearization``):
thrust ``T = T_max ((1 - e) x + e x²)`` with ``e = MOT_THST_EXPO`` and ``x`` the PWM's place
between ``MOT_SPIN_MIN`` (no thrust yet) and ``MOT_SPIN_MAX`` (full thrust) of the PWM range. So
the hover value ArduCopter learns, MOT_THST_HOVER, is the thrust fraction
``m g / (n T_max)`` (:attr:`RotorParams.hover_thrust_fraction`), up to its battery-voltage and
air-density compensation.

Frames are ArduPilot's: NED earth, FRD body. The step runs on plain floats, with the attitude kept
as a normalised quaternion: at 400 frames a second a JSON backend spends its time here, and scipy's
``Rotation`` costs tens of microseconds a call. scipy appears only off the hot path
(:attr:`RotorBody.attitude`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from sitl.vehicle.airframe import GRAVITY
from sitl.vehicle.json_backend import SensorFrame, ServoPacket

# How fast a body that touched down tilted tips back level onto its feet (rad/s): 15 deg in 0.13 s.
SETTLE_RATE_RPS = 2.0

__all__ = ["AIRFRAMES", "FRAMES", "RotorBody", "RotorFrame", "RotorParams", "rotor_airframe", "rotor_frame"]

log = logging.getLogger(__name__)

_CW, _CCW = -1.0, 1.0  # AP_MOTORS_MATRIX_YAW_FACTOR_CW / _CCW


@dataclass(frozen=True)
class RotorFrame:
    """One of ArduPilot's motor matrices: where each motor sits and which way its prop turns.

    Attributes:
        name: ours, e.g. ``"octa-x"``.
        frame_class: ArduPilot's FRAME_CLASS (1 quad, 3 octa).
        frame_type: ArduPilot's FRAME_TYPE (0 plus, 1 X).
        angles_deg: motor *i*'s arm, degrees clockwise from the nose (AP_MotorsMatrix's ``angle``).
        yaw_factors: +1 counter-clockwise prop, -1 clockwise.
    """

    name: str
    frame_class: int
    frame_type: int
    angles_deg: tuple[float, ...]
    yaw_factors: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.angles_deg) != len(self.yaw_factors) or not self.angles_deg:
            raise ValueError(f"frame {self.name}: {len(self.angles_deg)} angles, {len(self.yaw_factors)} yaw factors")

    @property
    def motors(self) -> int:
        return len(self.angles_deg)

    @property
    def roll_factors(self) -> tuple[float, ...]:
        """ArduPilot's roll factor ``cos(angle + 90°)``: -1 for a motor on the right arm."""
        return tuple(math.cos(math.radians(a + 90.0)) for a in self.angles_deg)

    @property
    def pitch_factors(self) -> tuple[float, ...]:
        """ArduPilot's pitch factor ``cos(angle)``: +1 for a motor on the nose."""
        return tuple(math.cos(math.radians(a)) for a in self.angles_deg)


FRAMES: dict[str, RotorFrame] = {f.name: f for f in (
    RotorFrame("quad-plus", 1, 0, (90.0, -90.0, 0.0, 180.0), (_CCW, _CCW, _CW, _CW)),
    RotorFrame("quad-x", 1, 1, (45.0, -135.0, -45.0, 135.0), (_CCW, _CCW, _CW, _CW)),
    RotorFrame("octa-plus", 3, 0, (0.0, 180.0, 45.0, 135.0, -45.0, -135.0, -90.0, 90.0),
               (_CW, _CW, _CCW, _CCW, _CCW, _CCW, _CW, _CW)),
    RotorFrame("octa-x", 3, 1, (22.5, -157.5, 67.5, 157.5, -22.5, -112.5, -67.5, 112.5),
               (_CW, _CW, _CCW, _CCW, _CCW, _CCW, _CW, _CW)),
)}


def rotor_frame(name: str) -> RotorFrame:
    """The motor matrix called ``name`` (``quad-plus``, ``quad-x``, ``octa-plus``, ``octa-x``)."""
    try:
        return FRAMES[name]
    except KeyError:
        raise KeyError(f"no rotor frame {name!r}; known: {', '.join(FRAMES)}") from None


@dataclass(frozen=True)
class RotorParams:
    """A multirotor's physical constants (SI) and the ArduPilot parameters that fly it.

    Attributes:
        name: what :func:`rotor_airframe` calls it.
        frame: its motor matrix.
        mass_kg: take-off mass.
        arm_m: centre to each motor's axis (half the diagonal wheelbase).
        inertia_kgm2: principal moments about the FRD axes.
        max_thrust_n: one motor's static thrust at full throttle.
        thrust_expo: the curve's bend (ArduPilot's MOT_THST_EXPO).
        spin_min, spin_max: where thrust starts and saturates, as fractions of the PWM range
            (ArduPilot's MOT_SPIN_MIN, MOT_SPIN_MAX).
        yaw_torque_per_n: a prop's drag torque per newton of its thrust (m).
        motor_tau_s: time constant of a motor's thrust following its PWM (spin-up).
        pwm_min_us, pwm_max_us: the ESC's PWM range (ArduCopter takes RC3_MIN/RC3_MAX).
        drag_lin, drag_quad: drag force ``(lin + quad |v_air|) v_air`` (N per m/s, N per (m/s)²).
        angular_damping: aerodynamic torque per rad/s of body rate (N m s).
        crash_speed_mps: touching the ground faster than this is a crash (as
            :class:`~sitl.vehicle.airframe.AirframeParams`).
        ardupilot_tuning: parameters beyond the frame and hover guess that it needs on stock
            tuning, as (name, value) pairs.
    """

    name: str
    frame: RotorFrame
    mass_kg: float
    arm_m: float
    inertia_kgm2: tuple[float, float, float]
    max_thrust_n: float
    thrust_expo: float = 0.65
    spin_min: float = 0.15
    spin_max: float = 0.95
    yaw_torque_per_n: float = 0.02
    motor_tau_s: float = 0.02
    pwm_min_us: float = 1000.0
    pwm_max_us: float = 2000.0
    drag_lin: float = 0.25
    drag_quad: float = 0.0
    angular_damping: float = 0.02
    crash_speed_mps: float = 3.0
    ardupilot_tuning: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        for name in ("mass_kg", "arm_m", "max_thrust_n", "motor_tau_s", "crash_speed_mps"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{self.name}: {name} must be > 0, got {getattr(self, name)}")
        if not all(i > 0.0 for i in self.inertia_kgm2) or len(self.inertia_kgm2) != 3:
            raise ValueError(f"{self.name}: inertia_kgm2 must be three positive moments, got {self.inertia_kgm2}")
        if not 0.0 <= self.spin_min < self.spin_max <= 1.0:
            raise ValueError(f"{self.name}: need 0 <= spin_min < spin_max <= 1, got {self.spin_min}, {self.spin_max}")
        if not 0.0 <= self.thrust_expo <= 1.0:
            raise ValueError(f"{self.name}: thrust_expo must be in [0, 1], got {self.thrust_expo}")
        if not self.hover_thrust_fraction < 1.0:
            raise ValueError(f"{self.name}: {self.frame.motors} x {self.max_thrust_n} N cannot lift {self.mass_kg} kg")

    @property
    def hover_thrust_fraction(self) -> float:
        """Each motor's share of its full thrust in hover: what MOT_THST_HOVER learns."""
        return self.mass_kg * GRAVITY / (self.frame.motors * self.max_thrust_n)

    @property
    def hover_throttle(self) -> float:
        """The PWM, as a fraction of its range, that hovers (the thrust curve solved, then spin range)."""
        e, f = self.thrust_expo, self.hover_thrust_fraction
        x = f if e == 0.0 else (-(1.0 - e) + math.sqrt((1.0 - e) ** 2 + 4.0 * e * f)) / (2.0 * e)
        return self.spin_min + (self.spin_max - self.spin_min) * x

    @property
    def hover_pwm_us(self) -> float:
        return self.pwm_min_us + (self.pwm_max_us - self.pwm_min_us) * self.hover_throttle

    def ardupilot_params(self) -> dict[str, float]:
        """What to write to ArduCopter's defaults file for this airframe: frame, thrust curve, hover guess, tuning."""
        params: dict[str, float] = {
            "FRAME_CLASS": self.frame.frame_class, "FRAME_TYPE": self.frame.frame_type,
            "MOT_THST_EXPO": self.thrust_expo, "MOT_SPIN_MIN": self.spin_min, "MOT_SPIN_MAX": self.spin_max,
            "MOT_THST_HOVER": round(self.hover_thrust_fraction, 3),
        }
        params.update(self.ardupilot_tuning)
        return params


# A 1.5 kg quad "+" as ArduPilot's own SITL quad is to its autopilot: 4 x 9.43 N, so it hovers at 39 % of
# full thrust (copter.parm's MOT_THST_HOVER), and the drag per kilogram that fitted that quad
# (benchmarks/bench_fidelity.py, QUAD_AIRFRAME: 1.37 + 0.234 |v| N per m/s on 8 kg, from its top ground
# speed into a 3 m/s wind at the lean limit). At 4 x 15 N (hover at 25 %) ArduCopter wound its throttle
# down to the floor sooner after touchdown and disarmed 0.2 s earlier than on its own quad.
QUAD = RotorParams(name="quad", frame=FRAMES["quad-plus"], mass_kg=1.5, arm_m=0.25,
                   inertia_kgm2=(0.015, 0.015, 0.03), max_thrust_n=9.43, drag_lin=0.257, drag_quad=0.0439)

# DJI S1000, the paper's aircraft: an octocopter, arms 45° apart with the nose between two of them
# (ArduPilot's octa X), 1045 mm diagonal wheelbase, 15 x 5.2 in props on 4114 400 KV motors, 6S.
# 7.5 kg take-off: the 4.4 kg airframe (S1000 4.2 kg + flight controller), a 6S 10 Ah pack
# (1.3 kg) and a 1.8 kg camera, gimbal and companion computer: mid-way in DJI's 6-11 kg range.
# 22 N (2.2 kgf) a motor at full throttle gives a thrust-to-weight of 2.4 and a hover at 42 % of
# full thrust. Inertia from 8 x 0.2 kg (motor, prop, mount) at the arm's end, 8 x 0.1 kg of arm
# and ESC at 0.3 m, a 1.5 kg gimbal 0.2 m below the centre, a 3 kg centre: about 0.35 kg m² in roll
# and pitch, 0.6 in yaw. A 15-inch prop spins up more slowly than the quad's (60 ms) and drags a
# torque of about 0.024 m per newton (C_Q / C_T ~ 0.064 D). Drag as the built-in simulator's S1000.
# Stock roll and pitch gains fly it (their output is normalised by the motors' authority): the slow
# test in tests/sitl/vehicle/test_json_backend.py holds 10 m within 1 m on them. Yaw is another
# matter: prop drag gives an octocopter little yaw authority for its inertia, and with the stock
# ATC_RAT_YAW_P 0.2 the yaw-rate loop is slower than the 4.5/s yaw-angle loop around it, so a 60 deg
# heading step overshot by 20 deg and rang for 10 s (a chase's camera swung +-90 deg off the target).
# Tuned as autotune would, by heading steps in ArduCopter: rate P 1.5, I 0.15 and a reachable yaw
# acceleration (90 deg/s^2) overshoot by 12 deg and settle in 2.5 s.
S1000 = RotorParams(name="s1000", frame=FRAMES["octa-x"], mass_kg=7.5, arm_m=0.5225,
                    inertia_kgm2=(0.35, 0.35, 0.60), max_thrust_n=22.0, yaw_torque_per_n=0.024,
                    motor_tau_s=0.06, drag_lin=0.3, drag_quad=0.12, angular_damping=0.05,
                    ardupilot_tuning=(("ATC_RAT_YAW_P", 1.5), ("ATC_RAT_YAW_I", 0.15), ("ATC_ACCEL_Y_MAX", 9000.0)))

AIRFRAMES: dict[str, RotorParams] = {p.name: p for p in (QUAD, S1000)}


def rotor_airframe(name: str) -> RotorParams:
    """The airframe called ``name`` (``quad``, ``s1000``)."""
    try:
        return AIRFRAMES[name]
    except KeyError:
        raise KeyError(f"no rotor airframe {name!r}; known: {', '.join(AIRFRAMES)}") from None


def _triple(v: Sequence[float], what: str) -> tuple[float, float, float]:
    a = tuple(float(x) for x in v)
    if len(a) != 3:
        raise ValueError(f"{what}: expected 3 values, got {len(a)}")
    return a  # type: ignore[return-value]


def _readonly(values: Sequence[float]) -> np.ndarray:
    a = np.array(values, dtype=float)
    a.flags.writeable = False  # a copy: writing into it would change nothing, so it may not
    return a


class RotorBody:
    """A multirotor's state and its step; :meth:`physics` is the JSON server's callable.

    The truth a scorer reads (``position_ned``, ``velocity_ned``, ``rates_frd``, ``thrust_n``,
    ``wind_ned``) comes as read-only arrays; assign a whole new value to change one.

    Args:
        params: the airframe (default the 1.5 kg quad); :meth:`named` picks one by name.
        position_ned: metres from home; on the ground when ``position_ned[2] >= 0``.
        velocity_ned: m/s.
        attitude: FRD body -> NED (default level, nose north).
        rates_frd: body rates, rad/s.
        wind_ned: the air's velocity, m/s.
    """

    def __init__(self, params: RotorParams = QUAD, *, position_ned: Sequence[float] = (0.0, 0.0, 0.0),
                 velocity_ned: Sequence[float] = (0.0, 0.0, 0.0), attitude: Rotation | None = None,
                 rates_frd: Sequence[float] = (0.0, 0.0, 0.0), wind_ned: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        self.params = params
        self.position_ned = position_ned
        self.velocity_ned = velocity_ned
        self.rates_frd = rates_frd
        self.wind_ned = wind_ned
        self.attitude = attitude if attitude is not None else Rotation.identity()
        self._thrust = [0.0] * params.frame.motors
        self.on_ground = self._pz >= 0.0
        self.crashed = False
        self._dt = -1.0
        self._motor_keep = 0.0
        p, f = params, params.frame
        # Per motor: arm's forward and right reach (m), yaw torque per newton (m).
        self._motors = tuple((p.arm_m * math.cos(math.radians(a)), p.arm_m * math.sin(math.radians(a)),
                              y * p.yaw_torque_per_n) for a, y in zip(f.angles_deg, f.yaw_factors))
        span = (p.pwm_max_us - p.pwm_min_us) * (p.spin_max - p.spin_min)
        self._pwm_zero = p.pwm_min_us + (p.pwm_max_us - p.pwm_min_us) * p.spin_min  # PWM of no thrust
        self._pwm_scale = 1.0 / span

    @classmethod
    def named(cls, airframe: str, **state) -> RotorBody:
        """A body of the airframe called ``airframe`` (``quad``, ``s1000``); ``state`` as the constructor's."""
        return cls(rotor_airframe(airframe), **state)

    # -- state, as arrays for the scorer ------------------------------------------------------
    @property
    def position_ned(self) -> np.ndarray:
        return _readonly((self._px, self._py, self._pz))

    @position_ned.setter
    def position_ned(self, v: Sequence[float]) -> None:
        self._px, self._py, self._pz = _triple(v, "position_ned")

    @property
    def velocity_ned(self) -> np.ndarray:
        return _readonly((self._vx, self._vy, self._vz))

    @velocity_ned.setter
    def velocity_ned(self, v: Sequence[float]) -> None:
        self._vx, self._vy, self._vz = _triple(v, "velocity_ned")

    @property
    def rates_frd(self) -> np.ndarray:
        return _readonly((self._wp, self._wq, self._wr))

    @rates_frd.setter
    def rates_frd(self, v: Sequence[float]) -> None:
        self._wp, self._wq, self._wr = _triple(v, "rates_frd")

    @property
    def wind_ned(self) -> np.ndarray:
        """The air's velocity (m/s, NED); drag acts on the velocity relative to it."""
        return _readonly(self._wind)

    @wind_ned.setter
    def wind_ned(self, v: Sequence[float]) -> None:
        self._wind = _triple(v, "wind_ned")

    @property
    def thrust_n(self) -> np.ndarray:
        """Each motor's thrust now (N), in motor order."""
        return _readonly(self._thrust)

    @property
    def attitude(self) -> Rotation:
        """FRD body -> NED, as a scipy Rotation (built on each call: not for the hot path)."""
        return Rotation.from_quat((self._qx, self._qy, self._qz, self._qw))

    @attitude.setter
    def attitude(self, r: Rotation) -> None:
        self._qx, self._qy, self._qz, self._qw = (float(c) for c in r.as_quat())

    def euler_ned(self) -> tuple[float, float, float]:
        """Roll, pitch, yaw (rad) of the FRD body in NED (ZYX order, yaw in (-pi, pi])."""
        w, x, y, z = self._qw, self._qx, self._qy, self._qz
        roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
        pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
        yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        return roll, pitch, yaw

    # -- the step -----------------------------------------------------------------------------
    def physics(self, packet: ServoPacket, t_s: float) -> SensorFrame:
        """Step by ``packet.dt_s`` under its first PWMs (one a motor); what the IMU and GPS feel after it."""
        fx, fy, fz = self._step(packet.pwm_us, packet.dt_s)
        return SensorFrame(t_s, (self._wp, self._wq, self._wr), (fx, fy, fz), (self._px, self._py, self._pz),
                           (self._vx, self._vy, self._vz), self.euler_ned())

    def step(self, pwm_us: Sequence[float], dt: float) -> np.ndarray:
        """Advance by ``dt``, motor *i* on ``pwm_us[i]``; returns the specific force in FRD (the accelerometer)."""
        if len(pwm_us) < len(self._motors):
            raise ValueError(f"{self.params.name}: {len(self._motors)} motors, {len(pwm_us)} PWMs")
        return np.array(self._step(pwm_us, dt))

    def _step(self, pwm_us: Sequence[float], dt: float) -> tuple[float, float, float]:
        p = self.params
        if dt != self._dt:
            self._dt = dt
            self._motor_keep = math.exp(-dt / p.motor_tau_s)
        keep, e = self._motor_keep, p.thrust_expo
        zero, scale, t_max = self._pwm_zero, self._pwm_scale, p.max_thrust_n
        thrust = self._thrust
        total = tau_x = tau_y = tau_z = 0.0
        for i, ((fwd, right, yaw_k), pwm) in enumerate(zip(self._motors, pwm_us)):
            x = (pwm - zero) * scale
            x = 0.0 if x < 0.0 else 1.0 if x > 1.0 else x
            target = t_max * x * (1.0 - e + e * x)
            t = target + (thrust[i] - target) * keep
            thrust[i] = t
            total += t
            tau_x -= right * t  # thrust is along -z: r x F = (-right T, fwd T, 0)
            tau_y += fwd * t
            tau_z += yaw_k * t
        w, qx, qy, qz = self._qw, self._qx, self._qy, self._qz
        # Body -> NED rotation's columns as needed: thrust along body -z, drag back into the body.
        r00, r01, r02 = 1.0 - 2.0 * (qy * qy + qz * qz), 2.0 * (qx * qy - w * qz), 2.0 * (qx * qz + w * qy)
        r10, r11, r12 = 2.0 * (qx * qy + w * qz), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz - w * qx)
        r20, r21, r22 = 2.0 * (qx * qz - w * qy), 2.0 * (qy * qz + w * qx), 1.0 - 2.0 * (qx * qx + qy * qy)
        m = p.mass_kg
        ax, ay, az = self._wind
        rx, ry, rz = self._vx - ax, self._vy - ay, self._vz - az
        k_drag = (p.drag_lin + p.drag_quad * math.sqrt(rx * rx + ry * ry + rz * rz)) / m
        dx, dy, dz = -k_drag * rx, -k_drag * ry, -k_drag * rz  # drag's acceleration, NED
        t_m = total / m
        acc_n = dx - t_m * r02
        acc_e = dy - t_m * r12
        acc_d = dz - t_m * r22 + GRAVITY
        if self.on_ground:
            if acc_d >= 0.0:  # the ground holds it still, and levels it, until the rotors lift it
                return self._rest(dt)
            self.on_ground = False
        # Rigid body: Euler's equations with a diagonal inertia, then rates, attitude, velocity, position.
        ix, iy, iz = p.inertia_kgm2
        c = p.angular_damping
        wp, wq, wr = self._wp, self._wq, self._wr
        wp += (tau_x - c * wp - (iz - iy) * wq * wr) / ix * dt
        wq += (tau_y - c * wq - (ix - iz) * wr * wp) / iy * dt
        wr += (tau_z - c * wr - (iy - ix) * wp * wq) / iz * dt
        self._wp, self._wq, self._wr = wp, wq, wr
        rate = math.sqrt(wp * wp + wq * wq + wr * wr)
        if rate > 0.0:  # q <- q * exp(omega dt / 2), then renormalised
            half = 0.5 * rate * dt
            s = math.sin(half) / rate
            bw, bx, by, bz = math.cos(half), wp * s, wq * s, wr * s
            w, qx, qy, qz = (w * bw - qx * bx - qy * by - qz * bz, w * bx + qx * bw + qy * bz - qz * by,
                             w * by - qx * bz + qy * bw + qz * bx, w * bz + qx * by - qy * bx + qz * bw)
            n = 1.0 / math.sqrt(w * w + qx * qx + qy * qy + qz * qz)
            self._qw, self._qx, self._qy, self._qz = w * n, qx * n, qy * n, qz * n
        self._vx += acc_n * dt
        self._vy += acc_e * dt
        self._vz += acc_d * dt
        self._px += self._vx * dt
        self._py += self._vy * dt
        self._pz += self._vz * dt
        if self._pz >= 0.0:  # touchdown
            if self._vz > p.crash_speed_mps:
                self.crashed = True
                log.info("%s crashed: touched down at %.1f m/s (crash speed %.1f)", p.name, self._vz,
                         p.crash_speed_mps)
            # the ground takes the whole velocity out within this step, and the accelerometer feels its
            # push with the thrust and drag: an estimator that integrates it (ArduCopter's EKF) knows the
            # aircraft stopped. A plain 1 g at rest instead left ArduCopter's EKF sinking at 0.3-0.5 m/s
            # for 3 s after contact, and its landing late by as much.
            dx, dy, dz = dx - self._vx / dt, dy - self._vy / dt, dz - self._vz / dt
            self.on_ground = True
            self._vx = self._vy = self._vz = self._pz = 0.0
            self._wp = self._wq = self._wr = 0.0  # the feet stop it turning; levelling starts next step
        # Specific force in FRD: thrust along -z plus the drag turned into the body (R transposed).
        return (r00 * dx + r10 * dy + r20 * dz, r01 * dx + r11 * dy + r21 * dz, r02 * dx + r12 * dy + r22 * dz - t_m)

    def _rest(self, dt: float) -> tuple[float, float, float]:
        """Still on the ground at its heading, a tilted body tipping back level onto its feet at up to
        :data:`SETTLE_RATE_RPS` (the gyro sees it turn); returns the accelerometer's reading, the ground
        holding it up against gravity.

        Levelled within one step instead, a body that touched down leaning into a wind turned by 15 deg
        unseen by the gyro: ArduCopter's EKF kept the lean, read gravity as a horizontal acceleration,
        slid its estimate a metre over the ground and took 12 s instead of 2 to call the landing."""
        self._vx = self._vy = self._vz = 0.0
        self._pz = 0.0
        roll, pitch, yaw = self.euler_ned()
        tilt = math.hypot(roll, pitch)
        if tilt == 0.0:  # level: nothing to turn (every step of a body standing on the ground)
            self._wp = self._wq = self._wr = 0.0
            return 0.0, 0.0, -GRAVITY
        k = 1.0 if tilt <= SETTLE_RATE_RPS * dt else SETTLE_RATE_RPS * dt / tilt  # the tilt's share undone now
        d_roll, d_pitch = -roll * k, -pitch * k
        self._wp, self._wq, self._wr = (d_roll / dt, d_pitch * math.cos(roll) / dt, -d_pitch * math.sin(roll) / dt)
        roll, pitch = roll + d_roll, pitch + d_pitch
        cr, sr = math.cos(roll / 2.0), math.sin(roll / 2.0)
        cp, sp = math.cos(pitch / 2.0), math.sin(pitch / 2.0)
        cy, sy = math.cos(yaw / 2.0), math.sin(yaw / 2.0)
        self._qw, self._qx = cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy
        self._qy, self._qz = cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy
        return (GRAVITY * math.sin(pitch), -GRAVITY * math.sin(roll) * math.cos(pitch),
                -GRAVITY * math.cos(roll) * math.cos(pitch))
