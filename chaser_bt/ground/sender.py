"""Sending the ground stream over UDP without ever holding up the mission.

The socket is non-blocking and unconnected: a datagram the kernel cannot take at once is dropped,
and a ground station that is absent, unreachable or refusing costs nothing but a counted error.
Each kind of socket error is logged once (then only counted), so a missing ground station does
not flood the log at the tick rate.
"""

from __future__ import annotations

import errno
import logging
import socket
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from chaser_bt.ground.auth import OVERHEAD, StreamSigner
from chaser_bt.ground.protocol import MAX_DATAGRAM, Box, chunk_frame, draw_boxes, encode_jpeg, json_datagram

__all__ = ["GroundSender", "SenderCounters"]

log = logging.getLogger(__name__)

SEND_BUFFER_BYTES = 1 << 20


@dataclass
class SenderCounters:
    """What went out and what did not."""

    datagrams: int = 0
    bytes: int = 0
    messages: int = 0  # JSON messages sent whole
    frames: int = 0  # video frames whose every chunk was sent
    errors: int = 0  # datagrams the socket refused (no route, buffer full, ...): dropped

    def as_dict(self) -> dict[str, int]:
        return dict(vars(self))


class GroundSender:
    """Sends ground-stream messages (:mod:`chaser_bt.ground.protocol`) to ``host:port`` over UDP.

    Args:
        host: the ground station's address (name or IP; resolved once, here).
        port: its UDP port.
        max_datagram: largest datagram sent (video is chunked to fit, signature included).
        signer: signs every datagram (:mod:`chaser_bt.ground.auth`); None: the stream is unsigned.

    Raises:
        ValueError: the host does not resolve or the port is outside 1..65535.
    """

    def __init__(self, host: str, port: int, *, max_datagram: int = MAX_DATAGRAM,
                 signer: StreamSigner | None = None) -> None:
        if not 1 <= int(port) <= 65535:
            raise ValueError(f"ground port {port}: expected 1..65535")
        try:
            family, _, _, _, addr = socket.getaddrinfo(host, int(port), type=socket.SOCK_DGRAM)[0]
        except (socket.gaierror, UnicodeError) as e:
            raise ValueError(f"ground host {host!r} does not resolve: {e}") from e
        self.address = addr
        self.max_datagram = max_datagram
        self.signer = signer
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        # A video frame leaves as a burst of chunks: give the kernel room for a few of them.
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_BYTES)
        self.counters = SenderCounters()
        self._seq = 0
        self._frame_id = 0
        self._logged: set[int] = set()

    def send_message(self, kind: str, t: float, body: dict[str, Any]) -> bool:
        """One JSON message; whether it left (False: dropped and counted)."""
        data = json_datagram(kind, self._seq, t, body)
        self._seq += 1
        ok = self._send(data)
        self.counters.messages += ok
        return ok

    def send_frame(self, image: np.ndarray, t: float, boxes: Sequence[Box] = (), quality: int = 70) -> bool:
        """One video frame with ``boxes`` drawn, JPEG at ``quality``, chunked; whether every chunk left."""
        jpeg = encode_jpeg(draw_boxes(image, boxes) if boxes else image, quality)
        room = self.max_datagram - (OVERHEAD if self.signer is not None else 0)
        chunks = chunk_frame(jpeg, self._frame_id, t, room)
        self._frame_id = (self._frame_id + 1) & 0xFFFFFFFF
        ok = True
        for chunk in chunks:
            if not self._send(chunk):
                ok = False
                break  # the rest of this frame is useless to the ground
        self.counters.frames += ok
        return ok

    def close(self) -> None:
        self.sock.close()

    def _send(self, data: bytes) -> bool:
        if self.signer is not None:
            data = self.signer.sign(data)
        try:
            self.sock.sendto(data, self.address)
        except OSError as e:  # BlockingIOError (buffer full), ECONNREFUSED, ENETUNREACH, EMSGSIZE, ...
            self.counters.errors += 1
            code = e.errno if e.errno is not None else -1
            if code not in self._logged:
                self._logged.add(code)
                log.warning("ground stream to %s:%s: %s (%s); dropping, counted from now on", self.address[0],
                            self.address[1], e.strerror or e, errno.errorcode.get(code, code))
            return False
        self.counters.datagrams += 1
        self.counters.bytes += len(data)
        return True
