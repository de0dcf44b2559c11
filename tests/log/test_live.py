"""The live Foxglove view: a real WebSocket client sees every channel advertised with its schema,
subscribes, and receives during a flight exactly the messages the MCAP file gets.

The Foxglove SDK's server speaks ``foxglove.sdk.v1``, the successor of ``foxglove.websocket.v1`` with
the same operations used here (serverInfo, advertise, subscribe, binary messageData)."""

from __future__ import annotations

import base64
import json
import struct
import threading
import time

import pytest
from websockets.sync.client import connect

from chaser_bt.log import schemas as S
from chaser_bt.log.live import LiveSink
from chaser_bt.log.replay import read_log
from log_flight import fly

SUBPROTOCOL = "foxglove.sdk.v1"


class Client:
    """A minimal foxglove.websocket.v1 client: advertisements, subscriptions, binary message data."""

    def __init__(self, ws) -> None:
        self.ws = ws
        self.channels: dict[str, dict] = {}
        self.received: list[tuple[int, int, bytes]] = []  # (subscription id, log time ns, payload)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def read_advertisements(self, topics: set[str], timeout_s: float = 10.0) -> None:
        deadline = time.monotonic() + timeout_s
        while not topics <= set(self.channels) and time.monotonic() < deadline:
            msg = self.ws.recv(timeout=max(deadline - time.monotonic(), 0.01))
            if isinstance(msg, str):
                op = json.loads(msg)
                if op["op"] == "advertise":
                    self.channels.update({c["topic"]: c for c in op["channels"]})

    def subscribe(self, topics: list[str]) -> dict[int, str]:
        subs = {k + 1: t for k, t in enumerate(topics)}
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": sid, "channelId": self.channels[t]["id"]} for sid, t in subs.items()]}))
        return subs

    def start(self) -> None:
        def loop() -> None:
            while not self._stop.is_set():
                try:
                    msg = self.ws.recv(timeout=0.1)
                except TimeoutError:
                    continue
                except Exception:
                    return
                if isinstance(msg, bytes) and msg[0] == 0x01:  # messageData
                    sid, t_ns = struct.unpack_from("<IQ", msg, 1)
                    self.received.append((sid, t_ns, msg[13:]))
        self._thread = threading.Thread(target=loop, daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)


@pytest.fixture()
def live():
    sink = LiveSink(port=0, linger_s=2.0)  # a loaded CI machine: room for the last messages
    try:
        with connect(f"ws://127.0.0.1:{sink.port}", subprotocols=[SUBPROTOCOL], open_timeout=10) as ws:
            client = Client(ws)
            yield sink, client
            client.close()
    finally:
        sink.close()


def test_every_channel_is_advertised_with_its_schema(live):
    _, client = live
    client.read_advertisements(set(S.CHANNELS))
    assert set(client.channels) == set(S.CHANNELS)
    for topic, spec in S.CHANNELS.items():
        ch = client.channels[topic]
        assert (ch["encoding"], ch["schemaName"], ch["schemaEncoding"]) == \
            (spec.message_encoding, spec.schema_name, spec.schema_encoding)
        schema = ch["schema"].encode() if spec.schema_encoding == "jsonschema" else base64.b64decode(ch["schema"])
        assert schema == spec.schema_data


def test_a_subscribed_client_receives_the_flight_as_recorded(live, tmp_path):
    sink, client = live
    topics = [S.TOPIC_TREE, S.TOPIC_RADAR_PICTURE, S.TOPIC_SCENE_RADAR]
    client.read_advertisements(set(topics))
    subs = client.subscribe(topics)
    client.start()
    # The server takes the subscription asynchronously: probe until one arrives, then fly.
    probe = S.json_bytes({"t": 0.0, "tick": None, "root": "INVALID", "tip": "probe", "changes": []})
    deadline = time.monotonic() + 10
    while not client.received and time.monotonic() < deadline:
        sink.write(S.CHANNELS[S.TOPIC_TREE], 0, probe)
        time.sleep(0.05)
    assert client.received, "the subscription never took effect"
    path = tmp_path / "live.mcap"
    fly(path, sinks=[sink])
    deadline = time.monotonic() + 10
    log = read_log(path)
    expected = {t: [(round(m.t * 1e9), m.data) for m in log.topic(t)] for t in topics}
    total = sum(len(v) for v in expected.values())
    while time.monotonic() < deadline:  # let the last messages arrive
        got = [r for r in client.received if r[2] != probe]
        if len(got) >= total:
            break
        time.sleep(0.05)
    for sid, topic in subs.items():
        got = [(t_ns, data) for s, t_ns, data in client.received if s == sid and data != probe]
        assert got == expected[topic], topic
    assert expected[S.TOPIC_TREE] and expected[S.TOPIC_RADAR_PICTURE]
