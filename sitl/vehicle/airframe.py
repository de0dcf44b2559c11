"""The simulated airframe: mass, thrust, drag, response lags and battery of a multicopter.

Defaults describe a DJI S1000-class octocopter carrying a small payload: 4.4 kg empty, 8 kg
take-off mass, total thrust twice the hover weight, a 10 Ah 6S LiPo good for about 15 minutes
of hover. Every number is overridable from a scenario's ``airframe:`` block.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["GRAVITY", "AirframeParams", "lipo_cell_ocv"]

GRAVITY = 9.80665  # m/s^2, as ArduPilot's GRAVITY_MSS

# Resting (open-circuit) voltage of one LiPo cell against state of charge: the usual flat middle
# between 3.7 and 3.9 V and the knee below 10 %.
_SOC_POINTS = (0.0, 0.05, 0.10, 0.20, 0.30, 0.40, 0.50, 0.60, 0.70, 0.80, 0.90, 1.0)
_CELL_OCV_V = (3.30, 3.55, 3.65, 3.72, 3.76, 3.80, 3.84, 3.88, 3.95, 4.02, 4.10, 4.20)


def lipo_cell_ocv(soc: float) -> float:
    """Open-circuit voltage of one LiPo cell at state of charge ``soc`` (0..1, clipped)."""
    if soc <= 0.0:
        return _CELL_OCV_V[0]
    if soc >= 1.0:
        return _CELL_OCV_V[-1]
    i = 1
    while _SOC_POINTS[i] < soc:
        i += 1
    s0, s1 = _SOC_POINTS[i - 1], _SOC_POINTS[i]
    v0, v1 = _CELL_OCV_V[i - 1], _CELL_OCV_V[i]
    return v0 + (v1 - v0) * (soc - s0) / (s1 - s0)


@dataclass(frozen=True)
class AirframeParams:
    """Physical constants of the simulated multicopter (SI units).

    Attributes:
        mass_kg: take-off mass.
        max_thrust_ratio: maximum total rotor thrust over hover weight.
        idle_thrust_ratio: thrust at armed idle (ArduPilot MOT_SPIN_ARM) over hover weight; below 1,
            so an idling copter stays on the ground.
        attitude_tau_s: time constant of the first-order lag with which roll and pitch follow the
            commanded angles (the closed attitude loop of ArduPilot, ATC_INPUT_TC ~0.15 s).
        yaw_rate_tau_s: time constant with which the yaw rate follows its command.
        motor_tau_s: time constant of the total thrust following its command (rotor spin-up).
        drag_lin_h, drag_quad_h: horizontal drag force = (lin + quad * |v_air|) * v_air, N per m/s.
        drag_lin_v, drag_quad_v: the same along the vertical.
        battery_cells: LiPo cells in series.
        battery_capacity_mah: usable capacity.
        battery_resistance_ohm: pack internal resistance (voltage sag under load).
        hover_current_a: motor current at hover thrust; current scales with thrust^1.5
            (momentum theory: induced power ~ T^1.5).
        avionics_current_a: constant draw of flight controller, radios and payload.
        crash_speed_mps: touching the ground faster than this counts as a crash.
    """

    mass_kg: float = 8.0
    max_thrust_ratio: float = 2.0
    idle_thrust_ratio: float = 0.1
    attitude_tau_s: float = 0.15
    yaw_rate_tau_s: float = 0.1
    motor_tau_s: float = 0.04
    drag_lin_h: float = 0.3
    drag_quad_h: float = 0.12
    drag_lin_v: float = 0.5
    drag_quad_v: float = 0.3
    battery_cells: int = 6
    battery_capacity_mah: float = 10000.0
    battery_resistance_ohm: float = 0.04
    hover_current_a: float = 38.0
    avionics_current_a: float = 1.0
    crash_speed_mps: float = 3.0

    def __post_init__(self) -> None:
        positive = ("mass_kg", "attitude_tau_s", "yaw_rate_tau_s", "motor_tau_s",
                    "battery_capacity_mah", "hover_current_a", "crash_speed_mps")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not self.max_thrust_ratio > 1.0:
            raise ValueError(f"max_thrust_ratio must be > 1 to fly, got {self.max_thrust_ratio}")
        if not 0.0 <= self.idle_thrust_ratio < 1.0:
            raise ValueError(f"idle_thrust_ratio must be in [0, 1), got {self.idle_thrust_ratio}")
        if self.battery_cells < 1:
            raise ValueError(f"battery_cells must be >= 1, got {self.battery_cells}")
        for name in ("drag_lin_h", "drag_quad_h", "drag_lin_v", "drag_quad_v",
                     "battery_resistance_ohm", "avionics_current_a"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")

    @property
    def hover_thrust_n(self) -> float:
        """Thrust that balances the weight."""
        return self.mass_kg * GRAVITY

    @property
    def max_thrust_n(self) -> float:
        """Maximum total rotor thrust."""
        return self.max_thrust_ratio * self.hover_thrust_n

    @property
    def idle_thrust_n(self) -> float:
        """Thrust of armed rotors at idle."""
        return self.idle_thrust_ratio * self.hover_thrust_n

    @property
    def hover_throttle(self) -> float:
        """Throttle (0..1 of max thrust) that hovers: ArduPilot's learned MOT_THST_HOVER."""
        return 1.0 / self.max_thrust_ratio
