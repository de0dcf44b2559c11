"""Retasking a flying aircraft: a new mission tree, or a new version of one of its subtrees, takes over
at a safe point.

A retask arrives as a :class:`RetaskRequest` (a tree's bytes, where they came from, and the subtree it
replaces, if it replaces one): from a tree file the operator edits (:class:`FileWatcher`,
``chaser-bt run --reload-from``), over the signed uplink (``chaser-bt retask``), or scheduled by a
rehearsal scenario. :func:`prepare` (a whole tree) and :func:`prepare_subtree` (one subtree) check it
against the running flight before anything changes, and any problem is one line
(:class:`RetaskRejected`):

* it is a tree: UTF-8, valid, every node known, every port right (``file:line:col`` of the problem);
  for a subtree, the running tree has that subtree and the whole tree with the replacement spliced
  in is valid (:mod:`chaser_bt.tree.splice`: the running ``SubTree`` nodes' remappings still fit);
* it is for this vehicle (a request that names a system id must name the link's);
* the resources its leaves need are the ones the flight has (no radar mid-flight);
* the vehicle can take it: its telemetry is trusted, and no failsafe of the autopilot is flying
  it (RTL or LAND that the mission did not ask for);
* every leaf's ``setup`` succeeds with the flight's link, clock and resources.

Only then does :meth:`chaser_bt.mission.runner.MissionRunner.retask` make the change between two
ticks. A whole tree: the running tree is halted (its leaves' exit holds), the aircraft is held
(hover), and the new tree ticks from the next tick on. A subtree: only its instances change; one that
was running is halted (and the aircraft held if a leaf of it was commanding the aircraft), the rest of
the tree keeps its state, and the new instance ticks from its start when its parent next ticks it.
A rejected request changes nothing. Each attempt is a :class:`Retask` record, with the whole tree's
old and new hashes (and the subtree's name), in the log and the flight's report.
"""

from __future__ import annotations

import hashlib
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import py_trees

from chaser_bt.mission.resources import missing_resources
from chaser_bt.tree import MissionTree, Problem, TreeError
from chaser_bt.tree.documents import merge_includes, parse_document
from chaser_bt.tree.model import TreeDocument
from chaser_bt.tree.splice import Splice, SpliceError, build_document, plan_splice

__all__ = ["FileWatcher", "Retask", "RetaskRejected", "RetaskRequest", "prepare", "prepare_subtree", "prepare_tree",
           "spliced_hash", "tree_hash"]

log = logging.getLogger(__name__)

#: Modes the autopilot's failsafes fly: a retask waits until the pilot or the mission has it back.
_FAILSAFE_MODES = ("RTL", "LAND", "SMART_RTL", "BRAKE")


class RetaskRejected(ValueError):
    """A retask that cannot be taken; the message is one line saying why."""


@dataclass(frozen=True)
class RetaskRequest:
    """A tree offered to the flight: its bytes, its name (``.xml``: BT.CPP XML, else YAML), the folder
    its includes are relative to, where it came from, the vehicle it is for (None: any) and the
    subtree of the running tree it replaces (None: the whole tree)."""

    data: bytes
    name: str
    base_dir: Path
    origin: str
    sysid: int | None = None
    subtree: str | None = None

    @property
    def label(self) -> str:
        """How messages name it: ``retask land.yaml (uplink)``, then ``: subtree Leg`` for a subtree."""
        label = f"retask {self.name} ({self.origin})"
        return f"{label}: subtree {self.subtree}" if self.subtree is not None else label


@dataclass(frozen=True)
class Retask:
    """One retask attempt at mission time ``t``: taken or not, and why. The hashes are the whole
    tree's, before and after (:func:`tree_hash`, :func:`spliced_hash`); ``subtree`` names the subtree
    replaced (None: the whole tree)."""

    t: float
    accepted: bool
    origin: str
    name: str
    old_hash: str
    new_hash: str
    message: str
    subtree: str | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"t": round(self.t, 3), "accepted": self.accepted, "origin": self.origin, "name": self.name,
                "old_hash": self.old_hash, "new_hash": self.new_hash, "message": self.message,
                "subtree": self.subtree}


def tree_hash(data: bytes) -> str:
    """A tree's identity in logs: the first 12 hex digits of the SHA-256 of its bytes."""
    return hashlib.sha256(data).hexdigest()[:12]


def spliced_hash(old_hash: str, subtree: str, data: bytes) -> str:
    """The whole tree's identity once subtree ``subtree`` of the tree ``old_hash`` is replaced by the
    tree file ``data``: the first 12 hex digits of the SHA-256 of the three."""
    return hashlib.sha256(b"\0".join((old_hash.encode(), subtree.encode(), data))).hexdigest()[:12]


