"""MAVLink 2 message signing: the key, the timestamp, and which messages are let in.

MAVLink 2 signs a packet with the first 6 bytes of SHA-256(key + header + payload + CRC + link id +
timestamp); the timestamp counts 10 µs since 2015-01-01 00:00 UTC and must grow on each
(link id, system, component) stream, which stops replays (mavlink.io, "Message Signing").
pymavlink does the arithmetic; this module holds the policy both ends of our link share:

- **Keys** come from a text file (:func:`load_key`): a line of exactly 64 hex digits is the
  32-byte key itself; any other first line is a passphrase, and the key is SHA-256 of its ASCII
  bytes, the convention of MAVProxy's ``signing setup PASSPHRASE``, so a vehicle set up with
  MAVProxy and this file agree.
- **Admission** (:class:`SigningGate`): a message is let in when its signature is good and its
  timestamp new, or when it is unsigned but of a kind ArduPilot accepts unsigned (RADIO_STATUS and
  RADIO, which telemetry radios inject: GCS_Signing.cpp ``accept_list``; MAVProxy allows the
  same). Everything else is rejected and counted, unsigned and wrongly signed (bad hash, another
  key, a replayed or stale timestamp) apart.
- The signature is checked **before** the replay window moves. pymavlink records a packet's
  timestamp before comparing hashes, so one forged packet with a far-future timestamp would shut
  out every genuine packet of that stream; the C library (mavlink_helpers.h) and ArduPilot compare
  the hash first, and so do we.

One :class:`SigningGate` may serve several parsers (the simulator's ports): they share the key,
the outgoing timestamp and one table of stream timestamps, as ArduPilot's channels share
``signing_streams``.
"""

from __future__ import annotations

import enum
import hashlib
import hmac
import os
import string
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

__all__ = [
    "ALLOWED_UNSIGNED", "EPOCH_2015_UNIX_S", "SigningConfig", "SigningCounters", "SigningGate", "SigningKeyError",
    "Verdict", "key_from_text", "load_key", "passphrase_key", "signing_timestamp",
]

EPOCH_2015_UNIX_S = 1420070400  # 2015-01-01 00:00:00 UTC, the signing timestamp's zero
TICKS_PER_S = 100_000  # the signing timestamp counts 10 µs
KEY_BYTES = 32
NEW_STREAM_WINDOW_TICKS = 6000 * 1000  # a stream first heard may lag our timestamp by 60 s (MAVLink spec)
# ArduPilot GCS_Signing.cpp accept_list: what SiK/RFD radios inject is accepted unsigned.
ALLOWED_UNSIGNED: frozenset[str] = frozenset({"RADIO_STATUS", "RADIO"})


class SigningKeyError(ValueError):
    """A key file that cannot give a 32-byte key (the message names the file and what is wrong)."""


def passphrase_key(passphrase: str) -> bytes:
    """SHA-256 of the passphrase's ASCII bytes: MAVProxy's ``signing setup`` key."""
    return hashlib.sha256(passphrase.encode("ascii")).digest()


def key_from_text(text: str, where: str = "key") -> bytes:
    """The key from a key file's text: 64 hex digits, else the first non-empty line as a passphrase.

    Raises:
        SigningKeyError: no non-empty line, or a passphrase that is not printable ASCII.
    """
    line = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    if not line:
        raise SigningKeyError(f"{where}: empty; expected 64 hex digits or a passphrase on the first line")
    if len(line) == 2 * KEY_BYTES and all(c in string.hexdigits for c in line):
        return bytes.fromhex(line)
    if not all(c in string.printable for c in line):
        raise SigningKeyError(
            f"{where}: line 1: a passphrase must be printable ASCII (MAVProxy hashes its ASCII bytes)")
    return passphrase_key(line)


def load_key(path: str | Path) -> bytes:
    """Read a 32-byte signing key from a key file (format in the module docstring).

    Raises:
        SigningKeyError: the file cannot be read or holds no usable key.
    """
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise SigningKeyError(f"{path}: cannot read the signing key ({e})") from e
    return key_from_text(text, str(path))


def signing_timestamp(unix_s: float) -> int:
    """The signing timestamp (10 µs ticks since 2015-01-01) of a Unix time; 0 before 2015."""
    return max(int((unix_s - EPOCH_2015_UNIX_S) * TICKS_PER_S), 0)


@dataclass(frozen=True)
class SigningConfig:
    """Signing on one link: the shared key (never shown in a repr), our link id, what passes unsigned."""

    key: bytes = field(repr=False)
    link_id: int = 0
    allow_unsigned: frozenset[str] = ALLOWED_UNSIGNED

    def __post_init__(self) -> None:
        if not isinstance(self.key, bytes) or len(self.key) != KEY_BYTES:
            raise ValueError(f"SigningConfig.key: expected {KEY_BYTES} bytes")
        if not 0 <= self.link_id <= 255:
            raise ValueError(f"SigningConfig.link_id = {self.link_id}: expected 0..255")
        unknown = [n for n in self.allow_unsigned if not hasattr(mavlink2, f"MAVLINK_MSG_ID_{n}")]
        if unknown:
            raise ValueError(f"SigningConfig.allow_unsigned: {', '.join(sorted(unknown))} not MAVLink message names")

    @classmethod
    def from_file(cls, path: str | Path, *, link_id: int = 0) -> SigningConfig:
        """A config with the key from ``path`` (see :func:`load_key`)."""
        return cls(load_key(path), link_id=link_id)


