"""The command envelope: where a set-point may send the aircraft, checked before it leaves.

Every GUIDED target the link sends passes through here first: it must be finite, within
``max_distance_m`` of home, between ``min_alt_m`` and ``max_alt_m`` above home, and no faster than
``max_speed_mps``. A radar report of a track at ten thousand kilometres, a corrupt home, a NaN
from a filter: each would otherwise become a target the autopilot flies until its own fence (if
any) stops it. A set-point outside is not sent; the link raises :class:`UnsafeCommand`, the leaf
fails with the reason and the hold of its exit takes over. The autopilot's own fence stays the
last line; this is the one before it, on the ground station's side, and once the vehicle's FENCE_*
parameters are read it never reaches past that fence (:meth:`CommandEnvelope.within_fence`): a
set-point the autopilot would answer with a fence breach (RTL) is refused before it is sent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping, Sequence

from chaser_bt.vehicle.errors import VehicleError

__all__ = ["CommandEnvelope", "FENCE_PARAMS", "UnsafeCommand"]

#: The ArduCopter parameters that say where its fence is (AC_Fence; FENCE_TYPE bits: 1 maximum
#: altitude, 2 circle around home, 4 polygon, 8 minimum altitude).
FENCE_PARAMS = ("FENCE_ENABLE", "FENCE_TYPE", "FENCE_RADIUS", "FENCE_ALT_MAX", "FENCE_ALT_MIN", "FENCE_MARGIN")
_ALT_MAX, _CIRCLE, _ALT_MIN = 1, 2, 8


class UnsafeCommand(VehicleError):
    """A set-point outside the command envelope (or not finite): it was not sent."""


@dataclass(frozen=True)
class CommandEnvelope:
    """Limits on every set-point, relative to the vehicle's home (m, m/s)."""

    max_distance_m: float = 2000.0  # horizontal distance from home
    min_alt_m: float = -20.0  # above home: a target a little under home (a field lower than the take-off) is fine
    max_alt_m: float = 500.0
    max_speed_mps: float = 30.0  # any commanded horizontal or vertical speed

    def __post_init__(self) -> None:
        for name in ("max_distance_m", "max_alt_m", "max_speed_mps"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"CommandEnvelope.{name} = {value}: expected a finite number > 0")
        if not (math.isfinite(self.min_alt_m) and self.min_alt_m < self.max_alt_m):
            raise ValueError(f"CommandEnvelope.min_alt_m = {self.min_alt_m}: expected finite and below max_alt_m")

    def within_fence(self, params: Mapping[str, float]) -> CommandEnvelope:
        """This envelope cut down to the vehicle's enabled fence, ``FENCE_MARGIN`` inside it (the circle
        and the altitudes; a polygon is not read). Unchanged while the fence is off, its parameters
        are not all known, or they describe no usable space (the pre-flight check reports that)."""
        if any(name not in params for name in FENCE_PARAMS) or not params["FENCE_ENABLE"]:
            return self
        kind, margin = int(params["FENCE_TYPE"]), max(0.0, float(params["FENCE_MARGIN"]))
        out = self
        if kind & _CIRCLE and params["FENCE_RADIUS"] - margin > 0:
            out = replace(out, max_distance_m=min(out.max_distance_m, params["FENCE_RADIUS"] - margin))
        top = min(out.max_alt_m, params["FENCE_ALT_MAX"] - margin) if kind & _ALT_MAX else out.max_alt_m
        bottom = max(out.min_alt_m, params["FENCE_ALT_MIN"] + margin) if kind & _ALT_MIN else out.min_alt_m
        if top > 0 and bottom < top:
            out = replace(out, max_alt_m=top, min_alt_m=bottom)
        return out

    def check_position(self, east_m: float, north_m: float, alt_above_home_m: float) -> None:
        """Raise :class:`UnsafeCommand` unless a target ``east_m``/``north_m`` from home at
        ``alt_above_home_m`` is inside the envelope."""
        if not all(math.isfinite(v) for v in (east_m, north_m, alt_above_home_m)):
            raise UnsafeCommand(f"position target not finite: {east_m}, {north_m}, {alt_above_home_m}")
        distance = math.hypot(east_m, north_m)
        if distance > self.max_distance_m:
            raise UnsafeCommand(f"position target {distance:.0f} m from home, beyond the envelope's "
                                f"{self.max_distance_m:g} m")
        if not self.min_alt_m <= alt_above_home_m <= self.max_alt_m:
            raise UnsafeCommand(f"position target {alt_above_home_m:.0f} m above home, outside the envelope's "
                                f"{self.min_alt_m:g}..{self.max_alt_m:g} m")

    def check_altitude(self, alt_above_home_m: float) -> None:
        """Raise :class:`UnsafeCommand` unless ``alt_above_home_m`` is within the envelope's heights."""
        if not (math.isfinite(alt_above_home_m) and self.min_alt_m <= alt_above_home_m <= self.max_alt_m):
            raise UnsafeCommand(f"altitude {alt_above_home_m} m above home outside the envelope's "
                                f"{self.min_alt_m:g}..{self.max_alt_m:g} m")

    def check_velocity(self, velocity_enu: Sequence[float], yaw_rate: float | None = None) -> None:
        """Raise :class:`UnsafeCommand` unless the velocity (and yaw rate) are finite and within the speed limit."""
        values = [float(v) for v in velocity_enu] + ([] if yaw_rate is None else [float(yaw_rate)])
        if len(velocity_enu) != 3 or not all(math.isfinite(v) for v in values):
            raise UnsafeCommand(f"velocity target not finite: {list(velocity_enu)}, yaw rate {yaw_rate}")
        horizontal, vertical = math.hypot(values[0], values[1]), abs(values[2])
        if max(horizontal, vertical) > self.max_speed_mps:
            raise UnsafeCommand(f"velocity target {horizontal:.1f} m/s across, {vertical:.1f} m/s up or down, "
                                f"beyond the envelope's {self.max_speed_mps:g} m/s")

    def check_speed(self, speed_mps: float) -> None:
        """Raise :class:`UnsafeCommand` unless a speed setting is finite, positive and within the limit."""
        if not (math.isfinite(speed_mps) and 0 < speed_mps <= self.max_speed_mps):
            raise UnsafeCommand(f"speed {speed_mps} m/s outside the envelope's (0, {self.max_speed_mps:g}] m/s")
