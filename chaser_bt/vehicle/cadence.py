"""A periodic send kept on the link's clock and, when asked, on the vehicle's clock too.

The link's heartbeat (FS_GCS failsafe) and its held RC override (RC_OVERRIDE_TIME) are judged by
the vehicle in *its* time. Against a simulator at speed-up, a period on the ground station's wall
clock is many seconds of vehicle time, so the vehicle sees the heartbeat rarely and goes into
failsafe. A :class:`Cadence` given the vehicle's time (its ``time_boot_ms``) is due when a period
has passed on *either* clock: the vehicle's rules it at any speed-up, and the link's own keeps the
send going when the vehicle's time stalls (a quiet or lock-stepped vehicle). Sending a little more
often than the period never hurts; sending less often does.
"""

from __future__ import annotations

import math

__all__ = ["Cadence"]

_SLACK_S = 1e-6  # absorbs float error in the clocks


class Cadence:
    """Due every ``period_s`` on the link's clock, or on the vehicle's clock when one is passed.

    Args:
        period_s: the period, in seconds of either clock.
        link_t: the link's time now; the first send is due at once.
    """

    def __init__(self, period_s: float, link_t: float) -> None:
        if not period_s > 0:
            raise ValueError(f"period_s = {period_s}: expected > 0")
        self.period_s = float(period_s)
        self._next_link = float(link_t)
        self._next_vehicle: float | None = None  # unknown until a vehicle time is seen

    def fire(self, link_t: float, vehicle_t: float = math.nan) -> bool:
        """Whether a send is due now; if so the next one is scheduled (the caller sends).

        ``vehicle_t`` is ``nan`` when the vehicle's clock is not used or not known yet. A vehicle
        clock seen for the first time, or gone backwards (a reboot), starts counting from now.
        """
        use_vehicle = math.isfinite(vehicle_t)
        if use_vehicle and (self._next_vehicle is None or vehicle_t < self._next_vehicle - self.period_s):
            self._next_vehicle = vehicle_t + self.period_s
        link_due = link_t >= self._next_link - _SLACK_S
        vehicle_due = use_vehicle and vehicle_t >= self._next_vehicle - _SLACK_S  # type: ignore[operator]
        if not (link_due or vehicle_due):
            return False
        self._next_link = _next_slot(self._next_link, self.period_s, link_t) if link_due else link_t + self.period_s
        if use_vehicle:
            self._next_vehicle = (_next_slot(self._next_vehicle, self.period_s, vehicle_t)  # type: ignore[arg-type]
                                  if vehicle_due else vehicle_t + self.period_s)
        return True

    def restart(self, link_t: float, vehicle_t: float = math.nan) -> None:
        """A send just went out of turn: the next is one period from now on each clock."""
        self._next_link = link_t + self.period_s
        self._next_vehicle = vehicle_t + self.period_s if math.isfinite(vehicle_t) else None


def _next_slot(scheduled: float, period: float, now: float) -> float:
    """The next time on a fixed cadence, so late polls do not stretch the period; after a long
    pause the cadence restarts from ``now`` instead of sending a burst."""
    nxt = scheduled + period
    return nxt if nxt > now else now + period
