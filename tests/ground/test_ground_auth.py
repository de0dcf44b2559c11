"""The signed ground stream: the documented layout, and a receiver that drops forgeries and replays."""

from __future__ import annotations

import hashlib
import hmac
import socket
import struct

import numpy as np
import py_trees
import pytest

from chaser_bt.ground import FrameAssembler, GroundSender, StreamSigner, StreamVerifier, parse_datagram
from chaser_bt.ground.protocol import json_datagram

KEY = bytes(range(32))
NOW = 1767225600.0  # 2026-01-01T00:00:00Z
# Worked out by hand: (1767225600 - 1420070400) s since 2015-01-01, in 10 µs ticks.
STAMP_NOW = 347_155_200 * 100_000


def _signer(t: list[float], link_id: int = 0) -> StreamSigner:
    return StreamSigner(KEY, link_id, unix_time=lambda: t[0])


def _verifier(**kw) -> StreamVerifier:
    return StreamVerifier(KEY, unix_time=lambda: NOW, **kw)


def test_a_signed_datagram_is_the_documented_header_mac_and_payload():
    payload = b'{"v":1,"type":"status","seq":0,"t":1.5}'
    signed = _signer([NOW], link_id=7).sign(payload)
    header = b"CBTS" + bytes([1, 7]) + STAMP_NOW.to_bytes(8, "little")
    assert signed[:14] == header and signed[30:] == payload
    assert signed[14:30] == hmac.new(KEY, header + payload, hashlib.sha256).digest()[:16]


def test_timestamps_strictly_increase_even_when_the_clock_stands_still_or_goes_back():
    t = [NOW]
    signer = _signer(t)
    stamps = []
    for clock in (NOW, NOW, NOW - 5.0, NOW + 1.0):
        t[0] = clock
        stamps.append(struct.unpack_from("<Q", signer.sign(b"x"), 6)[0])
    assert stamps == [STAMP_NOW, STAMP_NOW + 1, STAMP_NOW + 2, STAMP_NOW + 100_000]


def test_the_receiver_believes_genuine_fresh_datagrams_only_and_counts_the_rest():
    signer, verifier = _signer([NOW]), _verifier()
    first, second = signer.sign(b"one"), signer.sign(b"two")
    assert verifier.open(first) == b"one" and verifier.open(second) == b"two"
    assert verifier.open(first) is None  # replayed
    tampered = bytearray(signer.sign(b"three"))
    tampered[-1] ^= 0x01
    assert verifier.open(bytes(tampered)) is None  # forged: payload changed after signing
    wrong_key = StreamSigner(bytes(32), unix_time=lambda: NOW + 1.0).sign(b"evil")
    assert verifier.open(wrong_key) is None  # forged: someone else's key
    assert verifier.open(b'{"v":1,"type":"status"}') is None  # unsigned
    assert verifier.open(b"CBTS\x01") is None  # forged: truncated
    c = verifier.counters
    assert (c.accepted, c.replayed, c.forged, c.unsigned, c.dropped) == (2, 1, 3, 1, 5)


def test_each_link_id_has_its_own_timestamps():
    verifier = _verifier()
    a, b = _signer([NOW + 1.0], link_id=1), _signer([NOW], link_id=2)
    assert verifier.open(a.sign(b"a")) == b"a"
    assert verifier.open(b.sign(b"b")) == b"b"  # older than link 1's, but link 2's first


def test_a_recording_replayed_later_is_refused_unless_no_clock_is_shared():
    old = _signer([NOW - 120.0]).sign(b"recorded two minutes ago")
    strict = _verifier(max_skew_s=60.0)
    assert strict.open(old) is None and strict.counters.replayed == 1
    assert _verifier(max_skew_s=None).open(old) == b"recorded two minutes ago"


def test_the_key_must_be_a_mavlink_signing_key():
    with pytest.raises(ValueError, match="32 bytes"):
        StreamSigner(b"short")
    with pytest.raises(ValueError, match="32 bytes"):
        StreamVerifier(b"short")
    with pytest.raises(ValueError, match="link id"):
        StreamSigner(KEY, 256)


def _listener() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    return sock


