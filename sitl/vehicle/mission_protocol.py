"""The MAVLink mission protocol over the vehicle's :class:`~sitl.vehicle.mission.MissionStore`.

As ArduPilot's MissionItemProtocol answers it (GCS_MAVLink/MissionItemProtocol*.cpp), for the
mission, fence and rally lists alike:

- download: MISSION_REQUEST_LIST -> MISSION_COUNT; MISSION_REQUEST_INT -> MISSION_ITEM_INT (the
  legacy MISSION_REQUEST -> MISSION_ITEM, degrees as floats); a sequence number past the end ->
  MISSION_ACK MAV_MISSION_INVALID_SEQUENCE. The mission's item 0 is home, frame GLOBAL, altitude
  AMSL (zeros before home is set, as ArduPilot's unset home).
- upload: MISSION_COUNT -> MISSION_REQUEST for item 0, each MISSION_ITEM_INT (or MISSION_ITEM)
  with the awaited sequence number -> the request for the next one, the last -> MISSION_ACK
  ACCEPTED and, for a mission, "Flight plan received". ArduPilot asks with MISSION_REQUEST, not
  _INT (seen on the 4.7.0-dev SITL) and takes either item message back. A count of 0 clears the
  list; a fence item that is not a fence command or a rally item that is not a rally point ends
  the upload with MAV_MISSION_UNSUPPORTED. An item with another sequence number gets the awaited
  request again (ArduPilot re-requests on a timer; here at once).
- MISSION_CLEAR_ALL -> MISSION_ACK ACCEPTED (mission type 255 clears all three); the mission is then
  empty, home slot included, as the real SITL reports it.

Replies go to the requesting system and component.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

os.environ["MAVLINK20"] = "1"

from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from chaser_bt.geo import GeoPoint  # noqa: E402
from sitl.vehicle.mission import (  # noqa: E402
    MAX_ITEMS,
    MISSION,
    MISSION_TYPES,
    MissionItem,
    MissionStore,
)

__all__ = ["MissionProtocol"]

_FENCE_COMMANDS = frozenset(range(mavlink2.MAV_CMD_NAV_FENCE_RETURN_POINT, mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION + 1))
_RALLY_COMMANDS = frozenset({mavlink2.MAV_CMD_NAV_RALLY_POINT})
_ALL = mavlink2.MAV_MISSION_TYPE_ALL


@dataclass
class _Upload:
    mission_type: int
    count: int
    sysid: int
    compid: int
    items: list[MissionItem]


class MissionProtocol:
    """Answers the mission messages (see module docstring).

    Args:
        store: the vehicle's lists.
        home: the vehicle's home now (None before it is set).
        emit: packs and queues one message.
        text: queues one STATUSTEXT (severity, text).
    """

    def __init__(self, store: MissionStore, home: Callable[[], GeoPoint | None],
                 emit: Callable[[object], None], text: Callable[[int, str], None]) -> None:
        self._store = store
        self._home = home
        self._emit = emit
        self._text = text
        self._upload: _Upload | None = None

    def handle(self, msg) -> None:
        """One mission message addressed to this vehicle."""
        kind = msg.get_type()
        if kind == "MISSION_REQUEST_LIST":
            self._on_request_list(msg)
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            self._on_request(msg, as_int=kind == "MISSION_REQUEST_INT")
        elif kind == "MISSION_COUNT":
            self._on_count(msg)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            self._on_item(msg, as_int=kind == "MISSION_ITEM_INT")
        elif kind == "MISSION_CLEAR_ALL":
            self._on_clear_all(msg)
        # MISSION_ACK from the GCS ends its download: nothing to do

    def _ack(self, msg, result: int, mission_type: int) -> None:
        self._emit(mavlink2.MAVLink_mission_ack_message(msg.get_srcSystem(), msg.get_srcComponent(),
                                                        result, mission_type))

    def _home_item(self) -> MissionItem:
        home = self._home()
        if home is None:
            return MissionItem(mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_CMD_NAV_WAYPOINT)
        return MissionItem(mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_CMD_NAV_WAYPOINT,
                           x=round(home.lat_deg * 1e7), y=round(home.lon_deg * 1e7), z=float(home.alt_m))

    # --- download ---
    def _on_request_list(self, msg) -> None:
        t = msg.mission_type
        if t not in MISSION_TYPES:
            self._ack(msg, mavlink2.MAV_MISSION_UNSUPPORTED, t)
            return
        self._emit(mavlink2.MAVLink_mission_count_message(msg.get_srcSystem(), msg.get_srcComponent(),
                                                          self._store.count(t), t))

    def _on_request(self, msg, *, as_int: bool) -> None:
        t, seq = msg.mission_type, msg.seq
        if t not in MISSION_TYPES:
            self._ack(msg, mavlink2.MAV_MISSION_UNSUPPORTED, t)
            return
        if not 0 <= seq < self._store.count(t):
            self._ack(msg, mavlink2.MAV_MISSION_INVALID_SEQUENCE, t)
            return
        item = self._home_item() if t == MISSION and seq == 0 else self._store.item(t, seq)
        if item is None:  # cannot happen inside the count; kept so a gap never crashes the link
            self._ack(msg, mavlink2.MAV_MISSION_INVALID_SEQUENCE, t)
            return
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        params = (item.param1, item.param2, item.param3, item.param4)
        if as_int:
            out = mavlink2.MAVLink_mission_item_int_message(*src, seq, item.frame, item.command, 0, item.autocontinue,
                                                            *params, item.x, item.y, item.z, t)
        else:
            out = mavlink2.MAVLink_mission_item_message(*src, seq, item.frame, item.command, 0, item.autocontinue,
                                                        *params, item.x * 1e-7, item.y * 1e-7, item.z, t)
        self._emit(out)

    # --- upload ---
    def _on_count(self, msg) -> None:
        t, count = msg.mission_type, msg.count
        if t not in MISSION_TYPES:
            self._ack(msg, mavlink2.MAV_MISSION_UNSUPPORTED, t)
            return
        self._upload = None
        if count == 0:
            self._store.clear(t)
            self._ack(msg, mavlink2.MAV_MISSION_ACCEPTED, t)
            return
        if count > MAX_ITEMS:
            self._ack(msg, mavlink2.MAV_MISSION_NO_SPACE, t)
            return
        self._upload = _Upload(t, count, msg.get_srcSystem(), msg.get_srcComponent(), [])
        self._request_next()

    def _request_next(self) -> None:
        up = self._upload
        assert up is not None
        self._emit(mavlink2.MAVLink_mission_request_message(up.sysid, up.compid, len(up.items), up.mission_type))

    def _on_item(self, msg, *, as_int: bool) -> None:
        up = self._upload
        if up is None or msg.mission_type != up.mission_type or msg.get_srcSystem() != up.sysid:
            return  # no upload of this list in progress from this GCS: ignored
        if msg.seq != len(up.items):
            self._request_next()
            return
        t = up.mission_type
        if (t == 1 and msg.command not in _FENCE_COMMANDS) or (t == 2 and msg.command not in _RALLY_COMMANDS):
            self._upload = None
            self._ack(msg, mavlink2.MAV_MISSION_UNSUPPORTED, t)
            return
        x, y = (int(msg.x), int(msg.y)) if as_int else (round(msg.x * 1e7), round(msg.y * 1e7))
        up.items.append(MissionItem(msg.frame, msg.command, msg.param1, msg.param2, msg.param3, msg.param4,
                                    x, y, float(msg.z), msg.autocontinue))
        if len(up.items) < up.count:
            self._request_next()
            return
        self._store.replace(t, up.items)
        self._upload = None
        self._ack(msg, mavlink2.MAV_MISSION_ACCEPTED, t)
        if t == MISSION:
            self._text(mavlink2.MAV_SEVERITY_INFO, "Flight plan received")

    def _on_clear_all(self, msg) -> None:
        t = msg.mission_type
        if t != _ALL and t not in MISSION_TYPES:
            self._ack(msg, mavlink2.MAV_MISSION_UNSUPPORTED, t)
            return
        for kind in MISSION_TYPES if t == _ALL else (t,):
            self._store.clear(kind)
        self._upload = None
        self._ack(msg, mavlink2.MAV_MISSION_ACCEPTED, t)
