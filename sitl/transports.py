"""Loopback transports for the real-time simulator: ArduPilot SITL's UDP and TCP faces.

- :class:`UdpPort` binds ``127.0.0.1:<port>`` like ArduPilot's ``udpin``: it answers every peer that
  has sent it a datagram within ``peer_timeout_s``; a client connects with pymavlink's
  ``udpout:127.0.0.1:<port>`` (and must speak first, as every GCS does with its heartbeat).
- :class:`TcpServer` listens like SITL's ``tcp:127.0.0.1:5760`` and hands out one
  :class:`TcpClientPort` per accepted client, several at once.

Every port has the simulator's ``read() -> bytes`` / ``write(bytes)`` pair and never blocks. Wall
time (for forgetting quiet UDP peers) comes from an injected ``monotonic`` callable.
"""

from __future__ import annotations

import errno
import logging
import socket
import time
from typing import Callable

__all__ = ["UdpPort", "TcpServer", "TcpClientPort", "LOOPBACK"]

log = logging.getLogger(__name__)

LOOPBACK = "127.0.0.1"
_RECV_SIZE = 65535
_MAX_DATAGRAM = 8192  # split writes at this size; the client's parser is a stream parser
_MAX_TX_BACKLOG = 1 << 20  # bytes queued for a slow TCP client before it is dropped


class UdpPort:
    """A UDP socket on loopback that replies to every recent peer.

    Args:
        port: local port (0 = pick a free one; see :attr:`port`).
        peer_timeout_s: forget a peer that has not sent anything for this long.
        monotonic: wall-clock source for peer expiry.
    """

    def __init__(
        self,
        port: int = 14550,
        *,
        peer_timeout_s: float = 10.0,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.sock.bind((LOOPBACK, port))
        self.port: int = self.sock.getsockname()[1]
        self._peers: dict[tuple[str, int], float] = {}
        self._timeout_s = peer_timeout_s
        self._monotonic = monotonic
        self._rx = bytearray()

    @property
    def peers(self) -> list[tuple[str, int]]:
        """Addresses currently answered."""
        return list(self._peers)

    def pull(self) -> None:
        """Move every waiting datagram into the receive buffer (so select() stops reporting it)."""
        now = self._monotonic()
        while True:
            try:
                data, addr = self.sock.recvfrom(_RECV_SIZE)
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionResetError:  # ICMP port unreachable from a peer that left
                continue
            self._peers[addr] = now
            self._rx += data

    def read(self) -> bytes:
        """Every datagram received so far, concatenated (datagrams hold whole MAVLink packets)."""
        self.pull()
        data = bytes(self._rx)
        self._rx.clear()
        return data

    def write(self, data: bytes) -> int:
        """Send ``data`` to every peer heard from within the timeout; dead peers are forgotten."""
        now = self._monotonic()
        for addr, seen in list(self._peers.items()):
            if now - seen > self._timeout_s:
                del self._peers[addr]
                continue
            for i in range(0, len(data), _MAX_DATAGRAM):
                try:
                    self.sock.sendto(data[i : i + _MAX_DATAGRAM], addr)
                except (BlockingIOError, InterruptedError):
                    break  # the kernel buffer is full: drop, as a radio would
                except OSError as e:
                    log.debug("udp send to %s failed: %s", addr, e)
                    self._peers.pop(addr, None)
                    break
        return len(data)

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
    """A listening socket on loopback; :meth:`accept` returns newly connected clients."""

    def __init__(self, port: int = 5760) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((LOOPBACK, port))
        self.sock.listen(8)
        self.sock.setblocking(False)
        self.port: int = self.sock.getsockname()[1]

    def accept(self) -> list[TcpClientPort]:
        """Every client waiting to be accepted (none without blocking)."""
        clients = []
        while True:
            try:
                sock, addr = self.sock.accept()
            except (BlockingIOError, InterruptedError):
                break
            except OSError as e:
                if e.errno in (errno.ECONNABORTED, errno.EPROTO):
                    continue
                raise
            clients.append(TcpClientPort(sock, addr))
        return clients

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        self.sock.close()
