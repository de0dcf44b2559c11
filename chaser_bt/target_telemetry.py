"""Target telemetry: the intruder's own MAVLink position, as the paper used it during development.

The paper's follow controller took range from the target's GPS (section 3.1 lists "target
telemetry" as an input; section 5: azimuth and elevation from vision, range from GPS). Here the
target is another MAVLink system on the ground station's connection: its GLOBAL_POSITION_INT
(lat/lon, altitude AMSL, NED velocity) becomes a :class:`~chaser_bt.cue.TargetCue` with
``source="telemetry"`` in the mission's ENU frame.

:class:`TargetTelemetry` listens on a :class:`~chaser_bt.vehicle.VehicleLink` through
``add_listener(on_receive=...)``, which sees every message before the link's own system-id filter
drops those of other systems. The time of a fix is the mission clock at reception (the target's
``time_boot_ms`` is its own clock, not ours). Messages from the vehicle itself are ignored;
malformed or implausible fixes are dropped and counted.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from chaser_bt.cue import TargetCue
from chaser_bt.geo import GeoPoint, LocalFrame

__all__ = ["TargetFix", "TargetTelemetry"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TargetFix:
    """One received target position: where (geodetic), how fast (ENU m/s), when (mission s)."""

    t: float
    sysid: int
    point: GeoPoint
    velocity_enu: np.ndarray


class TargetTelemetry:
    """Latest GLOBAL_POSITION_INT per foreign system id, as target cues.

    Args:
        clock: mission time now (the mission Clock's ``now``), stamped on each fix at reception.
        vehicle_sysid: returns our own vehicle's system id (None until known); its messages are ignored.
        sigma_h_m, sigma_v_m: 1-sigma GPS error for the cue's covariance.
    """

    def __init__(self, clock: Callable[[], float], vehicle_sysid: Callable[[], int | None] = lambda: None,
                 *, sigma_h_m: float = 1.5, sigma_v_m: float = 3.0) -> None:
        self._clock = clock
        self._vehicle_sysid = vehicle_sysid
        self._cov = np.diag([sigma_h_m ** 2, sigma_h_m ** 2, sigma_v_m ** 2])
        self._fixes: dict[int, TargetFix] = {}
        self.dropped = 0  # malformed or implausible fixes
        self.received = 0

    @classmethod
    def attach(cls, link: Any, clock: Callable[[], float], **kwargs: Any) -> TargetTelemetry:
        """A telemetry reader listening on ``link`` (a VehicleLink), skipping the link's own vehicle."""
        tel = cls(clock, lambda: link.target_sysid, **kwargs)
        link.add_listener(on_receive=tel.on_message)
        return tel

    def on_message(self, msg: Any) -> None:
        """Feed one decoded MAVLink message (a link listener: never raises)."""
        try:
            if msg.get_type() != "GLOBAL_POSITION_INT":
                return
            sysid = int(msg.get_srcSystem())
            if sysid == self._vehicle_sysid():
                return
            lat, lon = msg.lat * 1e-7, msg.lon * 1e-7
            alt = msg.alt * 1e-3
            vel = np.array([msg.vy, msg.vx, -msg.vz], float) * 0.01  # NED cm/s -> ENU m/s
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and math.isfinite(alt)) or (lat == 0 and lon == 0):
                self.dropped += 1
                return
            self._fixes[sysid] = TargetFix(float(self._clock()), sysid, GeoPoint(lat, lon, alt), vel)
            self.received += 1
        except Exception:  # a listener must not raise into the link
            self.dropped += 1
            log.debug("dropped a malformed target position", exc_info=True)

    @property
    def systems(self) -> list[int]:
        """System ids heard so far."""
        return sorted(self._fixes)

    def latest_fix(self, sysid: int | None = None) -> TargetFix | None:
        """The newest fix of ``sysid`` (None: of the system heard most recently)."""
        if sysid is not None:
            return self._fixes.get(sysid)
        return max(self._fixes.values(), key=lambda f: f.t, default=None)

    def cue(self, frame: LocalFrame | None, sysid: int | None = None) -> TargetCue | None:
        """The newest fix as an ENU cue in ``frame`` (None without a frame or a fix)."""
        fix = self.latest_fix(sysid)
        if fix is None or frame is None:
            return None
        return TargetCue(t=fix.t, position_enu=frame.point_to_enu(fix.point), covariance_enu=self._cov,
                         velocity_enu=fix.velocity_enu, source="telemetry", track_id=fix.sysid)
