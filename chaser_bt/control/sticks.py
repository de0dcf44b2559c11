"""ArduCopter's stick mapping in ALT_HOLD, inverted: wanted lean, climb and yaw rate -> RC PWM.

The paper flew its follow controller through ALT_HOLD (section 3.2), where the autopilot turns the
sticks into lean angles, a climb rate and a yaw rate. Sending RC_CHANNELS_OVERRIDE therefore means
inverting ArduCopter's own mapping (``RC_Channel::norm_input_dz``, ``get_pilot_desired_lean_angles``,
``get_pilot_desired_climb_rate``, ``get_pilot_desired_yaw_rate``), with the vehicle's parameters:

- roll/pitch: ``(pwm - (1500 ± DZ)) / (500 - DZ)`` of ``ANGLE_MAX``; stick high = roll right /
  nose up (so flying forward is pitch PWM below 1500: 1300 is about -11 deg with the defaults);
- throttle: mid-stick ± ``THR_DZ`` holds altitude; above climbs up to ``PILOT_SPEED_UP``, below
  descends up to ``PILOT_SPEED_DN`` (0 = the same as up);
- yaw: ``norm * PILOT_Y_RATE``; stick high turns clockwise seen from above.

Angles are MAVLink's (roll right and pitch up positive); the yaw rate given here is ENU
(counter-clockwise positive), converted to the stick's clockwise sense inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["CENTRED", "StickMap", "RcSticks"]

GRAVITY = 9.80665


@dataclass(frozen=True)
class RcSticks:
    """PWM of RC channels 1-4 (roll, pitch, throttle, yaw)."""

    roll: int
    pitch: int
    throttle: int
    yaw: int

    def as_tuple(self) -> tuple[int, int, int, int]:
        return (self.roll, self.pitch, self.throttle, self.yaw)


CENTRED = RcSticks(1500, 1500, 1500, 1500)


@dataclass(frozen=True)
class StickMap:
    """The vehicle parameters the mapping depends on (ArduCopter's defaults, SI units)."""

    angle_max_rad: float = math.radians(30.0)  # ANGLE_MAX 3000 cdeg
    yaw_rate_max: float = math.radians(202.5)  # PILOT_Y_RATE deg/s
    climb_up_max: float = 2.5  # PILOT_SPEED_UP cm/s / 100
    climb_down_max: float = 2.5  # PILOT_SPEED_DN (0 = PILOT_SPEED_UP)
    roll_dz: float = 20.0  # RC1_DZ
    pitch_dz: float = 20.0  # RC2_DZ
    thr_dz: float = 100.0  # THR_DZ
    yaw_dz: float = 20.0  # RC4_DZ
    climb_deadband_mps: float = 0.05  # smaller climb demands centre the stick (no chatter across THR_DZ)

    @classmethod
    def from_params(cls, params: dict[str, float]) -> StickMap:
        """Build from ArduCopter parameter values (missing ones keep the defaults)."""
        d = cls()
        # ArduCopter 4.7 renamed three of them, in SI units: ATC_ANGLE_MAX (deg), PILOT_SPD_UP/DN (m/s).
        up = params["PILOT_SPD_UP"] if "PILOT_SPD_UP" in params else params.get("PILOT_SPEED_UP", d.climb_up_max * 100.0) * 0.01
        dn = (params["PILOT_SPD_DN"] if "PILOT_SPD_DN" in params else params.get("PILOT_SPEED_DN", 0.0) * 0.01) or up
        angle_deg = params["ATC_ANGLE_MAX"] if "ATC_ANGLE_MAX" in params else params.get(
            "ANGLE_MAX", math.degrees(d.angle_max_rad) * 100.0) * 0.01
        return cls(
            angle_max_rad=math.radians(angle_deg),
            yaw_rate_max=math.radians(params.get("PILOT_Y_RATE", math.degrees(d.yaw_rate_max))),
            climb_up_max=up, climb_down_max=dn,
            roll_dz=params.get("RC1_DZ", d.roll_dz), pitch_dz=params.get("RC2_DZ", d.pitch_dz),
            thr_dz=params.get("THR_DZ", d.thr_dz), yaw_dz=params.get("RC4_DZ", d.yaw_dz),
        )

    # -- inverse of norm_input_dz --------------------------------------------------------------
    @staticmethod
    def _pwm(norm: float, dz: float) -> int:
        norm = min(max(norm, -1.0), 1.0)
        if norm > 0.0:
            return round(1500.0 + dz + norm * (500.0 - dz))
        if norm < 0.0:
            return round(1500.0 - dz + norm * (500.0 - dz))
        return 1500

    def lean_pwm(self, roll_rad: float, pitch_rad: float) -> tuple[int, int]:
        """Roll and pitch PWM for lean angles (roll right, pitch nose-up positive), within ANGLE_MAX."""
        total = math.hypot(roll_rad, pitch_rad)
        if total > self.angle_max_rad:
            roll_rad, pitch_rad = roll_rad * self.angle_max_rad / total, pitch_rad * self.angle_max_rad / total
        return (self._pwm(roll_rad / self.angle_max_rad, self.roll_dz),
                self._pwm(pitch_rad / self.angle_max_rad, self.pitch_dz))

    def throttle_pwm(self, climb_mps: float) -> int:
        """Throttle PWM for a climb rate (m/s, negative descends); 1500 holds altitude.

        Outside ``climb_deadband_mps`` the stick leaves THR_DZ, so the smallest demand already moves it
        past the deadzone edge; inside it the stick is centred.
        """
        top, bottom = 500.0 + self.thr_dz, 500.0 - self.thr_dz
        if abs(climb_mps) < self.climb_deadband_mps:
            thr = 500.0
        elif climb_mps > 0.0:
            thr = top + min(climb_mps / self.climb_up_max, 1.0) * (1000.0 - top)
        elif climb_mps < 0.0:
            thr = bottom + max(climb_mps / self.climb_down_max, -1.0) * bottom
        else:
            thr = 500.0
        return round(1000.0 + thr)

    def yaw_pwm(self, yaw_rate_enu: float) -> int:
        """Yaw PWM for an ENU yaw rate (rad/s, counter-clockwise positive)."""
        return self._pwm(-yaw_rate_enu / self.yaw_rate_max, self.yaw_dz)

    def sticks(self, *, forward_accel: float, right_accel: float, climb_mps: float, yaw_rate_enu: float) -> RcSticks:
        """All four sticks from body-frame horizontal accelerations (m/s^2), climb and yaw rate.

        The accelerations become lean angles as ArduPilot's ``accel_to_lean_angles`` does.
        """
        pitch = math.atan(-forward_accel / GRAVITY)
        roll = math.atan(right_accel * math.cos(pitch) / GRAVITY)
        r, p = self.lean_pwm(roll, pitch)
        return RcSticks(r, p, self.throttle_pwm(climb_mps), self.yaw_pwm(yaw_rate_enu))
