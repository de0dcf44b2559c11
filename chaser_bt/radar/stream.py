"""Reading the radar's datagram stream: check each datagram, drop and count the bad ones, never raise.

A flight must not end because a radar sent garbage (DESIGN §8). :class:`RadarStreamReader` turns
datagrams into :class:`~chaser_bt.radar.report.RadarScan` objects and counts what it drops:
malformed (not JSON, wrong fields), oversized, wrong schema version, out of order (a sequence
number not above the last one from the same radar, or a scan time that goes backwards).
A sequence number far below the last one (more than ``restart_gap``) is a radar that restarted:
it is accepted and the sequence starts again. A track the radar could not have reported (beyond
its :class:`RadarEnvelope`: a range of ten thousand kilometres, a speed of a jet) is dropped from
its scan and counted.

Anyone who can reach the radar's UDP port could otherwise cue the chase, so the feed can be
authenticated and pinned: with a :class:`~chaser_bt.ground.auth.StreamVerifier` (the ground
stream's HMAC, same key file as MAVLink signing) the reader believes only signed, fresh
datagrams; :class:`UdpDatagramSource` can accept datagrams only from the radar's own addresses.

Datagrams come from a :class:`DatagramSource`: :class:`UdpDatagramSource` (a non-blocking UDP
socket) or :class:`QueueDatagramSource` (an in-process queue the simulator pushes into).
"""

from __future__ import annotations

import collections
import dataclasses
import logging
import socket
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from chaser_bt.ground.auth import StreamVerifier
from chaser_bt.radar.report import RadarScan, ScanFormatError, decode_scan

__all__ = ["DropCounts", "RadarEnvelope", "RadarStreamReader", "DatagramSource", "UdpDatagramSource",
           "QueueDatagramSource"]

log = logging.getLogger(__name__)


@dataclass
class DropCounts:
    """How many datagrams were accepted and why the others were dropped."""

    accepted: int = 0
    malformed: int = 0
    oversized: int = 0
    wrong_version: int = 0
    out_of_order: int = 0
    unauthenticated: int = 0  # unsigned, forged or replayed, with a verifier set
    foreign_source: int = 0  # from an address the radar does not send from
    tracks_out_of_envelope: int = 0  # tracks (not datagrams) dropped from accepted scans

    @property
    def dropped(self) -> int:
        """Datagrams dropped whole."""
        return (self.malformed + self.oversized + self.wrong_version + self.out_of_order + self.unauthenticated
                + self.foreign_source)


@dataclass(frozen=True)
class RadarEnvelope:
    """What the radar can report; a track outside is a corrupt or forged report, not a target."""

    max_range_m: float = 20000.0  # small-drone surveillance radars see a few kilometres
    max_speed_mps: float = 150.0  # any velocity component

    def violation(self, track: Any) -> str | None:
        if track.range_m > self.max_range_m:
            return f"range {track.range_m:g} m beyond {self.max_range_m:g} m"
        if track.velocity is not None and float(np.max(np.abs(track.velocity))) > self.max_speed_mps:
            return f"velocity {track.velocity.tolist()} m/s beyond {self.max_speed_mps:g} m/s"
        return None


@dataclass
class RadarStreamReader:
    """Check datagrams one at a time; :meth:`accept` returns the scan or None (dropped, counted)."""

    restart_gap: int = 1000
    counts: DropCounts = field(default_factory=DropCounts)
    envelope: RadarEnvelope = field(default_factory=RadarEnvelope)
    verifier: StreamVerifier | None = None  # given: only signed, fresh datagrams are believed
    _last: dict[str, tuple[int, float]] = field(default_factory=dict)

    def accept(self, data: bytes) -> RadarScan | None:
        """The scan in ``data``, or None when it is dropped (see :attr:`counts`). Never raises."""
        if self.verifier is not None:
            opened = self.verifier.open(data)
            if opened is None:
                self.counts.unauthenticated += 1
                if self.counts.unauthenticated in (1, 100, 10000):
                    log.warning("radar datagram dropped: not signed with the radar's key (%d so far)",
                                self.counts.unauthenticated)
                return None
            data = opened
        try:
            scan = decode_scan(data)
        except ScanFormatError as e:
            setattr(self.counts, e.reason, getattr(self.counts, e.reason) + 1)
            log.debug("radar datagram dropped (%s): %s", e.reason, e)
            return None
        except Exception as e:  # defensive: nothing a datagram holds may end a flight
            self.counts.malformed += 1
            log.debug("radar datagram dropped (malformed): %s", e)
            return None
        last = self._last.get(scan.radar_id)
        if last is not None:
            last_seq, last_t = last
            restarted = scan.seq < last_seq - self.restart_gap
            if not restarted and (scan.seq <= last_seq or scan.t < last_t):
                self.counts.out_of_order += 1
                return None
        self._last[scan.radar_id] = (scan.seq, scan.t)
        self.counts.accepted += 1
        kept = tuple(tr for tr in scan.tracks if not self._outside(tr))
        return scan if len(kept) == len(scan.tracks) else dataclasses.replace(scan, tracks=kept)

    def _outside(self, track: Any) -> bool:
        why = self.envelope.violation(track)
        if why is not None:
            self.counts.tracks_out_of_envelope += 1
            log.warning("radar track %d dropped: %s (%d so far)", track.track_id, why, self.counts.tracks_out_of_envelope)
        return why is not None

    def accept_all(self, datagrams: list[bytes]) -> list[RadarScan]:
        """:meth:`accept` each datagram in turn; the scans that passed, in order."""
        return [s for s in (self.accept(d) for d in datagrams) if s is not None]


class DatagramSource(Protocol):
    """Where datagrams come from: :meth:`receive` returns what arrived since the last call."""

    def receive(self) -> list[bytes]: ...


class QueueDatagramSource:
    """An in-process datagram queue: the simulator :meth:`push`-es, the reader :meth:`receive`-s."""

    def __init__(self, maxlen: int = 10000) -> None:
        self._queue: collections.deque[bytes] = collections.deque(maxlen=maxlen)

    def push(self, data: bytes) -> None:
        self._queue.append(bytes(data))

    def receive(self) -> list[bytes]:
        out = list(self._queue)
        self._queue.clear()
        return out


class UdpDatagramSource:
    """A non-blocking UDP socket bound to ``host:port`` (port 0: any free port, see :attr:`port`).

    ``allowed_hosts``: accept datagrams only from these IP addresses (the radar's); the others are
    dropped and counted in ``counts.foreign_source``. None: from anyone.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, max_per_receive: int = 1000, *,
                 allowed_hosts: frozenset[str] | None = None, counts: DropCounts | None = None) -> None:
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self._sock.bind((host, port))
        self.max_per_receive = max_per_receive
        self.allowed_hosts = allowed_hosts
        self.counts = counts if counts is not None else DropCounts()

    @property
    def port(self) -> int:
        return int(self._sock.getsockname()[1])

    def receive(self) -> list[bytes]:
        out: list[bytes] = []
        while len(out) < self.max_per_receive:
            try:
                data, (sender, *_) = self._sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as e:  # e.g. ICMP port unreachable surfacing on some platforms
                log.debug("radar socket: %s", e)
                break
            if self.allowed_hosts is not None and sender not in self.allowed_hosts:
                self.counts.foreign_source += 1
                if self.counts.foreign_source in (1, 100, 10000):
                    log.warning("radar datagram from %s dropped: not the radar's address (%d so far)", sender,
                                self.counts.foreign_source)
                continue
            out.append(data)
        return out

    def close(self) -> None:
        self._sock.close()
