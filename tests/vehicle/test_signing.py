"""MAVLink 2 signing: key files, timestamps, the admission rule, and VehicleLink with a key."""

from __future__ import annotations

import hashlib

import pytest

from chaser_bt.vehicle import LinkConfig, VehicleLink, byte_pipe
from chaser_bt.vehicle.connection import mavutil
from chaser_bt.vehicle.signing import (
    SigningConfig,
    SigningGate,
    SigningKeyError,
    Verdict,
    key_from_text,
    load_key,
    signing_timestamp,
)

mav = mavutil.mavlink
KEY = bytes(range(32))
# SHA-256("abc"), FIPS 180-2 appendix B.1: the MAVProxy passphrase convention on a known vector
SHA256_ABC = bytes.fromhex("ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad")


def test_key_file_of_64_hex_digits_is_the_key_itself(tmp_path):
    path = tmp_path / "k.txt"
    path.write_text("\n  " + KEY.hex().upper() + "  \n")
    assert load_key(path) == KEY


def test_other_text_is_a_passphrase_hashed_as_mavproxy_does():
    assert key_from_text("abc\nignored second line") == SHA256_ABC
    assert key_from_text(KEY.hex()[:-1]) == hashlib.sha256(KEY.hex()[:-1].encode()).digest()  # 63 digits: a passphrase


@pytest.mark.parametrize("text, expect", [("", "empty"), ("  \n\n", "empty"), ("pässword", "printable ASCII")])
def test_unusable_key_files_name_the_file_and_the_problem(tmp_path, text, expect):
    path = tmp_path / "bad.key"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(SigningKeyError, match=expect) as e:
        load_key(path)
    assert str(path) in str(e.value)


def test_missing_key_file_is_a_key_error(tmp_path):
    with pytest.raises(SigningKeyError, match="cannot read"):
        load_key(tmp_path / "absent")


def test_config_checks_key_and_link_id_and_never_shows_the_key():
    with pytest.raises(ValueError, match="32 bytes"):
        SigningConfig(b"short")
    with pytest.raises(ValueError, match="link_id"):
        SigningConfig(KEY, link_id=256)
    with pytest.raises(ValueError, match="NOT_A_MESSAGE"):
        SigningConfig(KEY, allow_unsigned=frozenset({"NOT_A_MESSAGE"}))
    assert "key=" not in repr(SigningConfig(KEY)) and repr(KEY) not in repr(SigningConfig(KEY))


def test_signing_timestamp_counts_10_us_since_2015():
    assert signing_timestamp(1420070400.0) == 0
    assert signing_timestamp(1420070400.0 + 1.5) == 150_000
    assert signing_timestamp(1420070400.0 + 86_400) == 8_640_000_000
    assert signing_timestamp(0.0) == 0  # before 2015: clamped, never negative


def _packet(key: bytes | None, timestamp: int, msg=None, link_id: int = 0) -> bytes:
    """A packet from a stock pymavlink sender (sysid 1, compid 1)."""
    sender = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    if key is not None:
        sender.signing.secret_key, sender.signing.sign_outgoing = key, True
        sender.signing.timestamp, sender.signing.link_id = timestamp, link_id
    msg = msg if msg is not None else mav.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3)
    return msg.pack(sender)


def _gate_and_parser(timestamp: int = 1000) -> tuple[SigningGate, mav.MAVLink]:
    gate = SigningGate(SigningConfig(KEY), timestamp)
    parser = mav.MAVLink(None)
    parser.robust_parsing = True
    gate.attach(parser)
    return gate, parser


def _verdict(gate, parser, data: bytes) -> Verdict:
    (msg,) = parser.parse_buffer(data)
    return gate.verdict(msg)


def test_gate_verdicts_signed_unsigned_allowed_wrong_key_and_replay():
    gate, parser = _gate_and_parser()
    good = _packet(KEY, 5000)
    assert _verdict(gate, parser, good) is Verdict.SIGNED
    assert _verdict(gate, parser, good) is Verdict.BAD_SIGNATURE  # the same bytes again: a replay
    assert _verdict(gate, parser, _packet(KEY, 5001)) is Verdict.SIGNED
    assert _verdict(gate, parser, _packet(bytes(32), 6000)) is Verdict.BAD_SIGNATURE
    assert _verdict(gate, parser, _packet(None, 0)) is Verdict.UNSIGNED
    radio = mav.MAVLink_radio_status_message(1, 2, 3, 4, 5, 6, 7)
    assert _verdict(gate, parser, _packet(None, 0, radio)) is Verdict.UNSIGNED_ALLOWED
    tampered = bytearray(_packet(KEY, 7000))
    tampered[-1] ^= 1
    assert _verdict(gate, parser, bytes(tampered)) is Verdict.BAD_SIGNATURE


