"""The ground's commands to the aircraft: an authenticated uplink beside the ground stream.

The ground stream only goes down. An operator who sees, on the ground, that the chase holds the
wrong drone designates another by its radar track id. That command must never come from anyone
else, so the uplink is signed, always: the same HMAC header, key file and replay rules as the
ground stream (:mod:`chaser_bt.ground.auth`), around a version-1 JSON message
(:func:`chaser_bt.ground.protocol.json_datagram`) of type ``command``::

    {"v": 1, "type": "command", "seq": 12, "t": 1767225600.2, "command": "designate", "track_id": 4117}

``t`` is the sender's wall clock (informational; freshness is the signature's timestamp). Commands:

=====================  ==========================================================================
``designate``          ``track_id`` (a radar track id, 0 .. 2^31-1): make that track's object the
                       target
``retask``             ``name`` (the tree's file name: ``.xml`` is BT.CPP XML, else YAML), ``tree``
                       (its text), ``sysid`` (the vehicle it is for): fly this tree instead
                       (:mod:`chaser_bt.mission.retask`); it carries no ``subtree``
``replace_subtree``    ``name``, ``tree`` and ``sysid`` as a retask's, and ``subtree`` (a tree ID): the
                       file's tree replaces that subtree of the running tree only
=====================  ==========================================================================

A subtree's replacement is a kind of its own, never a ``retask`` with one more field: an aircraft
that does not know ``replace_subtree`` drops it as an unknown command, and never flies the file as
its whole tree. A ``retask`` that carries ``subtree`` is refused for the same reason.

:class:`UplinkReceiver` reads them from a UDP port without blocking: a datagram that is unsigned,
forged, replayed, from a host not allowed, malformed or an unknown command is dropped and counted
(:class:`UplinkCounters`), never raised. Each consumer takes its own kinds (:meth:`UplinkReceiver.take`):
the ``GroundDesignation`` leaves the designations, the mission runner the retasks and subtree
replacements. :func:`designate_datagram`, :func:`retask_datagram` and :func:`replace_subtree_datagram`
build them (``chaser-bt designate``, ``chaser-bt retask [--subtree NAME]``).
"""

from __future__ import annotations

import logging
import socket
import time
from dataclasses import dataclass, field
from typing import Any, Iterable

from chaser_bt.ground.auth import StreamSigner, StreamVerifier
from chaser_bt.ground.protocol import json_datagram, parse_datagram

__all__ = ["COMMANDS", "RETASK_COMMANDS", "GroundCommand", "UplinkCounters", "UplinkReceiver", "designate_datagram",
           "parse_command", "replace_subtree_datagram", "retask_datagram"]

log = logging.getLogger(__name__)

COMMANDS = ("designate", "retask", "replace_subtree")
#: The kinds that change the mission's tree: the whole of it, or one subtree.
RETASK_COMMANDS = ("retask", "replace_subtree")
MAX_TRACK_ID = 2**31 - 1
#: Characters a tree ID may not hold (BehaviorTree.CPP refuses them), so no subtree name has them.
_NOT_IN_TREE_IDS = frozenset(" \t\n\r<>&\"'/\\:*?|.")


@dataclass(frozen=True)
class GroundCommand:
    """One command the aircraft believed: its ``kind`` and ``seq``; a designation's ``track_id``; a
    retask's tree ``name``, ``tree`` text and target ``sysid``; and the ``subtree`` a
    ``replace_subtree`` replaces (None for a ``retask``: the whole tree)."""

    kind: str
    seq: int
    track_id: int | None = None
    name: str | None = None
    tree: str | None = None
    sysid: int | None = None
    subtree: str | None = None


def _integer(msg: dict, key: str, lo: int, hi: int) -> int:
    v = msg.get(key)
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise ValueError(f"{msg.get('command')}: {key} {v!r}: expected an integer {lo}..{hi}")
    return v


def parse_command(payload: bytes) -> GroundCommand:
    """A verified payload as a command.

    Raises:
        ValueError: not a version-1 ``command`` message, an unknown command, or a bad field (named).
    """
    msg = parse_datagram(payload)
    if not isinstance(msg, dict) or msg.get("type") != "command":
        raise ValueError("not a command message")
    kind = msg.get("command")
    if kind not in COMMANDS:
        raise ValueError(f"command {kind!r}: expected one of {', '.join(COMMANDS)}")
    seq = msg.get("seq")
    if isinstance(seq, bool) or not isinstance(seq, int):
        raise ValueError(f"{kind}: seq {seq!r}: expected an integer")
    if kind == "designate":
        return GroundCommand(kind, seq, track_id=_integer(msg, "track_id", 0, MAX_TRACK_ID))
    name, tree = msg.get("name"), msg.get("tree")
    if not isinstance(name, str) or not name or "/" in name or "\\" in name:
        raise ValueError(f"{kind}: name {name!r}: expected a file name such as chase.yaml")
    if not isinstance(tree, str):
        raise ValueError(f"{kind}: tree: expected the tree file's text, got {type(tree).__name__}")
    if kind == "retask":
        if "subtree" in msg:
            raise ValueError(f"retask: carries subtree {msg['subtree']!r}, which a retask never does (one subtree "
                             f"comes as replace_subtree); refused rather than flown as the whole tree")
        return GroundCommand(kind, seq, name=name, tree=tree, sysid=_integer(msg, "sysid", 1, 255))
    subtree = msg.get("subtree")
    _check_subtree(kind, subtree)
    return GroundCommand(kind, seq, name=name, tree=tree, sysid=_integer(msg, "sysid", 1, 255), subtree=subtree)


