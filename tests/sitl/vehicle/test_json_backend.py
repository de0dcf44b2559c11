"""ArduPilot's JSON physics interface: the wire format against hand-built bytes, the lock-step loop
over UDP, and the real ArduCopter SITL booting on it (slow; skips without ../shared/ardupilot)."""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import socket
import struct
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest

from sitl.vehicle.json_backend import (
    JsonPhysicsServer,
    SensorFrame,
    json_port,
    parse_servo_packet,
    resting_on_the_ground,
)

ROOT = Path(__file__).resolve().parents[3]
SPEEDUP = 30  # a cap: in lock-step SITL waits for each answer (about 10-15x here, on two shared cores)
log = logging.getLogger(__name__)


def _servo(count: int, rate: int = 400, pwm=(1000,) * 16, magic: int = 18458) -> bytes:
    return struct.pack(f"<HHI{len(pwm)}H", magic, rate, count, *pwm)


def test_a_16_channel_servo_packet_decodes_as_documented():
    pwm = tuple(1000 + 10 * k for k in range(16))
    p = parse_servo_packet(_servo(7, 1200, pwm))
    assert (p.frame_rate_hz, p.frame_count, p.pwm_us) == (1200, 7, pwm)
    assert p.dt_s == pytest.approx(1 / 1200)


def test_a_32_channel_servo_packet_has_its_own_magic():
    p = parse_servo_packet(_servo(1, 400, tuple(range(1100, 1132)), magic=29569))
    assert len(p.pwm_us) == 32 and p.pwm_us[31] == 1131


@pytest.mark.parametrize("data, why", [
    (b"\x1aH", "shorter"), (_servo(0, magic=1234), "magic"), (_servo(0)[:-2], "channels need"),
    (_servo(0, rate=0), "0 Hz"), (_servo(0, pwm=(1000,) * 32), "channels need"),
])
def test_bad_servo_packets_are_value_errors(data, why):
    with pytest.raises(ValueError, match=why):
        parse_servo_packet(data)


def test_the_reply_is_one_compact_json_line_sitl_can_parse():
    # SITL's parser looks for "key": with no space; written out by hand from JSON-interface.md.
    assert resting_on_the_ground(0.5).encode() == (
        b'\n{"timestamp":0.5,"imu":{"gyro":[0.0,0.0,0.0],"accel_body":[0.0,0.0,-9.80665]},'
        b'"position":[0.0,0.0,0.0],"velocity":[0.0,0.0,0.0],"attitude":[0.0,0.0,0.0]}\n')


def test_enu_position_and_velocity_are_sent_as_ned():
    f = SensorFrame.from_enu(2.0, (1.0, 2.0, 3.0), (-4.0, 5.0, 0.5), (0.1, -0.2, 1.5), (0, 0, 0), (0, 0, -9.8))
    msg = json.loads(f.encode())
    assert msg["position"] == [2.0, 1.0, -3.0] and msg["velocity"] == [5.0, -4.0, -0.5]
    with pytest.raises(ValueError, match="finite"):
        SensorFrame.from_enu(math.nan, (0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0)).encode()


def test_the_server_steps_in_lock_step_and_counts_resends_losses_and_restarts():
    steps = []

    def physics(packet, t):
        steps.append((packet.frame_count, round(t, 6)))
        return resting_on_the_ground(t)

    server = JsonPhysicsServer(9, physics)  # instance 9: port 9092 on loopback
    sitl = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sitl.bind(("127.0.0.1", 0))
    sitl.settimeout(2.0)
    replies = []
    try:
        for count in (0, 1, 1, 3, 0):  # a resend of 1, frame 2 lost, then SITL restarts
            sitl.sendto(_servo(count, 400), ("127.0.0.1", json_port(9)))
            assert server.serve_one(2.0)
            replies.append(json.loads(sitl.recv(4096))["timestamp"])
    finally:
        server.close()
        sitl.close()
    # Hand-worked: 400 Hz steps of 2.5 ms; the resend is answered again without a step.
    assert steps == [(0, 0.0025), (1, 0.005), (3, 0.0075), (0, 0.0025)]
    assert replies == pytest.approx([0.0025, 0.005, 0.005, 0.0075, 0.0025])
    c = server.counters
    assert (c.frames, c.resent, c.lost, c.restarts) == (4, 1, 1, 1)


