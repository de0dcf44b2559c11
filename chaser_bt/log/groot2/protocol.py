"""Groot2's monitor protocol, as BehaviorTree.CPP 4.10 speaks it (``groot2_protocol.h``): pure byte functions.

Every exchange is a multipart ZeroMQ request/reply on the server port (default 1667). The first
part of a request is a 6-byte header, ``protocol`` (u8, 2), ``type`` (u8, an ASCII letter) and
``unique_id`` (u32, little-endian: BT.CPP ``memcpy``\\s it on x86/ARM); the reply's first part is the
same 6 bytes (protocol set to 2) followed by the 16-byte tree UUID, one random version-4 UUID per
publisher. Failures are a two-part reply ``b"error"``, message. The payloads:

- FULLTREE (``T``): the tree as XML, written as ``WriteTreeToXML(tree, true, true)`` does;
- STATUS (``S``): 3 bytes per node, uid (u16 LE) and status (u8), see :class:`NodeStatus`;
- GET_TRANSITIONS (``t``): 9 bytes per transition, the first 6 bytes of the u64 microseconds since
  recording started, uid (u16), new status (u8);
- TOGGLE_RECORDING (``r``, second part ``start``/``stop``): ``start`` answers the wall time in
  microseconds since the epoch, as decimal text.

The publisher port (server port + 1) carries only BREAKPOINT_REACHED notices in 4.10.
"""

from __future__ import annotations

import enum
import struct
import uuid
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

__all__ = [
    "PROTOCOL_ID",
    "DEFAULT_PORT",
    "REQUEST_HEADER_SIZE",
    "REPLY_HEADER_SIZE",
    "IDLE_FROM",
    "RequestType",
    "NodeStatus",
    "ProtocolError",
    "RequestHeader",
    "ReplyHeader",
    "Transition",
    "encode_request_header",
    "decode_request_header",
    "encode_reply_header",
    "decode_reply_header",
    "encode_statuses",
    "decode_statuses",
    "encode_transitions",
    "decode_transitions",
    "error_reply",
    "new_tree_id",
]

PROTOCOL_ID = 2
#: BT.CPP's ``Groot2Publisher(tree, server_port = 1667)``; the publisher socket is one above.
DEFAULT_PORT = 1667
REQUEST_HEADER_SIZE = 6
REPLY_HEADER_SIZE = REQUEST_HEADER_SIZE + 16
#: A node reset to IDLE is reported as ``IDLE_FROM + previous status`` (12: idle after SUCCESS).
IDLE_FROM = 10

_HEADER = struct.Struct("<BBI")
_STATUS = struct.Struct("<HB")
_TRANSITION_TAIL = struct.Struct("<HB")
_TIMESTAMP_BYTES = 6


class RequestType(enum.IntEnum):
    """``BT::Monitor::RequestType``: the request's second header byte."""

    FULLTREE = ord("T")
    STATUS = ord("S")
    BLACKBOARD = ord("B")
    HOOK_INSERT = ord("I")
    HOOK_REMOVE = ord("R")
    BREAKPOINT_REACHED = ord("N")
    BREAKPOINT_UNLOCK = ord("U")
    HOOKS_DUMP = ord("D")
    REMOVE_ALL_HOOKS = ord("A")
    DISABLE_ALL_HOOKS = ord("X")
    TOGGLE_RECORDING = ord("r")
    GET_TRANSITIONS = ord("t")
    UNDEFINED = 0


class NodeStatus(enum.IntEnum):
    """``BT::NodeStatus``."""

    IDLE = 0
    RUNNING = 1
    SUCCESS = 2
    FAILURE = 3
    SKIPPED = 4


class ProtocolError(ValueError):
    """Bytes that are not a message of this protocol (wrong size)."""


@dataclass(frozen=True)
class RequestHeader:
    """The first part of a request; a reply echoes ``type`` and ``unique_id``."""

    type: int
    unique_id: int
    protocol: int = PROTOCOL_ID


@dataclass(frozen=True)
class ReplyHeader:
    """The first part of a reply: the request's header and the 16-byte id of the tree."""

    request: RequestHeader
    tree_id: bytes


@dataclass(frozen=True)
class Transition:
    """One recorded status change: microseconds since recording started, node uid, new status."""

    timestamp_us: int
    uid: int
    status: int


def encode_request_header(header: RequestHeader) -> bytes:
    return _HEADER.pack(header.protocol, header.type, header.unique_id)


def decode_request_header(data: bytes) -> RequestHeader:
    """Raises ProtocolError unless ``data`` is exactly 6 bytes (BT.CPP: "wrong request header")."""
    if len(data) != REQUEST_HEADER_SIZE:
        raise ProtocolError(f"a request header is {REQUEST_HEADER_SIZE} bytes, got {len(data)}")
    protocol, type_, unique_id = _HEADER.unpack(data)
    return RequestHeader(type_, unique_id, protocol)


def encode_reply_header(header: ReplyHeader) -> bytes:
    if len(header.tree_id) != 16:
        raise ValueError(f"the tree id is 16 bytes, got {len(header.tree_id)}")
    return encode_request_header(header.request) + bytes(header.tree_id)


def decode_reply_header(data: bytes) -> ReplyHeader:
    if len(data) != REPLY_HEADER_SIZE:
        raise ProtocolError(f"a reply header is {REPLY_HEADER_SIZE} bytes, got {len(data)}")
    return ReplyHeader(decode_request_header(data[:REQUEST_HEADER_SIZE]), bytes(data[REQUEST_HEADER_SIZE:]))


def encode_statuses(pairs: Iterable[tuple[int, int]]) -> bytes:
    """(uid, status code) pairs, in the publisher's node order, as the STATUS payload."""
    return b"".join(_STATUS.pack(uid, status) for uid, status in pairs)


def decode_statuses(data: bytes) -> list[tuple[int, int]]:
    if len(data) % _STATUS.size:
        raise ProtocolError(f"a STATUS payload is a multiple of {_STATUS.size} bytes, got {len(data)}")
    return [_STATUS.unpack_from(data, i) for i in range(0, len(data), _STATUS.size)]


def encode_transitions(transitions: Sequence[Transition]) -> bytes:
    """The GET_TRANSITIONS payload: a 48-bit timestamp, uid and status per transition."""
    out = bytearray()
    for t in transitions:
        out += (t.timestamp_us & (1 << 48) - 1).to_bytes(_TIMESTAMP_BYTES, "little")
        out += _TRANSITION_TAIL.pack(t.uid, t.status)
    return bytes(out)


def decode_transitions(data: bytes) -> list[Transition]:
    size = _TIMESTAMP_BYTES + _TRANSITION_TAIL.size
    if len(data) % size:
        raise ProtocolError(f"a GET_TRANSITIONS payload is a multiple of {size} bytes, got {len(data)}")
    out = []
    for i in range(0, len(data), size):
        timestamp = int.from_bytes(data[i:i + _TIMESTAMP_BYTES], "little")
        uid, status = _TRANSITION_TAIL.unpack_from(data, i + _TIMESTAMP_BYTES)
        out.append(Transition(timestamp, uid, status))
    return out


def error_reply(message: str) -> list[bytes]:
    """BT.CPP's ``sendErrorReply``: the parts ``error`` and the message (no header)."""
    return [b"error", message.encode("utf-8")]


def new_tree_id() -> bytes:
    """A random version-4 UUID's 16 bytes (BT.CPP's ``CreateRandomUUID``: same version and variant bits)."""
    return uuid.uuid4().bytes
