"""A discrete PID loop with output limits and anti-windup (paper section 3.2, table 1).

The follow controller runs three of these at 5 Hz. Time is passed in (``dt``), never read. The
derivative acts on the error's change between updates (the process variable is median-filtered
before it gets here, so the difference is not dominated by noise); the first update after a reset
has no derivative. Anti-windup is conditional integration: the integral does not grow while the
output is saturated in the direction the error pushes it, and it is clamped to ``i_limit`` (the
largest output share the integral may carry).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["PidGains", "Pid"]


@dataclass(frozen=True)
class PidGains:
    """Gains and limits of one loop (output units per error unit; ``kd`` per error unit per second).

    Args:
        kp, ki, kd: proportional, integral (per second) and derivative (seconds) gains.
        out_min, out_max: output saturation.
        i_limit: the integral term's magnitude never exceeds this (output units).
    """

    kp: float
    ki: float = 0.0
    kd: float = 0.0
    out_min: float = -math.inf
    out_max: float = math.inf
    i_limit: float = math.inf

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "kd", "i_limit"):
            v = getattr(self, name)
            if not (v >= 0.0) or math.isnan(v):
                raise ValueError(f"PID {name} must be >= 0, got {v}")
        if not self.out_min < self.out_max:
            raise ValueError(f"PID out_min ({self.out_min}) must be below out_max ({self.out_max})")


class Pid:
    """``u = kp e + ki ∫e dt + kd de/dt``, saturated, with conditional integration."""

    def __init__(self, gains: PidGains) -> None:
        self.gains = gains
        self.integral = 0.0  # the integral term's value (output units, ki already applied)
        self._last_error: float | None = None
        self.last_output = 0.0

    def reset(self) -> None:
        """Forget the integral and the last error (a new engagement)."""
        self.integral = 0.0
        self._last_error = None
        self.last_output = 0.0

    def update(self, error: float, dt: float, *, kd: float | None = None, feed_forward: float = 0.0,
               error_rate: float | None = None) -> float:
        """One step: the saturated output for ``error`` after ``dt`` seconds.

        Args:
            error: set-point minus process variable (or the sign convention the caller chose).
            dt: seconds since the last update (> 0).
            kd: this step's derivative gain when it varies (the yaw loop's K_D = 0.0003 R).
            feed_forward: added to the output before saturation (velocity feed-forward).
            error_rate: the error's rate of change when it is measured (e.g. from velocities)
                rather than differenced; used for the derivative term instead.
        """
        if not dt > 0.0:
            raise ValueError(f"PID dt must be > 0, got {dt}")
        g = self.gains
        kd = g.kd if kd is None else kd
        if error_rate is not None:
            derivative = error_rate
        else:
            derivative = 0.0 if self._last_error is None else (error - self._last_error) / dt
        self._last_error = error
        unsat = g.kp * error + self.integral + kd * derivative + feed_forward
        candidate = min(max(self.integral + g.ki * error * dt, -g.i_limit), g.i_limit)
        # Conditional integration: integrate only if not pushing further into saturation.
        pushing_up = unsat >= g.out_max and error > 0.0
        pushing_down = unsat <= g.out_min and error < 0.0
        if not (pushing_up or pushing_down):
            self.integral = candidate
        out = g.kp * error + self.integral + kd * derivative + feed_forward
        self.last_output = min(max(out, g.out_min), g.out_max)
        return self.last_output