def test_a_new_stream_more_than_a_minute_behind_is_refused():
    gate, parser = _gate_and_parser(timestamp=10_000_000)
    assert _verdict(gate, parser, _packet(KEY, 10_000_000 - 6_000_001, link_id=1)) is Verdict.BAD_SIGNATURE
    assert _verdict(gate, parser, _packet(KEY, 10_000_000 - 5_999_999, link_id=2)) is Verdict.SIGNED


def test_a_forged_far_future_timestamp_does_not_shut_out_the_real_stream():
    gate, parser = _gate_and_parser()
    assert _verdict(gate, parser, _packet(KEY, 2000)) is Verdict.SIGNED
    assert _verdict(gate, parser, _packet(bytes(32), 2**47)) is Verdict.BAD_SIGNATURE
    assert _verdict(gate, parser, _packet(KEY, 2001)) is Verdict.SIGNED
    assert gate.timestamp < 2**40  # the forgery did not move our clock either


def test_admit_counts_each_verdict():
    gate, parser = _gate_and_parser()
    for data in (_packet(KEY, 3000), _packet(None, 0), _packet(None, 0), _packet(bytes(32), 4000)):
        (msg,) = parser.parse_buffer(data)
        gate.admit(msg)
    c = gate.counters
    assert (c.signed, c.unsigned_rejected, c.bad_signature, c.rejected) == (1, 2, 1, 3)


def test_gate_signs_outgoing_with_growing_timestamps_a_stock_parser_verifies():
    gate = SigningGate(SigningConfig(KEY, link_id=7), 123_456)
    sender = mav.MAVLink(None, srcSystem=255, srcComponent=190)
    gate.attach(sender)
    gate.advance(1420070400.0 + 2.0)  # the clock is ahead: the timestamp jumps to it
    data = b"".join(mav.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(sender) for _ in range(3))
    receiver = mav.MAVLink(None)
    receiver.signing.secret_key = KEY
    receiver.signing.allow_unsigned_callback = lambda m, i: False
    msgs = receiver.parse_buffer(data)
    assert len(msgs) == 3 and all(m.get_signed() for m in msgs)
    stamps = [int.from_bytes(bytes(m.get_msgbuf()[-12:-6]), "little") for m in msgs]
    assert stamps == [200_000, 200_001, 200_002] and {m.get_msgbuf()[-13] for m in msgs} == {7}


# --------------------------------------------------------------------------- the link with a key
sitl_simulator = pytest.importorskip("sitl.simulator")
sitl_scenario = pytest.importorskip("sitl.world.scenario")


def _scenario():
    return sitl_scenario.Scenario.from_dict({
        "name": "signing", "home": {"lat_deg": 42.5445, "lon_deg": -71.6105, "alt_m": 80.0},
        "wind": {"speed_mps": 0.0, "gust_std_mps": 0.0},
        "boot": {"gps_fix_s": 1.0, "ekf_ready_s": 2.0, "prearm_ok_s": 3.0},
    }, source="<test>")


def _signed_pair(vehicle_key: bytes, link_key: bytes | None):
    sim = sitl_simulator.Simulator(_scenario(), 0)
    sim.endpoint.enable_signing(SigningConfig(vehicle_key))
    a, b = byte_pipe()
    sim.attach(b)
    config = LinkConfig(signing=SigningConfig(link_key, link_id=1) if link_key is not None else None)
    return sim, VehicleLink.over_pipe(a, config, monotonic=lambda: sim.time_s)


def test_link_with_the_key_flies_a_signed_vehicle():
    sim, link = _signed_pair(KEY, KEY)
    link.wait(lambda: link.target_compid is not None, 5.0, pump=sim.step)
    cmd = link.wait(link.set_mode("ALT_HOLD"), 5.0, pump=sim.step)
    assert cmd.ok and sim.autopilot.mode == "ALT_HOLD" and link.state.mode == "ALT_HOLD"
    assert sim.endpoint.signing.counters.rejected == 0 and sim.endpoint.signing.counters.signed > 5
    assert link.signing.counters.signed > 5


def test_link_without_the_key_is_not_obeyed_and_its_commands_are_counted():
    sim, link = _signed_pair(KEY, None)
    link.wait(lambda: link.target_compid is not None, 5.0, pump=sim.step)
    cmd = link.set_mode("ALT_HOLD")
    link.wait(lambda: cmd.done, 10.0, pump=sim.step)
    assert not cmd.ok and sim.autopilot.mode != "ALT_HOLD"
    assert sim.endpoint.signing.counters.unsigned_rejected > 0 and sim.endpoint.signing.counters.signed == 0


def test_link_refuses_to_believe_a_vehicle_signed_with_another_key():
    sim, link = _signed_pair(bytes(32), KEY)
    for _ in range(100):
        sim.step()
        link.poll()
    assert link.target_sysid is None and not link.state.mode
    assert link.signing.counters.bad_signature > 0 and link.signing.counters.signed == 0
