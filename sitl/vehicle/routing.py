"""MAVLink routing between the simulator's channels, as ArduPilot's MAVLink_routing.cpp does it.

A flight controller with several links (a ground station's radio, a companion computer's port)
forwards messages between them, so a ground station can reach a companion through the autopilot:

- Every message teaches a route: its source (system, component) is reachable on the channel it came
  in on (never the broadcast system 0, our own ids, or our system's broadcast component).
- A HEARTBEAT goes to every other channel but those its source is known on.
- Any other message is forwarded by its ``target_system``/``target_component`` fields (absent or 0:
  broadcast): to every channel but the incoming one with a route to a matching source, where "matching"
  is the target system, and the target component too when the target is our own system.
- It is processed locally when it is for us (broadcast or our ids), or for our system and nowhere
  forwarded; a message from our own ids (a loop in the wiring) is neither processed nor forwarded.
- RADIO and RADIO_STATUS are never forwarded. A forwarded message goes out byte for byte as it came
  in, signature included, so the receiver checks the sender's signature, not ours.

Private channels and the route limit (20) are not simulated; routes of a closed channel go with it.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

__all__ = ["Route", "Router"]

C = TypeVar("C")

_NEVER_FORWARDED = frozenset({"RADIO", "RADIO_STATUS"})


@dataclass(frozen=True)
class Route(Generic[C]):
    """A source (system, component) heard on a channel (held weakly: a closed channel's routes lapse)."""

    sysid: int
    compid: int
    channel: weakref.ref[C]


def targets(msg: Any) -> tuple[int, int]:
    """A message's ``(target_system, target_component)``; -1 where it has no such field."""
    names = msg.get_fieldnames()
    return (msg.target_system if "target_system" in names else -1,
            msg.target_component if "target_component" in names else -1)


class Router(Generic[C]):
    """The forwarding rules of ArduPilot's ``MAVLink_routing`` for the autopilot ``sysid``/``compid``."""

    def __init__(self, sysid: int, compid: int) -> None:
        self.sysid = sysid
        self.compid = compid
        self._routes: list[Route[C]] = []

    def routes(self) -> list[tuple[int, int, C]]:
        """The routes learnt, as (system, component, channel), oldest first (closed channels forgotten)."""
        live = [(r, r.channel()) for r in self._routes]
        self._routes = [r for r, c in live if c is not None]
        return [(r.sysid, r.compid, c) for r, c in live if c is not None]

    def check_and_forward(self, msg: Any, channel: C, channels: list[C]) -> tuple[bool, list[C]]:
        """Learn from ``msg`` (arrived on ``channel``); return (process it locally, channels to resend it on).

        ``channels`` are every open channel (a heartbeat goes to those its source is not known on).
        """
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if src == (self.sysid, self.compid):
            return False, []  # our own message looped back
        self._learn(src, channel)
        kind = msg.get_type()
        if kind in _NEVER_FORWARDED:
            return True, []
        if kind == "HEARTBEAT":
            known = {id(c) for s, k, c in self.routes() if (s, k) == src}
            return True, [c for c in channels if c is not channel and id(c) not in known]
        return self._forward(msg, channel)

    def _learn(self, src: tuple[int, int], channel: C) -> None:
        sysid, compid = src
        if sysid == 0 or (sysid == self.sysid and compid in (self.compid, 0)):
            return
        if any((s, k) == src and c is channel for s, k, c in self.routes()):
            return
        self._routes.append(Route(sysid, compid, weakref.ref(channel)))

    def _forward(self, msg: Any, channel: C) -> tuple[bool, list[C]]:
        to_sys, to_comp = targets(msg)
        broadcast_sys, broadcast_comp = to_sys in (0, -1), to_comp in (0, -1)
        match_sys = broadcast_sys or to_sys == self.sysid
        local = match_sys and (broadcast_comp or to_comp == self.compid)
        if local and not broadcast_sys and not broadcast_comp:
            return True, []  # it can only be for us
        out: list[C] = []
        for sysid, compid, c in self.routes():
            if c is channel or any(c is o for o in out):
                continue
            if broadcast_sys or (to_sys == sysid and (broadcast_comp or to_comp == compid or not match_sys)):
                out.append(c)
        if (not out and match_sys) or broadcast_sys:
            local = True
        return local, out
