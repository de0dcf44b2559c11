"""Reading the radar's datagram stream: check each datagram, drop and count the bad ones, never raise.

A flight must not end because a radar sent garbage (DESIGN §8). :class:`RadarStreamReader` turns
datagrams into :class:`~chaser_bt.radar.report.RadarScan` objects and counts what it drops:
malformed (not JSON, wrong fields), oversized, wrong schema version, out of order (a sequence
number not above the last one from the same radar, or a scan time that goes backwards).
A sequence number far below the last one (more than ``restart_gap``) is a radar that restarted:
it is accepted and the sequence starts again.

Datagrams come from a :class:`DatagramSource`: :class:`UdpDatagramSource` (a non-blocking UDP
socket) or :class:`QueueDatagramSource` (an in-process queue the simulator pushes into).
"""

from __future__ import annotations

import collections
import logging
import socket
from dataclasses import dataclass, field
from typing import Protocol

from chaser_bt.radar.report import RadarScan, ScanFormatError, decode_scan

__all__ = ["DropCounts", "RadarStreamReader", "DatagramSource", "UdpDatagramSource", "QueueDatagramSource"]

log = logging.getLogger(__name__)


@dataclass
class DropCounts:
    """How many datagrams were accepted and why the others were dropped."""

    accepted: int = 0
    malformed: int = 0
    oversized: int = 0
    wrong_version: int = 0
    out_of_order: int = 0

    @property
    def dropped(self) -> int:
        return self.malformed + self.oversized + self.wrong_version + self.out_of_order


@dataclass
class RadarStreamReader:
    """Check datagrams one at a time; :meth:`accept` returns the scan or None (dropped, counted)."""

    restart_gap: int = 1000
    counts: DropCounts = field(default_factory=DropCounts)
    _last: dict[str, tuple[int, float]] = field(default_factory=dict)

    def accept(self, data: bytes) -> RadarScan | None:
        """The scan in ``data``, or None when it is dropped (see :attr:`counts`). Never raises."""
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
        return scan

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
    """A non-blocking UDP socket bound to ``host:port`` (port 0: any free port, see :attr:`port`)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0, max_per_receive: int = 1000) -> None:
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self._sock.bind((host, port))
        self.max_per_receive = max_per_receive

    @property
    def port(self) -> int:
        return int(self._sock.getsockname()[1])

    def receive(self) -> list[bytes]:
        out: list[bytes] = []
        while len(out) < self.max_per_receive:
            try:
                data, _ = self._sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as e:  # e.g. ICMP port unreachable surfacing on some platforms
                log.debug("radar socket: %s", e)
                break
            out.append(data)
        return out

    def close(self) -> None:
        self._sock.close()
