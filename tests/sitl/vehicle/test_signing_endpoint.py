"""The simulator with a signing key obeys only correctly signed MAVLink, as a keyed ArduCopter does.

The ground station here is stock pymavlink (``MAVLink.signing`` set by hand, as the pymavlink
signing guide shows), independent of :mod:`chaser_bt.vehicle.signing`.
"""

from __future__ import annotations

import hashlib
import queue
import threading

from mavlink_gcs import PipeGcs, mav, quick_scenario
from pymavlink import mavutil

from chaser_bt.vehicle.signing import EPOCH_2015_UNIX_S, SigningConfig
from sitl.server import serve
from sitl.simulator import Simulator

KEY = hashlib.sha256(b"chaser test key").digest()
OTHER_KEY = hashlib.sha256(b"not the key").digest()
ALT_HOLD, STABILIZE = 2, 0


def _signed_gcs(key: bytes | None, timestamp: int | None = None) -> PipeGcs:
    sim = Simulator(quick_scenario(), 0)
    sim.endpoint.enable_signing(SigningConfig(KEY))
    gcs = PipeGcs(sim)
    gcs.parser.signing.secret_key = KEY  # the GCS checks the vehicle's signatures too
    gcs.parser.signing.allow_unsigned_callback = lambda m, msg_id: False
    _sign(gcs, key, timestamp)
    gcs.run(1.0)
    return gcs


def _sign(gcs: PipeGcs, key: bytes | None, timestamp: int | None = None) -> None:
    s = gcs.mav.signing
    s.secret_key, s.sign_outgoing, s.link_id = key, key is not None, 3
    s.timestamp = timestamp if timestamp is not None else _now_ticks(gcs.sim)


def _now_ticks(sim) -> int:
    return int((sim.scenario.start_unix_s + sim.time_s - EPOCH_2015_UNIX_S) * 100_000)


def _set_mode(gcs: PipeGcs, mode: int):
    """Send DO_SET_MODE; the ACK (None when the command was dropped)."""
    return gcs.set_mode(mode)


def test_signed_command_is_obeyed_and_the_vehicle_signs_its_answer():
    gcs = _signed_gcs(KEY)
    ack = _set_mode(gcs, ALT_HOLD)
    assert ack is not None and ack.result == mav.MAV_RESULT_ACCEPTED
    assert gcs.sim.autopilot.mode_number == ALT_HOLD
    # every vehicle packet the GCS decoded carried a good signature under the shared key
    assert gcs.log and all(m.get_signed() for _, m in gcs.log)
    c = gcs.sim.endpoint.signing.counters
    assert c.signed >= 1 and c.rejected == 0


def test_unsigned_command_is_rejected_and_counted():
    gcs = _signed_gcs(None)
    assert _set_mode(gcs, ALT_HOLD) is None
    assert gcs.sim.autopilot.mode_number != ALT_HOLD
    c = gcs.sim.endpoint.signing.counters
    assert c.unsigned_rejected == 1 and c.bad_signature == 0 and c.signed == 0


def test_command_signed_with_another_key_is_rejected_and_counted():
    gcs = _signed_gcs(OTHER_KEY)
    assert _set_mode(gcs, ALT_HOLD) is None
    assert gcs.sim.autopilot.mode_number != ALT_HOLD
    c = gcs.sim.endpoint.signing.counters
    assert c.bad_signature == 1 and c.unsigned_rejected == 0 and c.signed == 0


def test_replayed_signed_command_is_rejected():
    gcs = _signed_gcs(KEY)
    packet = mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_DO_SET_MODE, 0,
                                              mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, ALT_HOLD, 0, 0, 0, 0, 0)
    recorded = packet.pack(gcs.mav)
    gcs.send_raw(recorded)
    gcs.run(0.2)
    assert gcs.sim.autopilot.mode_number == ALT_HOLD
    assert _set_mode(gcs, STABILIZE).result == mav.MAV_RESULT_ACCEPTED
    gcs.send_raw(recorded)  # an eavesdropper plays the ALT_HOLD command back
    gcs.run(0.5)
    assert gcs.sim.autopilot.mode_number == STABILIZE
    assert gcs.sim.endpoint.signing.counters.bad_signature == 1


