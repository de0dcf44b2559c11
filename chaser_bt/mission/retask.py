"""Retasking a flying aircraft: a new mission tree takes over from the running one, at a safe point.

A retask arrives as a :class:`RetaskRequest` (a tree's bytes, where they came from): from a tree file
the operator edits (:class:`FileWatcher`, ``chaser-bt run --reload-from``), over the signed uplink
(``chaser-bt retask``), or scheduled by a rehearsal scenario. :func:`prepare` checks it against the
running flight before anything changes, and any problem is one line (:class:`RetaskRejected`):

* it is a tree: UTF-8, valid, every node known, every port right (``file:line:col`` of the problem);
* it is for this vehicle (a request that names a system id must name the link's);
* the resources its leaves need are the ones the flight has (no radar mid-flight);
* the vehicle can take it: its telemetry is trusted, and no failsafe of the autopilot is flying
  it (RTL or LAND that the mission did not ask for);
* every leaf's ``setup`` succeeds with the flight's link, clock and resources.

Only then does :meth:`chaser_bt.mission.runner.MissionRunner.retask` swap the trees between two
ticks: the running tree is halted (its leaves' exit holds), the aircraft is held (hover), and the new
tree ticks from the next tick on. A rejected request changes nothing. Each attempt is a
:class:`Retask` record, with both trees' hashes, in the log and the flight's report.
"""

from __future__ import annotations

import hashlib
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from chaser_bt.mission.resources import missing_resources
from chaser_bt.tree import MissionTree, TreeError, load_tree_text

__all__ = ["FileWatcher", "Retask", "RetaskRejected", "RetaskRequest", "prepare", "tree_hash"]

log = logging.getLogger(__name__)

#: Modes the autopilot's failsafes fly: a retask waits until the pilot or the mission has it back.
_FAILSAFE_MODES = ("RTL", "LAND", "SMART_RTL", "BRAKE")


class RetaskRejected(ValueError):
    """A retask that cannot be taken; the message is one line saying why."""


@dataclass(frozen=True)
class RetaskRequest:
    """A tree offered to the flight: its bytes, its name (``.xml``: BT.CPP XML, else YAML), the folder
    its includes are relative to, where it came from, and the vehicle it is for (None: any)."""

    data: bytes
    name: str
    base_dir: Path
    origin: str
    sysid: int | None = None


@dataclass(frozen=True)
class Retask:
    """One retask attempt at mission time ``t``: taken or not, and why."""

    t: float
    accepted: bool
    origin: str
    name: str
    old_hash: str
    new_hash: str
    message: str

    def as_dict(self) -> dict[str, Any]:
        return {"t": round(self.t, 3), "accepted": self.accepted, "origin": self.origin, "name": self.name,
                "old_hash": self.old_hash, "new_hash": self.new_hash, "message": self.message}


def tree_hash(data: bytes) -> str:
    """A tree's identity in logs: the first 12 hex digits of the SHA-256 of its bytes."""
    return hashlib.sha256(data).hexdigest()[:12]


def prepare(request: RetaskRequest, link: Any, resources: dict[str, Any]) -> MissionTree:
    """The request's tree, built and checked against this flight (module docstring; the runner then
    sets its leaves up).

    Raises:
        RetaskRejected: one line naming the request and the first reason it cannot be taken.
    """
    where = f"retask {request.name} ({request.origin})"
    if request.sysid is not None and link.target_sysid is not None and request.sysid != link.target_sysid:
        raise RetaskRejected(f"{where}: for vehicle {request.sysid}, this is vehicle {link.target_sysid}")
    try:
        text = request.data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RetaskRejected(f"{where}: not a tree file: byte {exc.start} is not UTF-8") from None
    if not text.strip():
        raise RetaskRejected(f"{where}: empty")
    try:
        tree = load_tree_text(text, source=request.name, base_dir=request.base_dir)
    except TreeError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else "invalid tree"
        raise RetaskRejected(f"{where}: {first}") from None
    missing = missing_resources(tree.root, resources)
    if missing is not None:
        raise RetaskRejected(f"{where}: {str(missing).splitlines()[0]}")
    state = link.state
    if state.telemetry_fault:
        raise RetaskRejected(f"{where}: the vehicle's telemetry is not trusted ({state.telemetry_fault})")
    if state.armed and state.mode in _FAILSAFE_MODES:
        raise RetaskRejected(f"{where}: the autopilot is flying {state.mode}; retask once the aircraft is back in "
                             f"the mission's hands")
    return tree


class FileWatcher:
    """Offers a tree file as a retask each time it changes and then stays unchanged for ``settle_s``
    (an editor's save, or a copy still being written, is not taken half-way).

    Args:
        path: the file to watch; it may not exist yet.
        settle_s: how long its size and modification time must hold still (wall seconds).
        monotonic: the wall clock (injectable for tests).
    """

    def __init__(self, path: str | Path, settle_s: float = 0.5, monotonic: Callable[[], float] = time.monotonic) -> None:
        self.path = Path(path)
        self.settle_s = settle_s
        self._monotonic = monotonic
        self._offered = self._stamp()  # the file as it was at start is the running tree, or none
        self._seen: tuple[int, int] | None = self._offered
        self._since = monotonic()

    def _stamp(self) -> tuple[int, int] | None:
        try:
            st = os.stat(self.path)
        except OSError:
            return None
        return (st.st_mtime_ns, st.st_size)

    def poll(self) -> RetaskRequest | None:
        """The file's new contents once it has settled after a change; else None."""
        stamp, now = self._stamp(), self._monotonic()
        if stamp != self._seen:
            self._seen, self._since = stamp, now
            return None
        if stamp is None or stamp == self._offered or now - self._since < self.settle_s:
            return None
        self._offered = stamp
        try:
            data = self.path.read_bytes()
        except OSError as exc:
            log.warning("retask %s: cannot read: %s", self.path, exc.strerror or exc)
            return None
        return RetaskRequest(data, self.path.name, self.path.parent, f"file {self.path}")