def _first(problems: list[Problem]) -> str:
    """The first problem, on one line, and how many more there are."""
    ordered = sorted(problems)
    first = str(ordered[0]).strip().splitlines()[0] if ordered else "invalid tree"
    return first + (f" (and {len(ordered) - 1} more)" if len(ordered) > 1 else "")


def _read(request: RetaskRequest, where: str, link: Any) -> tuple[TreeDocument, list[Problem]]:
    """The request's document (its includes merged) and its parse problems, once it is for this vehicle and text."""
    if request.sysid is not None and link.target_sysid is not None and request.sysid != link.target_sysid:
        raise RetaskRejected(f"{where}: for vehicle {request.sysid}, this is vehicle {link.target_sysid}")
    try:
        text = request.data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RetaskRejected(f"{where}: not a tree file: byte {exc.start} is not UTF-8") from None
    if not text.strip():
        raise RetaskRejected(f"{where}: empty")
    document, problems = parse_document(text, request.name)
    merged, more = merge_includes(document, Path(request.base_dir))
    return merged, problems + more


def _check_flight(where: str, roots: list[py_trees.behaviour.Behaviour], link: Any, resources: dict[str, Any]) -> None:
    """The flight can take these new nodes: it has their resources, and the mission has the aircraft."""
    for root in roots:
        missing = missing_resources(root, resources)
        if missing is not None:
            raise RetaskRejected(f"{where}: {str(missing).splitlines()[0]}")
    state = link.state
    if state.telemetry_fault:
        raise RetaskRejected(f"{where}: the vehicle's telemetry is not trusted ({state.telemetry_fault})")
    if state.armed and state.mode in _FAILSAFE_MODES:
        raise RetaskRejected(f"{where}: the autopilot is flying {state.mode}; retask once the aircraft is back in "
                             f"the mission's hands")


def prepare_tree(request: RetaskRequest, link: Any, resources: dict[str, Any]) -> tuple[MissionTree, TreeDocument]:
    """The request's whole tree, built and checked against this flight, and the document it was built
    from (module docstring; the runner then sets its leaves up).

    Raises:
        RetaskRejected: one line naming the request and the first reason it cannot be taken.
    """
    where = request.label
    document, problems = _read(request, where, link)
    try:
        tree = build_document(document, problems)
    except TreeError as exc:
        raise RetaskRejected(f"{where}: {_first(exc.problems)}") from None
    _check_flight(where, [tree.root], link, resources)
    return tree, document


def prepare(request: RetaskRequest, link: Any, resources: dict[str, Any]) -> MissionTree:
    """:func:`prepare_tree`'s tree."""
    return prepare_tree(request, link, resources)[0]


def prepare_subtree(request: RetaskRequest, link: Any, resources: dict[str, Any], running: MissionTree,
                    document: TreeDocument | None) -> Splice:
    """The replacement of subtree ``request.subtree`` of ``running`` (built from ``document``), checked
    against this flight, its new instances built but not yet in the tree (:mod:`chaser_bt.tree.splice`).

    Raises:
        RetaskRejected: one line naming the request, the subtree and the first reason it cannot be taken.
    """
    assert request.subtree is not None
    where = request.label
    replacement, problems = _read(request, where, link)
    if problems:
        raise RetaskRejected(f"{where}: {_first(problems)}")
    if document is None:
        raise RetaskRejected(f"{where}: the running tree was not read from a file, so its subtrees are not known: "
                             f"retask the whole tree")
    try:
        splice = plan_splice(running, document, replacement, request.subtree)
    except SpliceError as exc:
        raise RetaskRejected(f"{where}: {exc}") from None
    except TreeError as exc:
        raise RetaskRejected(f"{where}: spliced in, the tree does not validate: {_first(exc.problems)}") from None
    _check_flight(where, [site.new for site in splice.sites], link, resources)
    return splice


class FileWatcher:
    """Offers a tree file as a retask each time it changes and then stays unchanged for ``settle_s``
    (an editor's save, or a copy still being written, is not taken half-way).

    Args:
        path: the file to watch; it may not exist yet.
        settle_s: how long its size and modification time must hold still (wall seconds).
        monotonic: the wall clock (injectable for tests).
        subtree: the subtree of the running tree each version replaces (None: the whole tree).
    """

    def __init__(self, path: str | Path, settle_s: float = 0.5, monotonic: Callable[[], float] = time.monotonic,
                 subtree: str | None = None) -> None:
        self.path = Path(path)
        self.settle_s = settle_s
        self.subtree = subtree
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
        return RetaskRequest(data, self.path.name, self.path.parent, f"file {self.path}", subtree=self.subtree)
