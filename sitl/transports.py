"""Loopback transports for the real-time simulator: ArduPilot SITL's UDP and TCP faces.

- :class:`UdpPort` binds ``127.0.0.1:<port>`` like ArduPilot's ``udpin``: each peer that sends it a
  datagram becomes a :class:`UdpPeer`, a link of its own (its own parser and streams upstream), until
  it is quiet for ``peer_timeout_s``; a client connects with pymavlink's ``udpout:127.0.0.1:<port>``
  (and must speak first, as every GCS does with its heartbeat). One peer's garbage cannot break
  another's packets.
- :class:`TcpServer` listens like SITL's ``tcp:127.0.0.1:5760`` and hands out one
  :class:`TcpClientPort` per accepted client, several at once, up to ``max_clients``; beyond that
  a client is accepted and closed at once, and the refusal logged.

Every port has the simulator's ``read() -> bytes`` / ``write(bytes)`` pair and never blocks. Wall
time (for forgetting quiet UDP peers) comes from an injected ``monotonic`` callable.
"""

from __future__ import annotations

import errno
import logging
import socket
import time
from typing import Callable

__all__ = ["UdpPeer", "UdpPort", "TcpServer", "TcpClientPort", "LOOPBACK"]

log = logging.getLogger(__name__)

LOOPBACK = "127.0.0.1"
_RECV_SIZE = 65535
_MAX_DATAGRAM = 8192  # split writes at this size; the client's parser is a stream parser
_MAX_TX_BACKLOG = 1 << 20  # bytes queued for a slow TCP client before it is dropped


class UdpPeer:
    """One UDP peer of a :class:`UdpPort`: its own receive buffer (so its own MAVLink parser and
    channel upstream), replies to its address only. ``closed`` once it has been quiet for the port's
    ``peer_timeout_s``."""

    def __init__(self, port: UdpPort, addr: tuple[str, int], now: float) -> None:
        self._port = port
        self.addr = addr
        self.heard_at = now
        self._rx = bytearray()
        self.closed = False

    def feed(self, data: bytes, now: float) -> None:
        self._rx += data
        self.heard_at = now

    def read(self) -> bytes:
        """Every datagram this peer sent since the last read, concatenated (whole MAVLink packets)."""
        self._port.pull()
        data = bytes(self._rx)
        self._rx.clear()
        return data

    def write(self, data: bytes) -> int:
        """Send ``data`` to this peer (split into datagrams of at most 8 KiB); a full buffer drops it."""
        if self.closed:
            return 0
        for i in range(0, len(data), _MAX_DATAGRAM):
            try:
                self._port.sock.sendto(data[i : i + _MAX_DATAGRAM], self.addr)
            except (BlockingIOError, InterruptedError):
                break  # the kernel buffer is full: drop, as a radio would
            except OSError as e:
                log.debug("udp send to %s failed: %s", self.addr, e)
                self.closed = True
                break
        return len(data)


