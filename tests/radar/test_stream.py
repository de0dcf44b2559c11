"""The datagram schema and the stream reader: good scans pass, bad ones are dropped and counted, nothing raises."""

from __future__ import annotations

import json
import socket

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from chaser_bt.radar.report import MAX_DATAGRAM_BYTES, RadarScan, TrackReport, decode_scan, encode_scan
from chaser_bt.radar.stream import QueueDatagramSource, RadarStreamReader, UdpDatagramSource


def scan(seq: int, t: float, n: int = 2) -> RadarScan:
    return RadarScan(t, seq, tuple(TrackReport(10 + i, 100.0 + i, 0.1 * i, 0.05, np.array([1.0, -2.0, 0.5]), 0.9)
                                   for i in range(n)), "r1")


def test_encode_decode_round_trip():
    s = scan(3, 12.5)
    back = decode_scan(encode_scan(s))
    assert (back.t, back.seq, back.radar_id) == (12.5, 3, "r1")
    assert [r.track_id for r in back.tracks] == [10, 11]
    assert np.allclose(back.tracks[1].velocity, [1.0, -2.0, 0.5]) and back.tracks[1].az_rad == 0.1


def test_each_kind_of_bad_datagram_is_counted_under_its_reason():
    reader = RadarStreamReader()
    good = json.loads(encode_scan(scan(5, 1.0)))
    assert reader.accept(encode_scan(scan(5, 1.0))) is not None
    assert reader.accept(b"{not json") is None
    assert reader.accept(json.dumps({**good, "version": 2}).encode()) is None
    assert reader.accept(b" " * (MAX_DATAGRAM_BYTES + 1)) is None
    assert reader.accept(encode_scan(scan(4, 1.2))) is None  # seq went back
    assert reader.accept(encode_scan(scan(6, 0.5))) is None  # time went back
    assert reader.accept(json.dumps({**good, "seq": 7, "tracks": [{"id": 1, "range_m": "far"}]}).encode()) is None
    c = reader.counts
    assert (c.accepted, c.malformed, c.wrong_version, c.oversized, c.out_of_order) == (1, 2, 1, 1, 2)
    assert reader.accept(encode_scan(scan(6, 1.5))) is not None and c.accepted == 2


def test_a_restarted_radar_is_accepted_again():
    reader = RadarStreamReader(restart_gap=100)
    assert reader.accept(encode_scan(scan(5000, 10.0))) is not None
    assert reader.accept(encode_scan(scan(1, 11.0))) is not None


def _mutations(data: st.DataObject) -> bytes:
    base = bytearray(encode_scan(scan(data.draw(st.integers(0, 10)), data.draw(st.floats(0, 100)), 3)))
    kind = data.draw(st.sampled_from(["flip", "cut", "json", "bytes", "field"]))
    if kind == "flip":
        for _ in range(data.draw(st.integers(1, 8))):
            base[data.draw(st.integers(0, len(base) - 1))] = data.draw(st.integers(0, 255))
        return bytes(base)
    if kind == "cut":
        return bytes(base[: data.draw(st.integers(0, len(base)))])
    if kind == "bytes":
        return data.draw(st.binary(max_size=300))
    if kind == "json":
        j = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
                         lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=8), c, max_size=4),
                         max_leaves=12)
        return json.dumps(data.draw(j)).encode()
    obj = json.loads(bytes(base))
    key = data.draw(st.sampled_from(["schema", "version", "seq", "t", "tracks", "radar_id"]))
    obj[key] = data.draw(st.none() | st.integers() | st.floats(allow_nan=True) | st.text(max_size=4) | st.lists(st.integers(), max_size=3))
    if data.draw(st.booleans()) and obj.get("tracks"):
        tr = obj["tracks"][0] if isinstance(obj["tracks"], list) and obj["tracks"] else {}
        if isinstance(tr, dict):
            tr[data.draw(st.sampled_from(["id", "range_m", "az_rad", "el_rad", "vel_mps", "confidence"]))] = data.draw(
                st.none() | st.integers(-2**70, 2**70) | st.floats(allow_nan=True) | st.text(max_size=3) | st.lists(st.floats(), max_size=4))
    return json.dumps(obj).encode()


