"""The ground stream signed: an HMAC on every datagram, so a receiver drops forged and replayed ones.

The key is the one MAVLink signing uses, in the same key file (64 hex digits, or a passphrase
hashed as MAVProxy does: :func:`chaser_bt.vehicle.signing.load_key`). A signed datagram is the
plain one (a JSON message or a video chunk, :mod:`chaser_bt.ground.protocol`) behind a 30-byte
header, little-endian, Python ``struct`` format ``<4sBBQ`` then 16 bytes:

====== ======= ==========================================================================
magic  4 bytes ``CBTS``
ver    uint8   ``1``
link   uint8   the sender's link id (0-255): one timestamp sequence per link id
stamp  uint64  MAVLink signing's timestamp: 10 µs ticks since 2015-01-01 UTC, strictly
               increasing per link id (the sender starts at its Unix time, then +1 or more)
mac    16 B    HMAC-SHA256(key, magic..stamp + payload), first 16 bytes
====== ======= ==========================================================================

As in MAVLink 2 signing (which this follows, with a full HMAC in place of its 48-bit hash): a
receiver believes a datagram only when its MAC checks out and its timestamp is newer than the last
one it believed from that link id; a link id heard for the first time must be within
``max_skew_s`` of the receiver's own clock, so a recording replayed later is refused too. Unsigned
datagrams are dropped when a key is set. Every drop is counted by kind.
"""

from __future__ import annotations

import hashlib
import hmac
import struct
import time
from dataclasses import dataclass
from typing import Callable

from chaser_bt.vehicle.signing import KEY_BYTES, TICKS_PER_S, signing_timestamp

__all__ = ["AUTH_HEADER", "AUTH_MAGIC", "MAC_BYTES", "StreamSigner", "StreamVerifier", "VerifierCounters"]

AUTH_MAGIC = b"CBTS"
AUTH_VERSION = 1
AUTH_HEADER = struct.Struct("<4sBBQ")  # magic, version, link id, timestamp; the MAC follows
MAC_BYTES = 16
OVERHEAD = AUTH_HEADER.size + MAC_BYTES  # 30 bytes per datagram


def _check_key(key: bytes) -> bytes:
    if not isinstance(key, bytes) or len(key) != KEY_BYTES:
        raise ValueError(f"ground-stream key: expected {KEY_BYTES} bytes (a MAVLink signing key)")
    return key


def _mac(key: bytes, header: bytes, payload: bytes) -> bytes:
    return hmac.new(key, header + payload, hashlib.sha256).digest()[:MAC_BYTES]


class StreamSigner:
    """Signs datagrams for one link id; timestamps never repeat and never go back.

    Args:
        key: the 32-byte shared key.
        link_id: this sender's link id (0-255).
        unix_time: the wall clock the timestamps follow (injectable for tests).
    """

    def __init__(self, key: bytes, link_id: int = 0, *, unix_time: Callable[[], float] = time.time) -> None:
        if not 0 <= link_id <= 255:
            raise ValueError(f"ground-stream link id {link_id}: expected 0..255")
        self._key = _check_key(key)
        self.link_id = link_id
        self._unix_time = unix_time
        self._last = 0

    def sign(self, payload: bytes) -> bytes:
        """The signed datagram carrying ``payload``."""
        self._last = max(self._last + 1, signing_timestamp(self._unix_time()))
        header = AUTH_HEADER.pack(AUTH_MAGIC, AUTH_VERSION, self.link_id, self._last)
        return header + _mac(self._key, header, payload) + payload


@dataclass
class VerifierCounters:
    """What a receiver believed and what it dropped, by why."""

    accepted: int = 0
    unsigned: int = 0  # no signature header although a key is set
    forged: int = 0  # malformed header, wrong version or a MAC that does not check out
    replayed: int = 0  # a good MAC but a timestamp not newer than the last believed (or too old)

    @property
    def dropped(self) -> int:
        return self.unsigned + self.forged + self.replayed


class StreamVerifier:
    """The receiver's side: :meth:`open` a datagram to its payload, or None (dropped and counted).

    Args:
        key: the 32-byte shared key.
        max_skew_s: a link id heard for the first time must be stamped within this of
            ``unix_time()``; None: accept any first timestamp (no clock shared with the sender).
        unix_time: the receiver's wall clock.
    """

    def __init__(self, key: bytes, *, max_skew_s: float | None = 60.0,
                 unix_time: Callable[[], float] = time.time) -> None:
        self._key = _check_key(key)
        self.max_skew_s = max_skew_s
        self._unix_time = unix_time
        self._last: dict[int, int] = {}
        self.counters = VerifierCounters()

    def open(self, datagram: bytes) -> bytes | None:
        """The payload of a genuine, fresh datagram; None for anything else (counted)."""
        if datagram[:4] != AUTH_MAGIC:
            self.counters.unsigned += 1
            return None
        if len(datagram) < OVERHEAD:
            self.counters.forged += 1
            return None
        _, version, link_id, stamp = AUTH_HEADER.unpack_from(datagram)
        header, mac = datagram[:AUTH_HEADER.size], datagram[AUTH_HEADER.size:OVERHEAD]
        payload = datagram[OVERHEAD:]
        if version != AUTH_VERSION or not hmac.compare_digest(mac, _mac(self._key, header, payload)):
            self.counters.forged += 1
            return None
        last = self._last.get(link_id)
        if last is None:
            if self.max_skew_s is not None:
                skew_s = abs(stamp - signing_timestamp(self._unix_time())) / TICKS_PER_S
                if skew_s > self.max_skew_s:
                    self.counters.replayed += 1
                    return None
        elif stamp <= last:
            self.counters.replayed += 1
            return None
        self._last[link_id] = stamp
        self.counters.accepted += 1
        return payload