class Verdict(enum.Enum):
    """What a received message's signature says."""

    SIGNED = "signed"  # good signature, new timestamp
    UNSIGNED_ALLOWED = "unsigned_allowed"  # unsigned, of a kind accepted unsigned
    UNSIGNED = "unsigned"  # unsigned: rejected
    BAD_SIGNATURE = "bad_signature"  # signed with another key, tampered, replayed or stale: rejected

    @property
    def accepted(self) -> bool:
        return self in (Verdict.SIGNED, Verdict.UNSIGNED_ALLOWED)


@dataclass
class SigningCounters:
    """Received messages by verdict."""

    signed: int = 0
    unsigned_allowed: int = 0
    unsigned_rejected: int = 0
    bad_signature: int = 0

    @property
    def rejected(self) -> int:
        return self.unsigned_rejected + self.bad_signature


class SigningGate:
    """Signs what goes out and judges what comes in, for one key over one or more pymavlink parsers.

    Args:
        config: key, link id and the unsigned allow-list.
        timestamp: the first outgoing timestamp (:func:`signing_timestamp` of the current Unix time);
            it then grows by one per packet sent, by :meth:`advance`, and to the newest good
            timestamp received.
    """

    def __init__(self, config: SigningConfig, timestamp: int) -> None:
        self.config = config
        self.counters = SigningCounters()
        state = mavlink2.MAVLinkSigning()
        state.secret_key = config.key
        state.link_id = config.link_id
        state.timestamp = int(timestamp)
        state.sign_outgoing = True
        # pymavlink lets every message through; admit() decides, so rejections are counted by kind.
        state.allow_unsigned_callback = lambda mav, msg_id: True
        self.state = state

    @property
    def timestamp(self) -> int:
        """The next outgoing timestamp (10 µs ticks since 2015)."""
        return int(self.state.timestamp)

    def attach(self, mav: Any) -> None:
        """Make the pymavlink ``MAVLink`` object ``mav`` sign with this gate and check hash-first."""
        mav.signing = self.state
        mav.check_signature = lambda msgbuf, src_system, src_component: _check_signature(
            self.state, msgbuf, src_system, src_component)

    def advance(self, unix_s: float) -> None:
        """Keep the outgoing timestamp at least at the clock's (ArduPilot: update_signing_timestamp)."""
        self.state.timestamp = max(self.state.timestamp, signing_timestamp(unix_s))

    def verdict(self, msg: Any) -> Verdict:
        """Classify a message decoded by an attached parser (no counting)."""
        if msg.get_signed():
            return Verdict.SIGNED
        header = msg.get_header()
        if header is not None and header.incompat_flags & mavlink2.MAVLINK_IFLAG_SIGNED:
            return Verdict.BAD_SIGNATURE
        return Verdict.UNSIGNED_ALLOWED if msg.get_type() in self.config.allow_unsigned else Verdict.UNSIGNED

    def admit(self, msg: Any) -> bool:
        """Whether to act on ``msg``; counts it under its verdict."""
        v = self.verdict(msg)
        c = self.counters
        if v is Verdict.SIGNED:
            c.signed += 1
        elif v is Verdict.UNSIGNED_ALLOWED:
            c.unsigned_allowed += 1
        elif v is Verdict.UNSIGNED:
            c.unsigned_rejected += 1
        else:
            c.bad_signature += 1
        return v.accepted


def _check_signature(state: Any, msgbuf: bytearray, src_system: int, src_component: int) -> bool:
    """The MAVLink signature check, hash first (mavlink_helpers.h ``mavlink_signature_check``)."""
    if len(msgbuf) < 13:
        return False
    digest = hashlib.sha256(state.secret_key + bytes(msgbuf[:-6])).digest()[:6]
    if not hmac.compare_digest(digest, bytes(msgbuf[-6:])):
        return False
    link_id = msgbuf[-13]
    timestamp = int.from_bytes(bytes(msgbuf[-12:-6]), "little")
    stream = (link_id, src_system, src_component)
    last = state.stream_timestamps.get(stream)
    if last is None:
        if timestamp + NEW_STREAM_WINDOW_TICKS < state.timestamp:
            return False  # a new stream far behind our clock: a recording played back
    elif timestamp <= last:
        return False  # replayed or reordered
    state.stream_timestamps[stream] = timestamp
    state.timestamp = max(state.timestamp, timestamp)
    return True