READER = RadarStreamReader()


@settings(max_examples=10_000, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(st.data())
def test_ten_thousand_fuzzed_datagrams_never_raise(data):
    before = READER.counts.accepted + READER.counts.dropped
    READER.accept(_mutations(data))
    assert READER.counts.accepted + READER.counts.dropped == before + 1


def test_queue_and_udp_sources_deliver_datagrams():
    q = QueueDatagramSource()
    q.push(b"a")
    q.push(b"b")
    assert q.receive() == [b"a", b"b"] and q.receive() == []
    src = UdpDatagramSource("127.0.0.1", 0)
    try:
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        tx.sendto(encode_scan(scan(1, 1.0)), ("127.0.0.1", src.port))
        tx.close()
        got = []
        for _ in range(200):
            got += src.receive()
            if got:
                break
            socket.socket().close()
        assert RadarStreamReader().accept_all(got)[0].seq == 1
    finally:
        src.close()


def test_a_track_the_radar_could_not_report_is_dropped_from_its_scan_and_counted():
    # One datagram with a track at 1e7 m (and one at 1e300 m, whose covariance would be NaN) beside a
    # real one: the real track stays, the others go.
    reader = RadarStreamReader()
    tracks = (TrackReport(1, 1e7, 0.0, 0.1), TrackReport(2, 212.4, -0.1, 0.09, np.array([1.2, -4.0, 0.1])),
              TrackReport(3, 1e300, 0.0, 0.0), TrackReport(4, 300.0, 0.0, 0.0, np.array([400.0, 0.0, 0.0])))
    scan = reader.accept(encode_scan(RadarScan(1.0, 1, tracks)))
    assert [tr.track_id for tr in scan.tracks] == [2]
    assert reader.counts.tracks_out_of_envelope == 3 and reader.counts.accepted == 1


def test_with_a_key_only_signed_fresh_datagrams_are_believed():
    from chaser_bt.ground.auth import StreamSigner, StreamVerifier

    key, clock = bytes(range(32)), [1.8e9]
    reader = RadarStreamReader(verifier=StreamVerifier(key, unix_time=lambda: clock[0]))
    signer = StreamSigner(key, link_id=3, unix_time=lambda: clock[0])
    plain = encode_scan(RadarScan(1.0, 1, (TrackReport(7, 200.0, 0.0, 0.1),)))
    signed = signer.sign(plain)
    assert reader.accept(plain) is None  # unsigned
    assert reader.accept(StreamSigner(bytes(32), unix_time=lambda: clock[0]).sign(plain)) is None  # another key
    assert reader.accept(signed).tracks[0].track_id == 7
    assert reader.accept(signed) is None  # the same datagram again: a replay
    assert reader.counts.unauthenticated == 3 and reader.counts.accepted == 1


def test_a_pinned_source_drops_datagrams_from_other_addresses():
    radar, intruder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM), socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    radar.bind(("127.0.0.1", 0))
    intruder.bind(("127.0.0.2", 0))  # the whole of 127/8 is loopback on Linux
    source = UdpDatagramSource("127.0.0.1", 0, allowed_hosts=frozenset({"127.0.0.1"}))
    try:
        for sock, payload in ((intruder, b"forged"), (radar, b"real"), (intruder, b"forged again")):
            sock.sendto(payload, ("127.0.0.1", source.port))
        import time

        deadline, got = time.monotonic() + 2.0, []
        while time.monotonic() < deadline and (len(got) < 1 or source.counts.foreign_source < 2):
            got += source.receive()
            time.sleep(0.01)
        assert got == [b"real"] and source.counts.foreign_source == 2
    finally:
        source.close()
        radar.close()
        intruder.close()