def test_radio_status_is_accepted_unsigned_like_arducopter():
    gcs = _signed_gcs(None)
    before = gcs.sim.endpoint.stats.messages_in
    gcs.send(mav.MAVLink_radio_status_message(200, 190, 80, 10, 20, 0, 0))
    gcs.run(0.1)
    assert gcs.sim.endpoint.signing.counters.unsigned_allowed == 1
    assert gcs.sim.endpoint.stats.messages_in == before + 1


def test_forged_packet_with_a_future_timestamp_does_not_lock_out_the_real_gcs():
    gcs = _signed_gcs(KEY)
    genuine = gcs.mav.signing.timestamp
    # a forger sends from our ids and link id, a timestamp a day ahead, the wrong key
    _sign(gcs, OTHER_KEY, genuine + 86_400 * 100_000)
    assert _set_mode(gcs, ALT_HOLD) is None
    _sign(gcs, KEY, genuine + 1)
    ack = _set_mode(gcs, ALT_HOLD)
    assert ack is not None and ack.result == mav.MAV_RESULT_ACCEPTED
    c = gcs.sim.endpoint.signing.counters
    assert c.bad_signature == 1


def test_vehicle_timestamps_follow_the_simulator_clock_and_only_grow():
    gcs = _signed_gcs(KEY)
    stamps = []
    for _ in range(3):
        gcs.run(1.0)
        t_sim = gcs.sim.time_s
        for _, m in gcs.log[-20:]:
            stamps.append(int.from_bytes(bytes(m.get_msgbuf()[-12:-6]), "little"))
        # within a few packets of the clock's ticks (1 tick per packet above the clock at most)
        assert abs(stamps[-1] - _now_ticks(gcs.sim)) < 2000
        assert t_sim == gcs.sim.time_s
    all_stamps = [int.from_bytes(bytes(m.get_msgbuf()[-12:-6]), "little") for _, m in gcs.log]
    assert all(b > a for a, b in zip(all_stamps, all_stamps[1:]))


def test_server_with_a_signing_key_answers_a_signed_mavutil_client_only(tmp_path):
    key_file = tmp_path / "key.txt"
    key_file.write_text(KEY.hex() + "\n")
    urls: queue.Queue = queue.Queue()
    stop = threading.Event()
    thread = threading.Thread(target=serve, args=(quick_scenario(),), daemon=True, kwargs=dict(
        speedup=10.0, udp_port=0, tcp_port=0, ready=urls.put, stop=stop, signing=SigningConfig.from_file(key_file)))
    thread.start()
    try:
        tcp = next(u for u in urls.get(timeout=20.0) if u.startswith("tcp:"))
        unsigned = mavutil.mavlink_connection(tcp, source_system=255, source_component=190)
        signed = mavutil.mavlink_connection(tcp, source_system=255, source_component=191)
        signed.setup_signing(KEY, sign_outgoing=True, link_id=1)
        for conn in (unsigned, signed):
            assert conn.wait_heartbeat(timeout=20.0) is not None
            conn.mav.command_long_send(1, 1, mav.MAV_CMD_DO_SET_MODE, 0, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                       ALT_HOLD, 0, 0, 0, 0, 0)
        ack = signed.recv_match(type="COMMAND_ACK", blocking=True, timeout=10.0)
        assert ack is not None and ack.result == mav.MAV_RESULT_ACCEPTED and ack.target_component == 191
        late = unsigned.recv_match(type="COMMAND_ACK", blocking=True, timeout=1.0,
                                   condition="COMMAND_ACK.target_component==190")
        assert late is None
        unsigned.close()
        signed.close()
    finally:
        stop.set()
        thread.join(timeout=20.0)
    assert not thread.is_alive()