@contextlib.contextmanager
def _arducopter_on(physics, tmp_path, instance: int = 8, extra_params: str = "", speedup: int = 10):
    """ArduCopter SITL (at ``speedup``) flying ``physics`` through our JSON server; yields (link, server)."""
    from chaser_bt.vehicle import LinkConfig, VehicleLink

    where = Path(os.environ.get("CHASER_BT_ARDUPILOT", ROOT.parent / "shared" / "ardupilot"))
    if not (where / "arducopter").is_file():
        pytest.skip(f"no ArduCopter SITL at {where} (set CHASER_BT_ARDUPILOT to its folder)")
    server = JsonPhysicsServer(instance, physics)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            server.serve_one(0.2)

    env = dict(os.environ, SITL_RUN_DIR=str(tmp_path / "run"), SITL_HOME="42.5,-71.6,80,0")
    if extra_params:
        (tmp_path / "extra.parm").write_text(extra_params)
        env["SITL_DEFAULTS"] = str(tmp_path / "extra.parm")
    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    pid_file = tmp_path / "run" / f"I{instance}" / "sitl.pid"
    link = None
    try:
        started = subprocess.run([str(where / "start_sitl.sh"), str(instance), str(speedup), "JSON:127.0.0.1"],
                                 capture_output=True, text=True, env=env, timeout=90)
        assert started.returncode == 0, started.stdout + started.stderr
        link = VehicleLink.connect(started.stdout.strip().splitlines()[-1],
                                   LinkConfig(connect_timeout_s=30.0, timers_on_vehicle_time=True))
        yield link, server
    finally:
        if link is not None:
            link.close()
        if pid_file.exists():
            _stop(int(pid_file.read_text().strip()))
        stop.set()
        thread.join(5.0)
        server.close()


@pytest.mark.slow
def test_real_arducopter_boots_on_our_json_backend_and_finds_its_home(tmp_path):
    """Lock-step end to end: ArduCopter's EKF, GPS and home come up from our sensor frames alone."""
    with _arducopter_on(lambda packet, t: resting_on_the_ground(t), tmp_path) as (link, server):
        link.wait(lambda s: s.home is not None and s.gps_fix_type >= 3, 120.0)
        s = link.state
        assert s.home.lat_deg == pytest.approx(42.5, abs=1e-5) and s.home.lon_deg == pytest.approx(-71.6, abs=1e-5)
        assert abs(s.alt_rel_m) < 1.0 and not s.armed
        # One clock: the vehicle's boot time is our physics time (its frames are answered in order).
        assert server.counters.resent == 0 and server.counters.lost == 0
        assert link.state.t_boot_s == pytest.approx(server.time_s, abs=0.5)


@pytest.mark.slow
@pytest.mark.parametrize("airframe, rates", [
    ("quad", {"SIM_RATE_HZ": 800}),  # ArduCopter's own 400 Hz loop: the gyro must run at 1.8x it (a pre-arm check)
    ("s1000", {"SIM_RATE_HZ": 400, "SCHED_LOOP_RATE": 200}),  # half the frames and loops: the rehearsal's rate
])
def test_real_arducopter_takes_off_and_holds_10_m_on_our_motor_level_body(tmp_path, airframe, rates):
    """ArduCopter's own attitude, rate and position loops fly our rotors (5-10 s of wall time each): the
    quad "+" on stock parameters, the S1000 octocopter (FRAME_CLASS 3, octa X) on the ones it names."""
    from sitl.vehicle.rotor_body import RotorBody

    body = RotorBody.named(airframe)
    extra = "".join(f"{k} {v}\n" for k, v in {**body.params.ardupilot_params(), **rates}.items())
    with _arducopter_on(body.physics, tmp_path, extra_params=extra, speedup=SPEEDUP) as (link, server):
        assert link.wait(lambda s: s.ready_to_arm, 120.0)
        assert link.wait(link.set_mode("GUIDED"), 20.0).ok
        assert link.wait(link.arm(), 30.0).ok
        assert link.wait(link.takeoff(10.0), 20.0).ok
        assert link.wait(lambda s: s.alt_rel_m > 9.5, 30.0)
        t_reached = link.state.t_boot_s
        worst = 0.0
        while link.state.t_boot_s < t_reached + 8.0:  # sampled every 0.1 s of its time, not in a busy loop
            t_next = link.state.t_boot_s + 0.1
            link.wait(lambda s: s.t_boot_s >= t_next, 10.0)
            worst = max(worst, abs(-body.position_ned[2] - 10.0), float(np.hypot(*body.position_ned[:2])))
        log.info("%s: held 10 m within %.2f m over 8 s; %d frames", airframe, worst, server.counters.frames)
        assert worst < 1.0 and link.state.mode == "GUIDED" and link.state.armed
        assert not body.crashed and server.counters.resent == 0


def _stop(pid: int) -> None:
    """SIGTERM, then SIGKILL: waiting on its physics socket, SITL does not always act on SIGTERM."""
    import time

    for sig in (15, 9):
        try:
            os.kill(pid, sig)
        except ProcessLookupError:
            return
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            try:
                if Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z":
                    return  # exited; its parent reaps it
            except OSError:
                return  # gone
            time.sleep(0.05)
