"""What the simulated ArduCopter stores of missions, fences and rally points (AP_Mission's storage).

Three lists, one per MAV_MISSION_TYPE (0 mission, 1 fence, 2 rally), of items as MISSION_ITEM_INT
carries them. The mission's item 0 is home: whatever is uploaded there, reading item 0 gives the
vehicle's home (AP_Mission::read_cmd_from_storage). A fresh vehicle's mission has that one item;
MISSION_CLEAR_ALL leaves it with none (the 4.7.0-dev SITL then answers MISSION_COUNT 0) until the
next upload. Fence and rally lists start empty. The upload and download protocol is
:mod:`sitl.vehicle.mission_protocol`; nothing here flies a mission (the autopilot has no AUTO).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FENCE", "MAX_ITEMS", "MISSION", "MISSION_TYPES", "RALLY", "MissionItem", "MissionStore"]

MISSION, FENCE, RALLY = 0, 1, 2  # MAV_MISSION_TYPE
MISSION_TYPES = (MISSION, FENCE, RALLY)
_POLYGON_VERTEX_COMMANDS = frozenset({5001, 5002})  # MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION/EXCLUSION
MAX_ITEMS = 700  # per list; a bigger upload is refused with MAV_MISSION_NO_SPACE


@dataclass(frozen=True)
class MissionItem:
    """One stored item, in MISSION_ITEM_INT's terms (x, y: 1e7 degrees or local; z: m)."""

    frame: int
    command: int
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    autocontinue: int = 1


class MissionStore:
    """The vehicle's stored lists; the mission's item 0 slot is home's (see module docstring)."""

    def __init__(self) -> None:
        self._items: dict[int, list[MissionItem | None]] = {t: [] for t in MISSION_TYPES}
        self._items[MISSION].append(None)  # home's slot: read as the vehicle's home

    def count(self, mission_type: int) -> int:
        """MISSION_COUNT.count: the items stored (home's slot included)."""
        return len(self._items[mission_type])

    def item(self, mission_type: int, seq: int) -> MissionItem | None:
        """Stored item ``seq``; None past the end and for the mission's item 0 (home: the caller's)."""
        items = self._items[mission_type]
        return items[seq] if 0 <= seq < len(items) else None

    def replace(self, mission_type: int, items: list[MissionItem] | list[MissionItem | None]) -> None:
        """A completed upload: the list becomes ``items``."""
        self._items[mission_type] = list(items)

    def polygon_points(self) -> int:
        """Stored fence polygon vertices (inclusion or exclusion), for AC_Fence's "present"."""
        return sum(1 for i in self._items[FENCE] if i is not None and i.command in _POLYGON_VERTEX_COMMANDS)

    def clear(self, mission_type: int) -> None:
        """MISSION_CLEAR_ALL (or an upload of 0 items) for one list."""
        self._items[mission_type] = []