def _check_subtree(kind: str, subtree: object) -> None:
    if not isinstance(subtree, str) or not subtree or any(c in _NOT_IN_TREE_IDS for c in subtree):
        raise ValueError(f"{kind}: subtree {subtree!r}: expected a tree ID such as Search")


def designate_datagram(signer: StreamSigner, track_id: int, seq: int = 0, unix_time: float | None = None) -> bytes:
    """The signed datagram that designates radar track ``track_id``."""
    if isinstance(track_id, bool) or not isinstance(track_id, int) or not 0 <= track_id <= MAX_TRACK_ID:
        raise ValueError(f"track id {track_id!r}: expected an integer 0..{MAX_TRACK_ID}")
    t = time.time() if unix_time is None else unix_time
    return signer.sign(json_datagram("command", seq, t, {"command": "designate", "track_id": track_id}))


def retask_datagram(signer: StreamSigner, name: str, tree_text: str, sysid: int, seq: int = 0,
                    unix_time: float | None = None) -> bytes:
    """The signed datagram that retasks vehicle ``sysid`` with the tree file ``name`` of text ``tree_text``.

    Raises:
        ValueError: the tree does not fit one datagram.
    """
    t = time.time() if unix_time is None else unix_time
    return signer.sign(json_datagram("command", seq, t, {"command": "retask", "name": name, "tree": tree_text,
                                                         "sysid": int(sysid)}))


def replace_subtree_datagram(signer: StreamSigner, name: str, tree_text: str, sysid: int, subtree: str, seq: int = 0,
                             unix_time: float | None = None) -> bytes:
    """The signed datagram that replaces subtree ``subtree`` of vehicle ``sysid``'s running tree with the
    tree file ``name`` of text ``tree_text``.

    Raises:
        ValueError: ``subtree`` is not a tree ID, or the tree does not fit one datagram.
    """
    _check_subtree("replace_subtree", subtree)
    t = time.time() if unix_time is None else unix_time
    return signer.sign(json_datagram("command", seq, t, {"command": "replace_subtree", "name": name, "tree": tree_text,
                                                         "sysid": int(sysid), "subtree": subtree}))


@dataclass
class UplinkCounters:
    """What the receiver did with every datagram."""

    accepted: int = 0
    not_allowed: int = 0  # from a host outside ``allowed_hosts``
    malformed: int = 0  # signed, but not a command the aircraft knows
    auth: dict[str, int] = field(default_factory=dict)  # the verifier's drops: unsigned, forged, replayed

    def as_dict(self) -> dict[str, Any]:
        return {"accepted": self.accepted, "not_allowed": self.not_allowed, "malformed": self.malformed, **self.auth}


class UplinkReceiver:
    """Ground commands from a UDP port, each verified with ``key``; :meth:`poll` never blocks.

    Args:
        host, port: where to listen (port 0: any free one, see :attr:`address`).
        key: the 32-byte shared key (required: the uplink is never unsigned).
        allowed_hosts: source addresses believed (empty: any that signs correctly).
        max_per_poll: datagrams read per poll at most (a flood cannot stall the tick).
    """

    def __init__(self, host: str, port: int, key: bytes, *, allowed_hosts: Iterable[str] = (),
                 max_per_poll: int = 64) -> None:
        self.verifier = StreamVerifier(key)
        self.allowed_hosts = frozenset(allowed_hosts)
        self.max_per_poll = max_per_poll
        self.counters = UplinkCounters()
        self._queued: list[GroundCommand] = []  # believed and not yet taken, in the order they arrived
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self._sock.bind((host, port))

    @property
    def address(self) -> tuple[str, int]:
        return self._sock.getsockname()

    def take(self, *kinds: str) -> list[GroundCommand]:
        """The commands of these kinds received so far and not yet taken, in the order they arrived
        (polls first); the others stay for their consumers.

        Raises:
            ValueError: no kind, or one that is not in :data:`COMMANDS`.
        """
        unknown = [k for k in kinds if k not in COMMANDS]
        if not kinds or unknown:
            raise ValueError(f"take {', '.join(unknown) or '(no kind)'}: expected kinds among {', '.join(COMMANDS)}")
        self.poll()
        taken = [c for c in self._queued if c.kind in kinds]
        self._queued = [c for c in self._queued if c.kind not in kinds]
        return taken

    def poll(self) -> list[GroundCommand]:
        """Every believable command that arrived since the last poll, oldest first (each is also kept
        for :meth:`take` of its kind)."""
        out: list[GroundCommand] = []
        for _ in range(self.max_per_poll):
            try:
                data, (src, _) = self._sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as e:  # e.g. ICMP port unreachable reported on the socket: not a command
                log.debug("uplink receive: %s", e)
                break
            if self.allowed_hosts and src not in self.allowed_hosts:
                self.counters.not_allowed += 1
                continue
            payload = self.verifier.open(data)
            c = self.verifier.counters
            self.counters.auth = {"unsigned": c.unsigned, "forged": c.forged, "replayed": c.replayed}
            if payload is None:
                continue
            try:
                cmd = parse_command(payload)
            except ValueError as e:
                self.counters.malformed += 1
                log.warning("uplink: dropped a signed datagram from %s: %s", src, e)
                continue
            self.counters.accepted += 1
            what = f"track {cmd.track_id}" if cmd.kind == "designate" else f"{cmd.name} for vehicle {cmd.sysid}"
            if cmd.subtree is not None:
                what += f" (subtree {cmd.subtree})"
            log.info("uplink: %s %s from %s (seq %d)", cmd.kind, what, src, cmd.seq)
            self._queued.append(cmd)
            out.append(cmd)
        return out

    def close(self) -> None:
        self._sock.close()
