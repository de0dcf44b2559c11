"""A stock pymavlink client (mavutil) against the real-time server sees an ArduCopter.

The server runs in a thread on free loopback ports at a high speed-up; every duration the tests
reason about is simulated time, read from the vehicle's own time_boot_ms, never the wall clock.
"""

from __future__ import annotations

import contextlib
import queue
import threading

import pytest
from mavlink_gcs import mav, quick_scenario
from pymavlink import mavutil

from sitl.server import serve

WALL_TIMEOUT_S = 20.0  # generous bound on wall time for anything to show up


@contextlib.contextmanager
def running_server(scenario, speedup: float = 20.0):
    """Start :func:`serve` in a thread; yield its connection strings; stop and join it."""
    urls: queue.Queue = queue.Queue()
    stop = threading.Event()
    thread = threading.Thread(
        target=serve,
        args=(scenario,),
        kwargs=dict(speedup=speedup, udp_port=0, tcp_port=0, ready=urls.put, stop=stop),
        daemon=True,
    )
    thread.start()
    try:
        yield {u.split(":")[0]: u for u in urls.get(timeout=WALL_TIMEOUT_S)}
    finally:
        stop.set()
        thread.join(timeout=WALL_TIMEOUT_S)
        assert not thread.is_alive(), "serve() did not stop when asked"


def _connect(url: str):
    conn = mavutil.mavlink_connection(url, source_system=255, source_component=190)
    conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)  # udpin learns its peer
    assert conn.wait_heartbeat(timeout=WALL_TIMEOUT_S) is not None
    return conn


class _SimClock:
    """Reads the vehicle's clock from the telemetry a connection receives."""

    def __init__(self, conn) -> None:
        self.conn = conn
        self.t = 0.0
        self.texts: list[str] = []  # every STATUSTEXT seen

    def recv(self, timeout: float = 0.2):
        msg = self.conn.recv_match(blocking=True, timeout=timeout)
        boot_ms = getattr(msg, "time_boot_ms", None)
        if boot_ms is not None:
            self.t = max(self.t, boot_ms / 1000.0)
        if msg is not None and msg.get_type() == "STATUSTEXT":
            self.texts.append(msg.text)
        return msg

    def wait(self, predicate, sim_timeout_s: float, on_message=lambda: None):
        """Read messages until one satisfies ``predicate`` (None if ``sim_timeout_s`` passes first)."""
        end = self.t + sim_timeout_s
        while self.t < end:
            msg = self.recv()
            on_message()
            if msg is not None and predicate(msg):
                return msg
        return None


def test_ready_reports_the_bound_tcp_and_udp_connection_strings():
    with running_server(quick_scenario()) as urls:
        assert set(urls) == {"tcp", "udpout"}
        assert urls["tcp"].startswith("tcp:127.0.0.1:") and not urls["tcp"].endswith(":0")
        assert urls["udpout"].startswith("udpout:127.0.0.1:") and not urls["udpout"].endswith(":0")


def test_mavutil_over_tcp_names_every_mode_it_sets():
    with running_server(quick_scenario()) as urls:
        conn = _connect(urls["tcp"])
        assert conn.flightmode == "STABILIZE"
        assert conn.mav_type == mav.MAV_TYPE_OCTOROTOR
        clock = _SimClock(conn)
        clock.wait(lambda m: m.get_type() == "SYS_STATUS"
                   and m.onboard_control_sensors_health & mav.MAV_SYS_STATUS_PREARM_CHECK, 30.0)
        for name in ("GUIDED", "LOITER", "BRAKE", "ALT_HOLD", "RTL", "LAND"):
            conn.set_mode(conn.mode_mapping()[name])
            hb = clock.wait(lambda m: m.get_type() == "HEARTBEAT" and mavutil.mode_string_v10(m) == name, 5.0)
            assert hb is not None, f"mode {name} never showed in HEARTBEAT"
            assert conn.flightmode == name
        conn.close()


def test_arming_before_gps_fix_is_refused_over_udp_with_the_reason():
    scenario = quick_scenario(boot={"gps_fix_s": 600.0, "ekf_ready_s": 600.0, "prearm_ok_s": 600.0})
    with running_server(scenario) as urls:
        conn = _connect(urls["udpout"])
        clock = _SimClock(conn)
        conn.arducopter_arm()
        ack = clock.wait(lambda m: m.get_type() == "COMMAND_ACK" and m.command == mav.MAV_CMD_COMPONENT_ARM_DISARM, 10.0)
        assert ack is not None and ack.result == mav.MAV_RESULT_FAILED
        assert "PreArm: Need 3D Fix" in clock.texts
        assert not conn.motors_armed()
        conn.close()


def test_lost_gcs_heartbeat_makes_the_vehicle_rtl():
    with running_server(quick_scenario(), speedup=10.0) as urls:
        conn = _connect(urls["tcp"])
        clock = _SimClock(conn)
        last_beat = [0.0]

        def heartbeat_at_1hz() -> None:
            if clock.t - last_beat[0] >= 1.0:
                conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                last_beat[0] = clock.t

        assert clock.wait(lambda m: m.get_type() == "SYS_STATUS"
                          and m.onboard_control_sensors_health & mav.MAV_SYS_STATUS_PREARM_CHECK,
                          30.0, heartbeat_at_1hz) is not None
        conn.set_mode(conn.mode_mapping()["GUIDED"])
        conn.arducopter_arm()
        assert clock.wait(lambda m: m.get_type() == "COMMAND_ACK" and m.command == 400, 5.0, heartbeat_at_1hz).result == 0
        conn.mav.command_long_send(1, 1, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 10.0)
        assert clock.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT" and m.relative_alt > 8000,
                          20.0, heartbeat_at_1hz) is not None
        assert conn.flightmode == "GUIDED"
        silent_from = last_beat[0]
        rtl = clock.wait(lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode == 6, 15.0)
        assert rtl is not None and conn.flightmode == "RTL"
        assert 5.0 <= clock.t - silent_from <= 6.5  # FS_GCS_TIMEOUT 5 s (+ telemetry granularity)
        assert "GCS Failsafe" in clock.texts
        conn.close()


