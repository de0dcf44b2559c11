"""Telemetry is checked before it is believed: values no aircraft reports are dropped and counted.

A corrupt autopilot, bytes that happen to pass the CRC, or a spoof that reuses the vehicle's ids can
carry what no small multirotor reports: NaN, a zero quaternion, a latitude past the pole, a home two
thousand kilometres under the sea. Believed, one such message turns every later GUIDED target into
nonsense or raises inside the tick. :class:`TelemetryGate` checks each message the vehicle state
is built from against physical limits (:class:`TelemetryLimits`), counts what it drops per reason,
and turns a flood of them into a fault the link puts where the tree's guards see it
(``VehicleState.telemetry_fault``).

Home is a special case: ArduCopter sets it at boot and again where it arms, a few metres apart. A
home that moves further is a fault, not a new truth: the first one stays.
"""

from __future__ import annotations

import logging
import math
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any

from chaser_bt.geo import LocalFrame

__all__ = ["TelemetryGate", "TelemetryLimits", "telemetry_problem"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TelemetryLimits:
    """What a small multirotor can report (SI units)."""

    max_speed_mps: float = 150.0  # any velocity component
    min_alt_amsl_m: float = -1000.0  # the Dead Sea shore is at -430 m
    max_alt_amsl_m: float = 12000.0
    max_rel_alt_m: float = 10000.0  # |altitude above home|
    max_home_shift_m: float = 50.0  # horizontal move of home between reports (boot vs arming position)
    max_home_climb_m: float = 30.0  # vertical move of home between reports
    max_battery_v: float = 100.0
    flood_window_s: float = 2.0  # a flood: at least flood_min drops, half the messages or more, in this window
    flood_min: int = 10


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def _attitude(m: Any, state: Any, lim: TelemetryLimits) -> tuple[str, str] | None:
    values = (m.roll, m.pitch, m.yaw, m.rollspeed, m.pitchspeed, m.yawspeed)
    if not _finite(*values):
        return "non_finite", f"ATTITUDE {values}"
    if abs(m.roll) > math.pi + 1e-3 or abs(m.pitch) > math.pi / 2 + 1e-3 or abs(m.yaw) > 2 * math.pi + 1e-3:
        return "attitude_range", f"ATTITUDE roll {m.roll:g} pitch {m.pitch:g} yaw {m.yaw:g} rad"
    return None


def _attitude_quaternion(m: Any, state: Any, lim: TelemetryLimits) -> tuple[str, str] | None:
    q = (m.q1, m.q2, m.q3, m.q4)
    if not _finite(*q):
        return "non_finite", f"ATTITUDE_QUATERNION {q}"
    norm = math.sqrt(sum(x * x for x in q))
    if not 0.9 <= norm <= 1.1:  # ArduPilot sends unit quaternions; a zero one has no rotation at all
        return "quaternion_norm", f"ATTITUDE_QUATERNION norm {norm:.3g}"
    return None


def _global_position(m: Any, state: Any, lim: TelemetryLimits) -> tuple[str, str] | None:
    lat, lon, alt, rel = m.lat * 1e-7, m.lon * 1e-7, m.alt * 1e-3, m.relative_alt * 1e-3
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        return "position_range", f"GLOBAL_POSITION_INT lat {lat:g} lon {lon:g}"
    if not (lim.min_alt_amsl_m <= alt <= lim.max_alt_amsl_m and abs(rel) <= lim.max_rel_alt_m):
        return "position_range", f"GLOBAL_POSITION_INT alt {alt:g} m amsl, {rel:g} m above home"
    if max(abs(m.vx), abs(m.vy), abs(m.vz)) * 0.01 > lim.max_speed_mps:
        return "speed_range", f"GLOBAL_POSITION_INT velocity {m.vx / 100:g}, {m.vy / 100:g}, {m.vz / 100:g} m/s"
    return None


def _home_position(m: Any, state: Any, lim: TelemetryLimits) -> tuple[str, str] | None:
    lat, lon, alt = m.latitude * 1e-7, m.longitude * 1e-7, m.altitude * 1e-3
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and lim.min_alt_amsl_m <= alt <= lim.max_alt_amsl_m):
        return "home_range", f"HOME_POSITION lat {lat:g} lon {lon:g} alt {alt:g} m"
    if state.home is not None:
        east, north, up = LocalFrame(state.home).to_enu(lat, lon, alt)
        moved = math.hypot(east, north)
        if moved > lim.max_home_shift_m or abs(up) > lim.max_home_climb_m:
            return "home_jump", f"HOME_POSITION moved {moved:.0f} m across and {up:+.0f} m up"
    return None


