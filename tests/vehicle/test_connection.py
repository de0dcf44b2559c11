"""Connection strings over real loopback sockets: connect succeeds on a heartbeat, fails bounded."""

from __future__ import annotations

import os
import socket
import threading
import time

os.environ["MAVLINK20"] = "1"

import pytest  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from chaser_bt.vehicle import LinkConfig, VehicleLink, VehicleUnreachable  # noqa: E402

FAST = LinkConfig(connect_timeout_s=1.5)


def _free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _heartbeat_bytes() -> bytes:
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    return mav.heartbeat_encode(mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, mavlink2.MAV_STATE_STANDBY).pack(mav)


def _connect_bounded(url: str, config: LinkConfig) -> float:
    t0 = time.monotonic()
    with pytest.raises(VehicleUnreachable, match=url.split(":")[0]):
        VehicleLink.connect(url, config)
    return time.monotonic() - t0


def test_tcp_to_a_closed_port_is_unreachable_within_the_connect_timeout():
    elapsed = _connect_bounded(f"tcp:127.0.0.1:{_free_port(socket.SOCK_STREAM)}", FAST)
    assert elapsed < FAST.connect_timeout_s + 2.0  # a bound on hanging, not a speed figure


def test_udpout_to_nobody_is_unreachable_within_the_connect_timeout():
    elapsed = _connect_bounded(f"udpout:127.0.0.1:{_free_port(socket.SOCK_DGRAM)}", FAST)
    assert elapsed < FAST.connect_timeout_s + 2.0


@pytest.mark.slow
def test_default_connect_gives_up_within_10_s():
    elapsed = _connect_bounded(f"tcp:127.0.0.1:{_free_port(socket.SOCK_STREAM)}", LinkConfig())
    assert elapsed < 12.0


@pytest.mark.parametrize("url", ["udpout:localhost", "tcp:127.0.0.1:port", "http://x:1", "127.0.0.1:14550"])
def test_malformed_connection_strings_are_value_errors(url):
    with pytest.raises(ValueError, match="connection string"):
        VehicleLink.connect(url, FAST)


def test_udpin_connects_on_the_first_autopilot_heartbeat_and_asks_for_streams():
    port = _free_port(socket.SOCK_DGRAM)
    stop = threading.Event()
    got: list[bytes] = []

    def vehicle() -> None:  # ArduPilot-style: sends heartbeats to the GCS port, reads what comes back
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.settimeout(0.05)
            while not stop.is_set():
                s.sendto(_heartbeat_bytes(), ("127.0.0.1", port))
                try:
                    got.append(s.recv(4096))
                except OSError:
                    pass

    t = threading.Thread(target=vehicle, daemon=True)
    t.start()
    try:
        link = VehicleLink.connect(f"udpin:127.0.0.1:{port}", LinkConfig(connect_timeout_s=5.0))
        assert (link.target_sysid, link.state.mode) == (1, "GUIDED")
        kinds: set[str] = set()
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and not kinds >= {"HEARTBEAT", "COMMAND_LONG"}:
            link.poll()
            time.sleep(0.02)
            kinds = {m.get_type() for m in mavlink2.MAVLink(None).parse_buffer(b"".join(got)) or []}
        link.close()
    finally:
        stop.set()
        t.join()
    assert kinds >= {"HEARTBEAT", "COMMAND_LONG"}


def test_tcp_connects_to_a_listening_vehicle():
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = server.getsockname()[1]
    stop = threading.Event()

    def vehicle() -> None:
        conn, _ = server.accept()
        with conn:
            while not stop.is_set():
                conn.sendall(_heartbeat_bytes())
                time.sleep(0.05)

    t = threading.Thread(target=vehicle, daemon=True)
    t.start()
    try:
        link = VehicleLink.connect(f"tcp:127.0.0.1:{port}", LinkConfig(connect_timeout_s=5.0))
        assert link.target_sysid == 1
        link.close()
    finally:
        stop.set()
        t.join()
        server.close()