def test_udp_and_several_tcp_clients_are_served_at_once():
    with running_server(quick_scenario()) as urls:
        clients = [_connect(urls["tcp"]), _connect(urls["tcp"]), _connect(urls["udpout"])]
        for conn in clients:
            assert conn.recv_match(type="ATTITUDE", blocking=True, timeout=WALL_TIMEOUT_S) is not None
            assert conn.target_system == 1
        clients[1].close()  # one client leaving does not disturb the others
        for conn in (clients[0], clients[2]):
            conn.recv_match(type="HEARTBEAT", blocking=True, timeout=WALL_TIMEOUT_S)
            assert conn.recv_match(type="HEARTBEAT", blocking=True, timeout=WALL_TIMEOUT_S) is not None
            conn.close()


def test_speedup_must_be_positive():
    with pytest.raises(ValueError, match="speedup"):
        serve(quick_scenario(), speedup=0.0, udp_port=0, tcp_port=0)


def test_a_peer_sending_garbage_does_not_cost_another_udp_client_its_acks():
    # One parser per UDP peer: a 2-byte "\xfd\xff" (a MAVLink 2 start and a length) every few ms
    # from another peer must not swallow the real client's packets.
    import socket
    import time

    with running_server(quick_scenario(), speedup=5.0) as urls:
        conn = _connect(urls["udpout"])
        port = int(urls["udpout"].rsplit(":", 1)[1])
        noise = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        stop = threading.Event()

        def spam():
            while not stop.is_set():
                noise.sendto(b"\xfd\xff", ("127.0.0.1", port))
                time.sleep(0.002)

        spammer = threading.Thread(target=spam, daemon=True)
        spammer.start()
        try:
            acks = 0
            for _ in range(8):
                conn.mav.command_long_send(1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0, mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                                           0, 0, 0, 0, 0, 0)
                acks += conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=3.0) is not None
        finally:
            stop.set()
            spammer.join()
            noise.close()
        assert acks == 8


def test_clients_beyond_the_cap_are_refused_and_the_server_lives_on():
    import socket

    urls: queue.Queue = queue.Queue()
    stop = threading.Event()
    thread = threading.Thread(target=serve, args=(quick_scenario(),), daemon=True,
                              kwargs=dict(speedup=20.0, udp_port=0, tcp_port=0, ready=urls.put, stop=stop, max_clients=4))
    thread.start()
    socks = []
    try:
        tcp_port = int(next(u for u in urls.get(timeout=WALL_TIMEOUT_S) if u.startswith("tcp")).rsplit(":", 1)[1])
        for _ in range(1100):  # beyond select()'s 1024 descriptors, the limit the server once died on
            s = socket.create_connection(("127.0.0.1", tcp_port), timeout=WALL_TIMEOUT_S)
            socks.append(s)
        served, refused = 0, 0
        for s in socks[:8]:  # the first four are served; later ones were closed at once
            s.settimeout(WALL_TIMEOUT_S)
            try:
                data = s.recv(4096)
            except ConnectionResetError:
                data = b""
            served, refused = served + bool(data), refused + (not data)
        assert (served, refused) == (4, 4)
        assert thread.is_alive()
        conn = socks[0]  # a served client still gets its heartbeats
        conn.settimeout(WALL_TIMEOUT_S)
        assert conn.recv(4096)
    finally:
        for s in socks:
            s.close()
        stop.set()
        thread.join(timeout=WALL_TIMEOUT_S)
    assert not thread.is_alive()


def test_the_radar_feed_is_signed_with_the_key_run_verifies_it_with():
    """`chaser-bt sitl --radar-key` signs each radar datagram: a receiver with the key gets the scan,
    a receiver with another key gets nothing."""
    import dataclasses
    import socket

    from chaser_bt.ground.auth import StreamSigner, StreamVerifier
    from chaser_bt.radar.report import decode_scan
    from sitl.world.radar import RadarConfig

    ground = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    ground.bind(("127.0.0.1", 0))
    ground.settimeout(WALL_TIMEOUT_S)
    scenario = dataclasses.replace(quick_scenario(), radar=RadarConfig(quick_scenario().home, udp_port=ground.getsockname()[1]))
    key, stop = bytes(range(32)), threading.Event()
    thread = threading.Thread(target=serve, args=(scenario,), daemon=True,
                              kwargs=dict(speedup=20.0, udp_port=0, tcp_port=0, stop=stop, radar_sign=StreamSigner(key).sign))
    thread.start()
    try:
        datagram = ground.recv(65535)
    finally:
        stop.set()
        thread.join(timeout=WALL_TIMEOUT_S)
        ground.close()
    assert StreamVerifier(bytes(range(1, 33))).open(datagram) is None
    payload = StreamVerifier(key).open(datagram)
    assert payload is not None and decode_scan(payload).seq >= 0