def _sys_status(m: Any, state: Any, lim: TelemetryLimits) -> tuple[str, str] | None:
    volts = m.voltage_battery * 1e-3
    if m.voltage_battery != 65535 and volts > lim.max_battery_v:
        return "battery_range", f"SYS_STATUS voltage {volts:g} V"
    if not -1 <= m.battery_remaining <= 100:
        return "battery_range", f"SYS_STATUS battery_remaining {m.battery_remaining}"
    return None


def _battery_status(m: Any, state: Any, lim: TelemetryLimits) -> tuple[str, str] | None:
    if not -1 <= m.battery_remaining <= 100:
        return "battery_range", f"BATTERY_STATUS battery_remaining {m.battery_remaining}"
    return None


_CHECKS = {
    "ATTITUDE": _attitude,
    "ATTITUDE_QUATERNION": _attitude_quaternion,
    "GLOBAL_POSITION_INT": _global_position,
    "HOME_POSITION": _home_position,
    "SYS_STATUS": _sys_status,
    "BATTERY_STATUS": _battery_status,
}


def telemetry_problem(msg: Any, state: Any, limits: TelemetryLimits = TelemetryLimits()) -> tuple[str, str] | None:
    """Why ``msg`` cannot be believed given ``state`` (the vehicle state so far): ``(reason, detail)``,
    or None when it can. Reasons: non_finite, attitude_range, quaternion_norm, position_range,
    speed_range, home_range, home_jump, battery_range."""
    check = _CHECKS.get(msg.get_type())
    return None if check is None else check(msg, state, limits)


@dataclass
class TelemetryGate:
    """Checks each vehicle message; counts drops per reason; a flood of drops is a fault.

    ``admit(msg, state, now)`` returns whether to apply ``msg`` to ``state``. The counts live on the
    vehicle state (``state.telemetry_rejected``), so the tree sees them on ``/vehicle/state``; the
    log has each reason's first drop and every hundredth. :attr:`fault` is '' unless at least
    ``flood_min`` drops made half or more of the messages within ``flood_window_s``.
    """

    limits: TelemetryLimits = field(default_factory=TelemetryLimits)
    fault: str = field(default="", init=False)
    _recent: deque[tuple[float, bool]] = field(default_factory=deque, init=False, repr=False)
    _recent_dropped: int = field(default=0, init=False)  # drops in _recent, kept as it changes

    def admit(self, msg: Any, state: Any, now: float) -> bool:
        problem = telemetry_problem(msg, state, self.limits)
        self._recent.append((now, problem is not None))
        self._recent_dropped += problem is not None
        while self._recent and self._recent[0][0] < now - self.limits.flood_window_s:
            self._recent_dropped -= self._recent.popleft()[1]
        if problem is not None:
            reason, detail = problem
            counts: Counter[str] = state.telemetry_rejected
            counts[reason] += 1
            if counts[reason] == 1 or counts[reason] % 100 == 0:
                log.warning("telemetry dropped (%s, %d so far): %s", reason, counts[reason], detail)
        self._update_fault(problem)
        return problem is None

    def _update_fault(self, problem: tuple[str, str] | None) -> None:
        dropped = self._recent_dropped
        if dropped >= self.limits.flood_min and 2 * dropped >= len(self._recent):
            if not self.fault:
                self.fault = (f"telemetry cannot be trusted: {dropped} of {len(self._recent)} messages dropped in "
                              f"{self.limits.flood_window_s:g} s" + (f" ({problem[1]})" if problem else ""))
                log.error("%s", self.fault)
        elif self.fault and dropped == 0:
            log.warning("telemetry trusted again (nothing dropped in %g s)", self.limits.flood_window_s)
            self.fault = ""