class UdpPort:
    """A UDP socket on loopback, ArduPilot's ``udpin``: every peer that sends a datagram becomes a
    :class:`UdpPeer` with a link of its own, until it has been quiet for ``peer_timeout_s``.

    Args:
        port: local port (0 = pick a free one; see :attr:`port`).
        peer_timeout_s: forget a peer that has not sent anything for this long.
        max_peers: peers answered at once; datagrams from more are dropped and counted (``refused``).
        monotonic: wall-clock source for peer expiry.
    """

    def __init__(
        self,
        port: int = 14550,
        *,
        peer_timeout_s: float = 10.0,
        max_peers: int = 32,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.sock.bind((LOOPBACK, port))
        self.port: int = self.sock.getsockname()[1]
        self._peers: dict[tuple[str, int], UdpPeer] = {}
        self._new: list[UdpPeer] = []
        self._timeout_s = peer_timeout_s
        self.max_peers = max_peers
        self.refused = 0  # datagrams from peers beyond max_peers
        self._monotonic = monotonic

    @property
    def peers(self) -> list[tuple[str, int]]:
        """Addresses currently answered."""
        return [addr for addr, peer in self._peers.items() if not peer.closed]

    def pull(self) -> None:
        """Hand every waiting datagram to its peer (so the selector stops reporting it); forget quiet peers."""
        now = self._monotonic()
        while True:
            try:
                data, addr = self.sock.recvfrom(_RECV_SIZE)
            except (BlockingIOError, InterruptedError):
                break
            except ConnectionResetError:  # ICMP port unreachable from a peer that left
                continue
            peer = self._peers.get(addr)
            if peer is None:
                if len(self._peers) >= self.max_peers:
                    self.refused += 1
                    if self.refused in (1, 100, 10000):
                        log.warning("udp: %d peers already; datagrams from %s:%d refused (%d so far)",
                                    self.max_peers, *addr, self.refused)
                    continue
                peer = self._peers[addr] = UdpPeer(self, addr, now)
                self._new.append(peer)
            peer.feed(data, now)
        for addr, peer in list(self._peers.items()):
            if peer.closed or now - peer.heard_at > self._timeout_s:
                peer.closed = True
                del self._peers[addr]

    def accept(self) -> list[UdpPeer]:
        """Peers heard for the first time since the last call."""
        self.pull()
        new, self._new = self._new, []
        return new

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        self.sock.close()


class TcpClientPort:
    """One accepted TCP client; writes that the socket cannot take yet are queued (bounded)."""

    def __init__(self, sock: socket.socket, addr: tuple[str, int]) -> None:
        self.sock = sock
        self.addr = addr
        self.sock.setblocking(False)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._tx = bytearray()
        self._rx = bytearray()
        self.closed = False

    @property
    def tx_pending(self) -> int:
        """Bytes queued for the client that the socket has not taken yet."""
        return len(self._tx)

    def pull(self) -> None:
        """Move what the client sent into the receive buffer; a hang-up closes the port."""
        while not self.closed:
            try:
                data = self.sock.recv(_RECV_SIZE)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                self.close()
                return
            if not data:
                self.close()
                return
            self._rx += data

    def read(self) -> bytes:
        """Everything the client has sent since the last read."""
        self.pull()
        data = bytes(self._rx)
        self._rx.clear()
        return data

    def write(self, data: bytes) -> int:
        """Queue ``data`` and send what the socket takes now."""
        if self.closed:
            return 0
        self._tx += data
        self.flush()
        if len(self._tx) > _MAX_TX_BACKLOG:
            log.warning("tcp client %s is not reading; dropping it", self.addr)
            self.close()
        return len(data)

    def flush(self) -> None:
        """Send as much of the queue as the socket accepts without blocking."""
        while self._tx and not self.closed:
            try:
                sent = self.sock.send(self._tx)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                self.close()
                return
            del self._tx[:sent]

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self.sock.close()


class TcpServer:
    """A listening socket on loopback; :meth:`accept` returns newly connected clients, at most
    ``max_clients`` open at once (the caller says how many are open)."""

    def __init__(self, port: int = 5760, *, max_clients: int = 32) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((LOOPBACK, port))
        self.sock.listen(64)
        self.sock.setblocking(False)
        self.port: int = self.sock.getsockname()[1]
        self.max_clients = max_clients
        self.refused = 0  # clients closed at once because max_clients were connected

    def accept(self, open_clients: int = 0) -> list[TcpClientPort]:
        """Every client waiting to be accepted (none without blocking); beyond ``max_clients`` open,
        each is closed at once."""
        clients = []
        while True:
            try:
                sock, addr = self.sock.accept()
            except (BlockingIOError, InterruptedError):
                break
            except OSError as e:
                if e.errno in (errno.ECONNABORTED, errno.EPROTO):
                    continue
                if e.errno in (errno.EMFILE, errno.ENFILE):  # out of descriptors: refuse until some close
                    log.warning("tcp: out of file descriptors; not accepting for now")
                    break
                raise
            if open_clients + len(clients) >= self.max_clients:
                self.refused += 1
                sock.close()
                if self.refused in (1, 100, 10000):
                    log.warning("tcp: %d clients already; %s:%d refused (%d so far)", self.max_clients, *addr,
                                self.refused)
                continue
            clients.append(TcpClientPort(sock, addr))
        return clients

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        self.sock.close()