def test_a_signed_stream_over_udp_reassembles_and_a_forger_on_the_network_is_dropped():
    ground = _listener()
    port = ground.getsockname()[1]
    sender = GroundSender("127.0.0.1", port, max_datagram=8000, signer=StreamSigner(KEY))
    image = np.random.default_rng(2).integers(0, 255, (240, 320, 3), dtype=np.uint8)  # noise: many chunks
    assert sender.send_message("status", 1.0, {"mode": "GUIDED"})
    assert sender.send_frame(image, 1.0, quality=95)
    n = sender.counters.datagrams
    assert n >= 4
    forger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    forger.sendto(json_datagram("estimate", 0, 1.0, {"position_enu": [0, 0, 0]}), ("127.0.0.1", port))  # unsigned
    verifier, assembler, frame, messages, captured = StreamVerifier(KEY), FrameAssembler(), None, [], []
    for _ in range(n + 1):
        data = ground.recv(65535)
        assert len(data) <= 8000
        captured.append(data)
        payload = verifier.open(data)
        if payload is None:
            continue
        msg = parse_datagram(payload)
        if isinstance(msg, dict):
            messages.append(msg)
        else:
            frame = assembler.add(msg) or frame
    for data in captured[:2]:  # the forger replays what it captured
        forger.sendto(data, ("127.0.0.1", port))
        assert verifier.open(ground.recv(65535)) is None
    assert [m["type"] for m in messages] == ["status"] and frame is not None
    assert (verifier.counters.accepted, verifier.counters.unsigned, verifier.counters.replayed) == (n, 1, 2)
    forger.close()
    sender.close()
    ground.close()


def test_stream_to_ground_signs_with_the_key_file_it_is_given(tmp_path):
    from chaser_bt.clock import ManualClock
    from chaser_bt.tree import load_tree_text
    from chaser_bt.vehicle import VehicleLink, byte_pipe
    from chaser_bt.vehicle.signing import passphrase_key

    (tmp_path / "ground.key").write_text("correct horse battery staple\n")  # MAVProxy-style passphrase
    ground = _listener()
    tree = load_tree_text(f"""
version: 1
trees:
  Main:
    StreamToGround: {{port: {ground.getsockname()[1]}, video_hz: 0, key_file: "{tmp_path / 'ground.key'}"}}
""", source="<test>")
    clock = ManualClock(3.0)
    link = VehicleLink.over_pipe(byte_pipe()[0], monotonic=clock.now)
    bt = py_trees.trees.BehaviourTree(tree.root)
    py_trees.blackboard.Blackboard.set("/vehicle/state", link.state)
    bt.setup(link=link, clock=clock)
    bt.tick()
    data = ground.recv(65535)
    assert StreamVerifier(passphrase_key("correct horse battery staple")).open(data) is not None
    assert StreamVerifier(KEY).open(data) is None
    bt.shutdown()
    ground.close()


def test_stream_to_ground_with_an_unreadable_key_file_stops_before_the_flight(tmp_path):
    from chaser_bt.clock import ManualClock
    from chaser_bt.tree import load_tree_text
    from chaser_bt.vehicle import VehicleLink, byte_pipe

    tree = load_tree_text(f"""
version: 1
trees:
  Main:
    StreamToGround: {{key_file: "{tmp_path / 'missing.key'}"}}
""", source="<test>")
    clock = ManualClock(0.0)
    link = VehicleLink.over_pipe(byte_pipe()[0], monotonic=clock.now)
    with pytest.raises(ValueError, match="missing.key"):
        py_trees.trees.BehaviourTree(tree.root).setup(link=link, clock=clock)


def test_the_verifier_in_the_docs_agrees_with_the_library():
    import re
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "ground.md").read_text()
    section = doc[doc.index("## Signed stream"):doc.index("## A receiver in plain Python")]
    namespace: dict = {}
    exec(re.search(r"```python\n(.*?)```", section, re.S).group(1), namespace)  # noqa: S102 - our own docs
    open_signed, last = namespace["open_signed"], {}
    signer = _signer([NOW])
    good = signer.sign(b"payload")
    assert open_signed(good, KEY, last) == b"payload"
    assert open_signed(good, KEY, last) is None  # replayed
    assert open_signed(good[:-1] + b"X", KEY, last) is None  # forged
    assert open_signed(b"payload", KEY, last) is None  # unsigned
    assert open_signed(signer.sign(b"next"), KEY, last) == b"next"
