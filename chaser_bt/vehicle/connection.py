"""Opening a MAVLink connection from a connection string, bounded in time; and the in-process pipe.

The same link flies the built-in simulator, ArduPilot SITL and a real aircraft with nothing
changed but the string (DESIGN §5). Accepted forms, as pymavlink spells them:

- ``udpin:HOST:PORT`` / ``udp:HOST:PORT`` listen for the vehicle (ArduPilot's usual GCS output);
- ``udpout:HOST:PORT`` send to a vehicle that listens (our simulator, ``sim_vehicle.py --out``);
- ``tcp:HOST:PORT`` connect to a vehicle (ArduPilot SITL's 5760); ``tcpin:HOST:PORT`` listen;
- ``DEVICE[,BAUD]`` a serial port, e.g. ``/dev/ttyACM0`` or ``/dev/ttyUSB0,57600`` (needs pyserial).

mavutil's TCP client retries a refused connect with blocking sleeps and no overall bound, and a
blocking connect to an unroutable host can hang for minutes; :class:`_TcpClient` bounds both.
"""

from __future__ import annotations

import logging
import math
import os
import socket
import time
from typing import Callable

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402  (MAVLINK20 must be set first)

from chaser_bt.vehicle.errors import VehicleUnreachable  # noqa: E402
from chaser_bt.vehicle.pipe import PipeEnd  # noqa: E402

mavutil.set_dialect("ardupilotmega")

__all__ = ["open_connection", "PipeConnection", "DEFAULT_SERIAL_BAUD"]

log = logging.getLogger(__name__)

DEFAULT_SERIAL_BAUD = 115200
_TCP_RETRY_S = 0.5  # a SITL that is still starting refuses for a moment; try again this often
_SCHEMES = ("udpin:", "udpout:", "udp:", "tcpin:", "tcp:")


class PipeConnection(mavutil.mavfile):
    """A pymavlink ``mavfile`` over an in-memory :class:`PipeEnd` (rehearsals in one process)."""

    def __init__(self, end: PipeEnd, *, source_system: int, source_component: int) -> None:
        self.end = end
        self._pending: Callable[[], int] | None = getattr(end, "pending", None)  # an end that can tell
        self._closed = False
        super().__init__(None, "pipe", source_system=source_system, source_component=source_component, input=False)

    def recv(self, n: int | None = None) -> bytes:
        # Hands over everything waiting; the parser keeps what it has not consumed yet.
        return self.end.read()

    def recv_msg(self):  # noqa: ANN201 (pymavlink's message type)
        """The next message, or None; mavfile's, less its costly empty round when there is nothing to parse.

        With no bytes in the pipe and none left in the parser, mavfile.recv_msg would read nothing,
        parse nothing and return None; a link polls once per simulator step, mostly to find that.
        """
        if self._pending is not None and not self._pending() and self.mav.buf_len() == 0:
            return None
        return super().recv_msg()

    def write(self, buf: bytes) -> int:
        if self._closed:
            return 0
        return self.end.write(bytes(buf))

    def close(self) -> None:
        self._closed = True


class _TcpClient(mavutil.mavtcp):
    """mavutil's TCP client with a connect bounded by ``timeout_s`` and logging instead of print."""

    def __init__(
        self, address: str, *, timeout_s: float, monotonic: Callable[[], float], source_system: int,
        source_component: int,
    ) -> None:
        self._timeout_s = timeout_s
        self._monotonic = monotonic
        self._eof_logged = False
        super().__init__(address, autoreconnect=False, source_system=source_system,
                         source_component=source_component, retries=0)

    def do_connect(self) -> None:
        host, port = self.destination_addr
        deadline = self._monotonic() + self._timeout_s
        error: OSError | None = None
        for _ in range(math.ceil(self._timeout_s / _TCP_RETRY_S) + 1):  # bounded even if the clock stalls
            try:
                sock = socket.create_connection((host, port), timeout=max(deadline - self._monotonic(), 0.05))
            except OSError as e:
                error = e
                if self._monotonic() + _TCP_RETRY_S >= deadline:
                    break
                time.sleep(_TCP_RETRY_S)
                continue
            sock.setblocking(False)
            mavutil.set_close_on_exec(sock.fileno())
            sock.setsockopt(socket.SOL_TCP, socket.TCP_NODELAY, 1)
            self.port = sock
            return
        raise VehicleUnreachable(f"tcp:{host}:{port}: cannot connect ({error}) within {self._timeout_s:g} s")

    def handle_disconnect(self) -> None:
        self._lost("connection reset by the vehicle")

    def handle_eof(self) -> None:
        self._lost("connection closed by the vehicle")

    def _lost(self, what: str) -> None:
        self.portdead = True
        if not self._eof_logged:
            log.warning("%s: %s", self.address, what)
            self._eof_logged = True


def open_connection(
    url: str, *, source_system: int, source_component: int, timeout_s: float,
    monotonic: Callable[[], float] = time.monotonic,
) -> mavutil.mavfile:
    """Open ``url`` (forms in the module docstring) as a pymavlink ``mavfile``.

    Raises:
        ValueError: the string is not one of the accepted forms.
        VehicleUnreachable: the port cannot be opened (refused, unroutable, in use, no device).
    """
    ids = {"source_system": source_system, "source_component": source_component}
    scheme = next((s for s in _SCHEMES if url.startswith(s)), None)
    try:
        if scheme is None:
            return _open_serial(url, ids)
        address = url[len(scheme):]
        host, sep, port = address.rpartition(":")
        if not sep or not host or not port.isdigit():
            raise ValueError(f"connection string {url!r}: expected {scheme}HOST:PORT")
        if scheme == "tcp:":
            return _TcpClient(address, timeout_s=timeout_s, monotonic=monotonic, **ids)
        if scheme == "tcpin:":
            return mavutil.mavtcpin(address, **ids)
        return mavutil.mavudp(address, input=scheme != "udpout:", **ids)
    except OSError as e:  # refused, unroutable, address in use, no such device (SerialException too)
        raise VehicleUnreachable(f"{url}: {e}") from e


def _open_serial(url: str, ids: dict[str, int]) -> mavutil.mavfile:
    device, _, baud = url.partition(",")
    if ":" in device and not os.path.exists(device):
        raise ValueError(
            f"connection string {url!r}: expected udpin:/udpout:/udp:/tcp:/tcpin:HOST:PORT or a serial DEVICE[,BAUD]"
        )
    if baud and not baud.isdigit():
        raise ValueError(f"connection string {url!r}: baud rate {baud!r} is not a number")
    try:
        return mavutil.mavserial(device, baud=int(baud) if baud else DEFAULT_SERIAL_BAUD, **ids)
    except ImportError as e:  # pymavlink imports pyserial only when a serial port is opened
        raise VehicleUnreachable(f"{url}: serial links need pyserial ({e})") from e
