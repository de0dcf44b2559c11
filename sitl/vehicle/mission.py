"""What the simulated ArduCopter stores of missions, fences and rally points (AP_Mission's storage).

Three lists, one per MAV_MISSION_TYPE (0 mission, 1 fence, 2 rally), of items as MISSION_ITEM_INT
carries them. The mission's item 0 is home: whatever is uploaded there, reading item 0 gives the
vehicle's home (AP_Mission::read_cmd_from_storage), so a fresh vehicle's mission has one item.
Fence and rally lists start empty. The upload and download protocol is
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
        self._items: dict[int, list[MissionItem]] = {t: [] for t in MISSION_TYPES}

    def count(self, mission_type: int) -> int:
        """MISSION_COUNT.count: stored items, the mission at least 1 (home)."""
        n = len(self._items[mission_type])
        return max(n, 1) if mission_type == MISSION else n

    def item(self, mission_type: int, seq: int) -> MissionItem | None:
        """Stored item ``seq`` (the mission's item 0 is not stored: home is given by the caller)."""
        items = self._items[mission_type]
        return items[seq] if 0 <= seq < len(items) else None

    def replace(self, mission_type: int, items: list[MissionItem]) -> None:
        """A completed upload: the list becomes ``items``."""
        self._items[mission_type] = list(items)

    def polygon_points(self) -> int:
        """Stored fence polygon vertices (inclusion or exclusion), for AC_Fence's "present"."""
        return sum(1 for i in self._items[FENCE] if i.command in _POLYGON_VERTEX_COMMANDS)

    def clear(self, mission_type: int) -> None:
        """MISSION_CLEAR_ALL for one list (the mission keeps home as item 0)."""
        self._items[mission_type] = []
