"""What the simulated vehicle is started with, besides its airframe and parameters: how long it
takes to boot, the faults that strike it, and the people around it (the safety pilot's switch, the
operator's ground station).

A scenario (:mod:`sitl.world.scenario`) reads these from YAML; the vehicle sees them only through
:class:`VehicleSetup`, so the aircraft knows nothing of the world file it was described in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from chaser_bt.geo import GeoPoint
from sitl.vehicle.airframe import AirframeParams
from sitl.vehicle.physics import WindParams

__all__ = ["BootParams", "Fault", "FAULT_KINDS", "GCS_MODES", "GroundStationEvent", "PilotEvent", "PilotScript",
           "VehicleSetup"]

FAULT_KINDS = ("link_loss", "gps_loss", "battery_drop", "disarm", "rc_loss")

#: Modes a scripted ground station can command (the simulated ArduCopter's, by mode number).
GCS_MODES = {"STABILIZE": 0, "ALT_HOLD": 2, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9, "BRAKE": 17}


@dataclass(frozen=True)
class BootParams:
    """Seconds after boot at which the readiness flags come up (DESIGN §5: ~40 s in SITL).

    Attributes:
        gps_fix_s: 3-D GPS fix.
        ekf_ready_s: EKF absolute position estimate.
        prearm_ok_s: all pre-arm checks pass (SYS_STATUS pre-arm health bit).
    """

    gps_fix_s: float = 5.0
    ekf_ready_s: float = 25.0
    prearm_ok_s: float = 40.0


@dataclass(frozen=True)
class Fault:
    """A scripted fault: ``kind`` starts at ``at_s`` (sim time) for ``duration_s`` (None = for good).

    Kinds: ``link_loss`` (the MAVLink radio goes silent; applied by the endpoint), ``gps_loss``
    (no fix, the EKF loses its position), ``battery_drop`` (a failing cell: the pack voltage
    drops by one cell's worth), ``disarm`` (a forced disarm at ``at_s``; the duration is ignored),
    ``rc_loss`` (the RC receiver hears nothing: the radio failsafe after RC_FS_TIMEOUT).
    """

    at_s: float
    kind: str
    duration_s: float | None = None

    def active(self, t: float) -> bool:
        """Whether the fault is in force at sim time ``t``."""
        if t < self.at_s:
            return False
        return self.duration_s is None or t < self.at_s + self.duration_s


@dataclass(frozen=True)
class PilotEvent:
    """The pilot moves the autonomy switch at sim time ``at_s``: ``gate`` True = on (high)."""

    at_s: float
    gate: bool


@dataclass(frozen=True)
class PilotScript:
    """The safety pilot's transmitter: an autonomy switch on ``gate_channel``, scripted over time.

    The switch reads ``on_pwm`` when on and ``off_pwm`` when off (ArduPilot counts a switch above
    1800 as high and below 1200 as low); it starts at ``gate`` and follows ``events`` in time order.
    The pilot stands by with every stick centred, the throttle too (so a mode that reads the
    sticks, such as LOITER after a hand-back, holds altitude); other channels read 1500.
    """

    gate_channel: int = 7
    gate: bool = True
    on_pwm: int = 1900
    off_pwm: int = 1100
    events: tuple[PilotEvent, ...] = ()

    def gate_at(self, t: float) -> bool:
        """The switch position at sim time ``t``."""
        on = self.gate
        for ev in self.events:
            if ev.at_s > t:
                break
            on = ev.gate
        return on

    def gate_pwm(self, t: float) -> int:
        """The switch channel's PWM at sim time ``t``."""
        return self.on_pwm if self.gate_at(t) else self.off_pwm


@dataclass(frozen=True)
class GroundStationEvent:
    """Another ground station (the operator's) sets flight ``mode`` at sim time ``at_s``."""

    at_s: float
    mode: str


class VehicleSetup(Protocol):
    """Everything an :class:`~sitl.vehicle.autopilot.Autopilot` is started with (a scenario is one)."""

    home: GeoPoint
    home_heading_deg: float
    wind: WindParams
    airframe: AirframeParams
    params: dict[str, float]
    boot: BootParams
    faults: tuple[Fault, ...]
    pilot: PilotScript | None
    ground_station: tuple[GroundStationEvent, ...]
