"""An in-memory, full-duplex byte pipe for running the simulator and a mission in one process.

A rehearsal still speaks encoded MAVLink through the same :class:`VehicleLink` a real flight
uses (DESIGN §2); only the wire is replaced. Each end has ``write(bytes)`` and a non-blocking
``read() -> bytes`` that drains whatever the other end wrote. The simulator accepts any object
with that pair of methods, so it needs nothing from this module.
"""

from __future__ import annotations

__all__ = ["PipeEnd", "byte_pipe"]


class PipeEnd:
    """One end of a :func:`byte_pipe`: bytes written here are read at the other end."""

    def __init__(self, inbox: bytearray, outbox: bytearray) -> None:
        self._inbox = inbox
        self._outbox = outbox
        self.connected = True

    def write(self, data: bytes) -> int:
        """Queue ``data`` for the other end; dropped silently while disconnected (a dead radio)."""
        if self.connected:
            self._outbox += data
        return len(data)

    def read(self) -> bytes:
        """Everything the other end has written since the last read (``b""`` when none)."""
        if not self._inbox:
            return b""
        data = bytes(self._inbox)
        self._inbox.clear()
        return data

    def pending(self) -> int:
        """Bytes waiting to be read at this end."""
        return len(self._inbox)


def byte_pipe() -> tuple[PipeEnd, PipeEnd]:
    """A connected pair of ends ``(a, b)``: ``a.write`` feeds ``b.read`` and vice versa."""
    a_to_b, b_to_a = bytearray(), bytearray()
    return PipeEnd(b_to_a, a_to_b), PipeEnd(a_to_b, b_to_a)
