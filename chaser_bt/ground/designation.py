"""The operator's designations, from wherever they come: the signed UDP uplink and MAVLink.

Two ways up carry the same command, "make radar track N the target": a ``designate`` on the
uplink (:mod:`chaser_bt.ground.uplink`, ``chaser-bt designate``) and a ground station's
``MAV_CMD_USER_1`` on the vehicle link (:mod:`chaser_bt.vehicle.designation`). Each source has
authenticated its own; :func:`take_designations` drains both, oldest first within each, so the
``GroundDesignation`` leaves write ``operator_track`` the same way whichever way it came.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from chaser_bt.ground.uplink import UplinkReceiver
    from chaser_bt.vehicle.link import VehicleLink

__all__ = ["Designation", "designation_summary", "take_designations"]


@dataclass(frozen=True)
class Designation:
    """One believed designation: the radar ``track_id``, its ``source`` (``uplink`` or ``mavlink``)
    and who sent it (``sender``: the ground station's address, or its MAVLink system/component)."""

    track_id: int
    source: str
    sender: str


def take_designations(uplink: UplinkReceiver | None, link: VehicleLink | None) -> list[Designation]:
    """Every designation believed since the last call: the uplink's, then the link's (None: that source is off)."""
    out: list[Designation] = []
    if uplink is not None:
        out += [Designation(cmd.track_id, "uplink", f"seq {cmd.seq}") for cmd in uplink.take("designate")]
    if link is not None:
        out += [Designation(d.track_id, "mavlink", f"{d.sysid}/{d.compid}") for d in link.take_designations()]
    return out


def designation_summary(uplink: UplinkReceiver | None, link: VehicleLink | None) -> str:
    """Both sources' counts in one line (a leaf's feedback)."""
    if uplink is None:
        parts = ["uplink off (chaser-bt run --uplink)"]
    else:
        c = uplink.counters
        parts = [f"uplink: {c.accepted} command(s), {sum(c.as_dict().values()) - c.accepted} dropped"]
    inbox = None if link is None else link.designations
    parts.append("MAVLink off (an unsigned link believes none)" if inbox is None else inbox.summary())
    return "; ".join(parts)
