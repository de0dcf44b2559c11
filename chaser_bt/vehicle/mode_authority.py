"""Who put the vehicle in its mode: the mission, or someone else (a ground station, the pilot, a failsafe).

The paper's ground station "can overwrite all commands if desired" (section 2.2): when the
operator, the pilot's mode switch or one of ArduCopter's own failsafes changes the flight mode,
the mission must notice and stop commanding rather than switch back. :class:`ModeAuthority`
watches a :class:`~chaser_bt.vehicle.VehicleLink` from both sides:

- every mode request the mission sends (COMMAND_LONG DO_SET_MODE, NAV_RETURN_TO_LAUNCH,
  NAV_LAND, or a SET_MODE message) is remembered as *pending*;
- every change of HEARTBEAT.custom_mode from the vehicle is matched against the pending requests:
  a requested mode is the mission's own, anything else is *foreign* and is logged with the time
  and the STATUSTEXT that came with it (ArduCopter names its failsafes: "GCS Failsafe", ...): of
  what the vehicle said since the last mode change at NOTICE or above, the most severe (a failsafe
  is CRITICAL or a WARNING; "Arming motors" and "EKF3 IMU0 is using GPS" are INFO: never a reason),
  the latest of those. ArduCopter may send the text just after the heartbeat that shows the new mode
  (its RC failsafe did, on the real SITL): a change that came with no reason takes the first one
  within :data:`LATE_REASON_S` after it.

A request that the vehicle has not honoured within :data:`PENDING_HEARTBEATS` heartbeats is
forgotten (a refused request must not excuse a later operator's switch to the same mode); the
count is in heartbeats, not seconds, so a request sent into a dead link is still pending when the
link returns and the vehicle shows the mode (ArduCopter's link-loss RTL, which the mission asked
for too).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from typing import Any, Callable

from chaser_bt.vehicle.connection import mavutil
from chaser_bt.vehicle.state import mode_name

__all__ = ["ForeignModeChange", "LATE_REASON_S", "ModeAuthority", "PENDING_HEARTBEATS"]

log = logging.getLogger(__name__)
mavlink = mavutil.mavlink

#: Heartbeats (about seconds, at ArduCopter's 1 Hz) a mode request stays pending.
PENDING_HEARTBEATS = 5
#: Seconds after a foreign change without a reason in which the vehicle's next reason still explains it.
LATE_REASON_S = 2.0
_MODE_OF_COMMAND = {mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH: "RTL", mavlink.MAV_CMD_NAV_LAND: "LAND"}


@dataclass(frozen=True)
class ForeignModeChange:
    """A mode change the mission did not ask for, at mission time ``t``; ``armed`` as the heartbeat
    said; ``why`` is the vehicle's most severe STATUSTEXT (NOTICE or above) since its last mode
    change, the latest of those (empty when it said none)."""

    t: float
    previous: str
    mode: str
    armed: bool
    why: str = ""


class ModeAuthority:
    """Classify the vehicle's mode changes as the mission's own or foreign (see the module docstring).

    Args:
        clock: mission time now, stamped on each change.
        vehicle_sysid: the vehicle's system id (None until known): only its heartbeats count.
    """

    def __init__(self, clock: Callable[[], float], vehicle_sysid: Callable[[], int | None]) -> None:
        self._clock = clock
        self._vehicle_sysid = vehicle_sysid
        self._pending: dict[str, int] = {}  # requested mode -> heartbeats seen since
        self._mode = ""
        self._reason: tuple[int, str] | None = None  # (severity, text) of the likeliest reason so far
        self.foreign: list[ForeignModeChange] = []
        self.own_changes = 0
        self._unexplained: int | None = None  # index in foreign of a change still waiting for its reason

    @classmethod
    def attach(cls, link: Any, clock: Callable[[], float]) -> ModeAuthority:
        """An authority listening on ``link`` (a VehicleLink) to what it sends and receives."""
        authority = cls(clock, lambda: link.target_sysid)
        link.add_listener(on_receive=authority.on_receive, on_send=authority.on_send)
        return authority

    @property
    def mode(self) -> str:
        """The vehicle's mode as last heard ("" before the first heartbeat)."""
        return self._mode

    def foreign_since(self, t: float, *, armed_only: bool = False) -> ForeignModeChange | None:
        """The latest foreign change after mission time ``t`` (with ``armed_only``, made while armed), if any."""
        for change in reversed(self.foreign):
            if change.t <= t:
                break
            if change.armed or not armed_only:
                return change
        return None

    def on_send(self, msg: Any) -> None:
        """A message the mission sent (link listener: never raises)."""
        try:
            mtype = msg.get_type()
            mode = None
            if mtype == "COMMAND_LONG":
                if msg.command == mavlink.MAV_CMD_DO_SET_MODE:
                    mode = mode_name(int(msg.param2))
                else:
                    mode = _MODE_OF_COMMAND.get(msg.command)
            elif mtype == "SET_MODE":
                mode = mode_name(int(msg.custom_mode))
            if mode is not None:
                self._pending[mode] = 0
        except Exception:  # a listener must not raise into the link
            log.debug("could not read a sent message", exc_info=True)

    def on_receive(self, msg: Any) -> None:
        """A message from the link (link listener: never raises)."""
        try:
            mtype = msg.get_type()
            if mtype not in ("HEARTBEAT", "STATUSTEXT") or msg.get_srcSystem() != self._vehicle_sysid():
                return
            if mtype == "STATUSTEXT":
                text = msg.text if isinstance(msg.text, str) else bytes(msg.text).decode(errors="replace")
                severity = int(getattr(msg, "severity", mavlink.MAV_SEVERITY_INFO))
                notice = severity <= mavlink.MAV_SEVERITY_NOTICE  # a reason, not chatter ("Arming motors" is INFO)
                if notice and self._explain_late(text.rstrip("\x00")):
                    return
                if notice and (self._reason is None or severity <= self._reason[0]):  # more severe, or as severe and later
                    self._reason = (severity, text.rstrip("\x00"))
                return
            if msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID:
                return  # another component's heartbeat (a gimbal, a companion)
            self._on_heartbeat(mode_name(int(msg.custom_mode)), bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED))
        except Exception:
            log.debug("could not read a received message", exc_info=True)

    def _on_heartbeat(self, mode: str, armed: bool) -> None:
        previous, self._mode = self._mode, mode
        if previous and mode != previous:
            if mode in self._pending:
                self.own_changes += 1
            else:
                why = self._reason[1] if self._reason is not None else ""
                change = ForeignModeChange(float(self._clock()), previous, mode, armed, why)
                self.foreign.append(change)
                self._unexplained = None if why else len(self.foreign) - 1
                log.warning("mode %s -> %s not commanded by the mission (%s)", previous, mode, change.why or "no reason given")
            self._pending.pop(mode, None)
            self._reason = None
        elif mode in self._pending:
            self._pending.pop(mode)  # already there: the request is answered
        for requested in list(self._pending):
            self._pending[requested] += 1
            if self._pending[requested] > PENDING_HEARTBEATS:
                del self._pending[requested]

    def _explain_late(self, text: str) -> bool:
        """Give ``text`` to the last foreign change if it came without a reason less than ``LATE_REASON_S``
        ago; whether it did."""
        i, self._unexplained = self._unexplained, None
        if i is None or float(self._clock()) - self.foreign[i].t > LATE_REASON_S:
            return False
        self.foreign[i] = replace(self.foreign[i], why=text)
        log.warning("mode %s -> %s: %s", self.foreign[i].previous, self.foreign[i].mode, text)
        return True
