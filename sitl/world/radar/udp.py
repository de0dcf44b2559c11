"""Sending radar datagrams over UDP, as the EchoGuard's ground software does (DESIGN §6)."""

from __future__ import annotations

import logging
import socket
from typing import Callable

__all__ = ["RadarUdpSender"]

log = logging.getLogger(__name__)


class RadarUdpSender:
    """Fire-and-forget datagrams to ``host:port``; a send that fails is logged and counted, not raised.
    ``sign`` (set it to a signer's ``sign``) wraps each datagram before it goes, as a radar feed that
    its receiver verifies (``chaser-bt sitl --radar-key``, ``chaser-bt run --radar-key``)."""

    def __init__(self, host: str, port: int, sign: Callable[[bytes], bytes] | None = None) -> None:
        self.address = (host, port)
        self.sign = sign
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sent = 0
        self.failed = 0

    def __call__(self, datagram: bytes) -> None:
        if self.sign is not None:
            datagram = self.sign(datagram)
        try:
            self._sock.sendto(datagram, self.address)
            self.sent += 1
        except OSError as e:  # nobody listening yet, buffer full: a radar does not care
            self.failed += 1
            log.debug("radar datagram not sent: %s", e)

    def close(self) -> None:
        self._sock.close()
