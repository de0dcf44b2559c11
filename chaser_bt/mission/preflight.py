"""The autopilot's own safety net, read at connect: what it will do when the mission cannot.

An unattended mission leans on ArduCopter's failsafes for everything it cannot handle itself: a
killed process or a lost radio (GCS failsafe), a pack that sags (battery failsafe), a flight that
wanders (fence), and RTL's height on the way home. ArduCopter ships most of them off. `run` reads
these parameters before the first tick, warns about each that is off, and with
``--require-failsafes`` refuses to fly without them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from chaser_bt.vehicle import VehicleError

__all__ = ["SAFETY_SETTINGS", "SafetySetting", "read_fence", "read_safety_settings", "safety_warnings"]


@dataclass(frozen=True)
class SafetySetting:
    """One parameter, the test it must pass, and what it means (and what to set) when it does not."""

    name: str
    ok: Callable[[float], bool]
    problem: str
    renamed: tuple[tuple[str, float], ...] = ()  # newer ArduCopter names, and the factor to this one's units


SAFETY_SETTINGS: tuple[SafetySetting, ...] = (
    SafetySetting("FS_GCS_ENABLE", lambda v: v != 0,
                  "GCS failsafe off: if this process dies or the link drops, the aircraft holds where it is "
                  "until its battery runs out (set FS_GCS_ENABLE 1, RTL)"),
    SafetySetting("BATT_FS_LOW_ACT", lambda v: v != 0,
                  "low-battery failsafe takes no action (set BATT_FS_LOW_ACT 2, RTL)"),
    SafetySetting("BATT_LOW_VOLT", lambda v: v > 0,
                  "no low-battery voltage: the battery failsafe never fires on a sagging pack (set BATT_LOW_VOLT)"),
    SafetySetting("FENCE_ENABLE", lambda v: v != 0,
                  "no geofence: nothing on the aircraft bounds where a wrong target can send it (set FENCE_ENABLE 1)"),
    SafetySetting("RTL_ALT", lambda v: v == 0 or v >= 1500,
                  "RTL_ALT under 15 m: the return flies home low, through trees and masts (cm; ArduCopter's default is 1500)",
                  renamed=(("RTL_ALT_M", 100.0),)),  # ArduCopter 4.7+: metres
)


def safety_warnings(params: dict[str, float], settings: tuple[SafetySetting, ...] = SAFETY_SETTINGS) -> list[str]:
    """One line per setting that is off or unread (a missing value is a warning: it could not be checked)."""
    out = []
    for s in settings:
        value = params.get(s.name)
        if value is None:
            out.append(f"{s.name} unread: could not check it ({s.problem.split(':')[0]} if it is off)")
        elif not s.ok(value):
            out.append(f"{s.name} = {value:g}: {s.problem}")
    return out


def read_safety_settings(link: Any, timeout_s: float = 5.0, settings: tuple[SafetySetting, ...] = SAFETY_SETTINGS) -> dict[str, float]:
    """Ask the vehicle for each setting at once (under each of its names) and wait (bounded) for the
    answers; what arrived, in each setting's own name and units."""
    names = [(s.name, *(n for n, _ in s.renamed)) for s in settings]
    commands = [link.request_param(name) for group in names for name in group]

    def answered() -> bool:  # each setting under one of its names (a vehicle knows one), or nothing more to come
        return all(any(n in link.params for n in group) for group in names) or all(c.done for c in commands)

    try:
        link.wait(answered, timeout_s)
    except VehicleError:  # some never answered: they are reported unread
        pass
    found = {}
    for s in settings:
        for name, factor in ((s.name, 1.0), *s.renamed):
            if name in link.params:
                found[s.name] = link.params[name] * factor
                break
    return found


def read_fence(link: Any, timeout_s: float = 5.0) -> Any:
    """Read the vehicle's FENCE_* parameters (bounded wait) so the link's command envelope stays inside
    its fence; the envelope now in force (:attr:`chaser_bt.vehicle.VehicleLink.envelope`)."""
    from chaser_bt.vehicle.envelope import FENCE_PARAMS

    commands = [link.request_param(name) for name in FENCE_PARAMS]
    try:
        link.wait(lambda: all(c.done for c in commands), timeout_s)
    except VehicleError:  # a vehicle without a fence, or a lost answer: the configured envelope stays
        pass
    return link.envelope
