"""A motor-level quadcopter ("+" frame) for ArduPilot's JSON physics backend: PWM in, IMU out.

Where :mod:`sitl.vehicle.physics` models what a flight controller's *outer* loops see (a lagged
attitude), an autopilot flying its own attitude loops needs the rotors: each motor's thrust
follows its PWM through a first-order spin-up lag and ArduPilot's thrust curve
(``MOT_THST_EXPO``: thrust ~ (1 - e) u + e u²), the arms turn thrust differences into roll and
pitch torques, the props' drag into a yaw torque, and a rigid body with a diagonal inertia
integrates them. Linear drag, a flat ground at home (it stops the fall and holds the copter level
while the thrust is below its weight), no wind yet.

Motor order and spin are ArduPilot's QUAD "+" (``AP_MotorsMatrix``): 1 right and 2 left spin
counter-clockwise, 3 front and 4 back clockwise. Frames are ArduPilot's: NED earth, FRD body.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from sitl.vehicle.airframe import GRAVITY
from sitl.vehicle.json_backend import SensorFrame, ServoPacket

__all__ = ["QuadParams", "QuadRotorBody"]

# Quad "+": (forward, right) arm position in arm lengths, yaw factor (+1 counter-clockwise prop).
_PLUS = ((0.0, 1.0, 1.0), (0.0, -1.0, 1.0), (1.0, 0.0, -1.0), (-1.0, 0.0, -1.0))


@dataclass(frozen=True)
class QuadParams:
    """A 1.5 kg quad that hovers near 40 % throttle (ArduCopter's MOT_THST_HOVER learns it)."""

    mass_kg: float = 1.5
    arm_m: float = 0.25
    inertia_kgm2: tuple[float, float, float] = (0.015, 0.015, 0.03)
    max_thrust_n: float = 15.0  # per motor at full PWM
    thrust_expo: float = 0.65  # MOT_THST_EXPO's default
    yaw_torque_per_n: float = 0.02  # prop drag torque per newton of thrust (m)
    motor_tau_s: float = 0.02
    pwm_min: int = 1000
    pwm_max: int = 2000
    drag_per_mps: float = 0.25  # N per m/s, linear
    angular_damping: float = 0.02  # N m per rad/s


@dataclass
class QuadRotorBody:
    """The state and its step; ``physics(packet, t)`` is the :class:`~sitl.vehicle.json_backend.JsonPhysicsServer` callable."""

    params: QuadParams = field(default_factory=QuadParams)
    position_ned: np.ndarray = field(default_factory=lambda: np.zeros(3))
    velocity_ned: np.ndarray = field(default_factory=lambda: np.zeros(3))
    attitude: Rotation = field(default_factory=Rotation.identity)  # FRD body -> NED
    rates_frd: np.ndarray = field(default_factory=lambda: np.zeros(3))
    thrust_n: np.ndarray = field(default_factory=lambda: np.zeros(4))

    def physics(self, packet: ServoPacket, t_s: float) -> SensorFrame:
        """Step by ``packet.dt_s`` under its first four PWMs; what the IMU and GPS feel after it."""
        specific_force = self.step(packet.pwm_us[:4], packet.dt_s)
        roll, pitch, yaw = self.attitude.as_euler("ZYX")[::-1]
        return SensorFrame(t_s, tuple(self.rates_frd), tuple(specific_force), tuple(self.position_ned),
                           tuple(self.velocity_ned), (float(roll), float(pitch), float(yaw)))

    def step(self, pwm_us, dt: float) -> np.ndarray:
        """Advance by ``dt``; returns the specific force in FRD (what the accelerometer reads)."""
        p = self.params
        u = np.clip((np.asarray(pwm_us, float) - p.pwm_min) / (p.pwm_max - p.pwm_min), 0.0, 1.0)
        target = p.max_thrust_n * ((1.0 - p.thrust_expo) * u + p.thrust_expo * u * u)
        self.thrust_n = target + (self.thrust_n - target) * math.exp(-dt / p.motor_tau_s)
        torque = np.zeros(3)
        for (fwd, right, spin), thrust in zip(_PLUS, self.thrust_n):
            torque += (-right * p.arm_m * thrust, fwd * p.arm_m * thrust, spin * p.yaw_torque_per_n * thrust)
        inertia = np.asarray(p.inertia_kgm2)
        w = self.rates_frd
        w_dot = (torque - p.angular_damping * w - np.cross(w, inertia * w)) / inertia
        force_body = np.array([0.0, 0.0, -float(self.thrust_n.sum())])
        force_ned = self.attitude.apply(force_body) - p.drag_per_mps * self.velocity_ned
        accel_ned = force_ned / p.mass_kg + (0.0, 0.0, GRAVITY)
        on_ground = self.position_ned[2] >= 0.0 and accel_ned[2] >= 0.0
        if on_ground:  # the ground holds it level and still until the rotors lift it
            yaw = self.attitude.as_euler("ZYX")[0]
            self.attitude = Rotation.from_euler("ZYX", (yaw, 0.0, 0.0))
            self.rates_frd = np.zeros(3)
            self.velocity_ned = np.zeros(3)
            self.position_ned[2] = 0.0
            return np.array([0.0, 0.0, -GRAVITY])
        self.rates_frd = w + w_dot * dt
        self.attitude = self.attitude * Rotation.from_rotvec(self.rates_frd * dt)
        self.velocity_ned = self.velocity_ned + accel_ned * dt
        self.position_ned = self.position_ned + self.velocity_ned * dt
        return self.attitude.inv().apply(force_ned / p.mass_kg)
