"""Groot2's live monitor over real sockets: a client written from the protocol header asks while a tree ticks.

The expected statuses follow BT.CPP's rules (behaviortree.dev, the Groot2Publisher source): a node
shows RUNNING/SUCCESS/FAILURE while its parent runs, 10 + its last status once reset (12 = idle
after SUCCESS), and a node that never ran 0. The uids come from the FULLTREE reply itself, as Groot2
reads them.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from chaser_bt.cli import main
from chaser_bt.log.groot2 import Groot2Error, Groot2Publisher
from chaser_bt.log.groot2.tree_xml import describe_tree
from chaser_bt.tree import load_tree_text
from chaser_bt.tree.conversion import convert_text

from groot2_client import Client, free_port_pair, statuses
from groot2_support import TREE_XML, reference_tree, registry, ticked_bt

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "sitl" / "scenarios" / "patrol.yaml"


@pytest.fixture
def served():
    tree, reg = reference_tree()
    port = free_port_pair()
    publisher = Groot2Publisher(tree, port, registry=reg)
    client = Client(port)
    yield tree, publisher, client
    client.close()
    publisher.close()


def _uids(xml_text: bytes) -> dict[str, int]:
    """Node path (subtree instance/name) -> uid, read from a FULLTREE reply."""
    out = {}
    for tree in ET.fromstring(xml_text).findall("BehaviorTree"):
        for element in tree.iter():
            if "_uid" in element.attrib:
                name = element.get("name") or element.get("_fullpath")
                out[f"{tree.get('_fullpath')}/{name}"] = int(element.get("_uid"))
    return out


def test_statuses_follow_the_ticks(served):
    tree, publisher, client = served
    _, (header, xml_text) = client.ask("T")
    uids = _uids(xml_text)
    assert len(uids) == 15 and sorted(uids.values()) == list(range(1, 16))
    bt = ticked_bt(tree, publisher.visitor)

    def now() -> dict[str, int]:
        request_id, (reply_header, payload) = client.ask("S")
        assert reply_header[:6] == b"\x02S" + request_id.to_bytes(4, "little")
        by_uid = statuses(payload)
        return {path: by_uid[uid] for path, uid in uids.items()}

    assert set(now().values()) == {0}
    bt.tick()
    s = now()
    assert (s["/mission"], s["/preflight"], s["/optional"], s["/outbound"]) == (1, 2, 0, 1)
    assert (s["outbound/leg"], s["outbound/fly"], s["outbound/arrive"]) == (1, 1, 0)
    bt.tick()
    bt.tick()  # outbound's leg finished: its nodes were reset; the fallback runs
    s = now()
    assert (s["/outbound"], s["outbound/leg"], s["outbound/fly"], s["outbound/arrive"]) == (2, 12, 12, 12)
    assert (s["/choose"], s["/not_ok"], s["/ok"], s["/hold"]) == (1, 3, 12, 1)
    for _ in range(3):
        bt.tick()
    s = now()
    assert bt.root.status.name == "SUCCESS"
    assert s["/optional"] == 0  # skipped: BT.CPP keeps a skipped node IDLE
    assert all(code == 12 for path, code in s.items() if path not in ("/optional", "/not_ok"))
    assert s["/not_ok"] == 13


def test_statuses_are_served_while_another_thread_ticks(served):
    tree, publisher, client = served
    bt = ticked_bt(tree, publisher.visitor)
    stop = threading.Event()

    def tick_forever() -> None:
        while not stop.is_set():
            bt.tick()
            if bt.root.status.name == "SUCCESS":
                bt.root.stop()
            time.sleep(0.001)

    ticker = threading.Thread(target=tick_forever)
    ticker.start()
    try:
        seen = set()
        for _ in range(200):
            _, (_, payload) = client.ask("S")
            assert len(payload) == 45
            seen.update(statuses(payload).values())
    finally:
        stop.set()
        ticker.join()
    assert {1, 2, 12} <= seen


def test_recording_returns_the_transitions_once(served):
    tree, publisher, client = served
    bt = ticked_bt(tree, publisher.visitor)
    bt.tick()  # before recording: not recorded
    _, (_, started) = client.ask("r", b"start")
    assert abs(int(started) / 1e6 - time.time()) < 5
    bt.tick()
    bt.tick()
    _, (_, payload) = client.ask("t")
    changes = [(int.from_bytes(payload[i + 6:i + 8], "little"), payload[i + 8]) for i in range(0, len(payload), 9)]
    uids = _uids(client.ask("T")[1][1])
    assert (uids["outbound/fly"], 2) in changes and (uids["outbound/fly"], 0) in changes
    assert (uids["/preflight"], 2) not in changes  # it succeeded on the first tick
    assert client.ask("t")[1][1] == b""  # handed out once
    client.ask("r", b"stop")
    bt.tick()
    assert client.ask("t")[1][1] == b""


def test_breakpoints_are_refused_and_unknown_requests_answer_errors(served):
    _, _, client = served
    _, reply = client.ask("I", b'{"uid": 2, "position": 0, "enabled": true, "mode": 0, "once": false, '
                               b'"desired_status": "SUCCESS"}')
    assert reply[0] == b"error" and b"breakpoints are not supported" in reply[1]
    assert client.ask("B")[1] == [b"error", b"must be 2 parts message"]
    assert client.ask("Q")[1] == [b"error", b"Request not recognized"]
    assert client.ask_raw([b"\x02S"]) == [b"error", b"wrong request header"]
    assert client.ask("D")[1][1] == b"[]"
    assert client.ask("S")[1][1]  # still serving


def test_blackboard_reply_holds_the_wired_entries(served):
    tree, publisher, client = served
    bt = ticked_bt(tree, publisher.visitor)
    bt.tick()
    # {"Main": null}: the reference tree wires no port to the blackboard (msgpack: map of 1, fixstr, nil)
    assert client.ask("B", b"Main;nope")[1][1] == b"\x81\xa4Main\xc0"
    assert client.ask("B", b"nope")[1][1] == b"\xc0"


def test_bound_to_loopback_unless_asked(served):
    _, publisher, _ = served
    assert publisher.host == "127.0.0.1"
    endpoint = publisher.endpoints
    assert endpoint == (f"tcp://127.0.0.1:{publisher.port}", f"tcp://127.0.0.1:{publisher.port + 1}")


def test_a_taken_port_is_an_error_and_close_frees_both_ports():
    tree, reg = reference_tree()
    port = free_port_pair()
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", port + 1))
        with pytest.raises(Groot2Error, match=str(port)):
            Groot2Publisher(tree, port, registry=reg)
    publisher = Groot2Publisher(tree, port, registry=reg)
    publisher.close()
    publisher.close()
    for p in (port, port + 1):
        with socket.socket() as s:
            s.bind(("127.0.0.1", p))


def test_a_monitor_fault_is_logged_and_the_tick_goes_on(served, monkeypatch, caplog):
    tree, publisher, client = served
    bt = ticked_bt(tree, publisher.visitor)

    def broken(ticked):
        raise RuntimeError("mirror broke")

    monkeypatch.setattr(publisher._mirror, "update", broken)
    with caplog.at_level(logging.ERROR):
        bt.tick()
        bt.tick()
    assert bt.root.status.name == "RUNNING"
    assert caplog.text.count("status update failed") == 1  # logged once, not at every tick
    assert client.ask("S")[1][1]


def test_yaml_and_xml_forms_of_a_tree_describe_alike():
    reg = registry()
    text = TREE_XML.read_text()
    yaml_text = convert_text(text, "tree.xml", "yaml", registry=reg)
    from_xml = describe_tree(load_tree_text(text, "tree.xml", reg), reg)
    from_yaml = describe_tree(load_tree_text(yaml_text, "tree.yaml", reg), reg)
    assert from_yaml.xml == from_xml.xml
    assert [n.uid for n in from_yaml.nodes] == [n.uid for n in from_xml.nodes]


# -- the CLI ------------------------------------------------------------------------------------


# 400 s of simulated waiting: a couple of wall-clock seconds at the patrol's ~200x, long enough for the
# monitor's client to catch the Wait running (30 s passed in 0.17 s, before the client's first ask).
HOLD = """\
<root BTCPP_format="4">
  <BehaviorTree ID="Hold">
    <Sequence name="hold">
      <Wait name="wait" duration_s="400"/>
      <AlwaysSuccess name="done"/>
    </Sequence>
  </BehaviorTree>
</root>
"""


def test_rehearse_serves_groot2_during_the_flight_and_frees_the_port(tmp_path, capsys):
    path = tmp_path / "hold.xml"
    path.write_text(HOLD)
    port = free_port_pair()
    result = {}
    flight = threading.Thread(target=lambda: result.update(code=main(
        ["rehearse", str(path), "--scenario", str(SCENARIO), "--no-camera", "--no-radar", "--groot2", str(port)])))
    flight.start()
    client = Client(port)
    try:
        _, (_, xml_text) = client.ask("T")
        uids = _uids(xml_text)
        seen = []
        while flight.is_alive() and 1 not in seen:
            seen.append(statuses(client.ask("S")[1][1])[uids["/wait"]])
            time.sleep(0.01)
    finally:
        client.close()
        flight.join(60)
    assert result["code"] == 0
    assert 1 in seen  # Groot2 saw the Wait RUNNING
    assert uids == {"/hold": 1, "/wait": 2, "/done": 3}
    assert f"port {port}" in capsys.readouterr().err
    for p in (port, port + 1):
        with socket.socket() as s:
            s.bind(("127.0.0.1", p))


def test_run_refuses_a_taken_groot2_port_before_connecting(tmp_path, capsys):
    path = tmp_path / "hold.xml"
    path.write_text(HOLD)
    port = free_port_pair()
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", port))
        assert main(["run", str(path), "--connect", "tcp:127.0.0.1:9", "--groot2", str(port)]) == 2
    assert "--groot2" in capsys.readouterr().err


def test_run_closes_the_monitor_when_the_flight_cannot_start(tmp_path, capsys):
    path = tmp_path / "hold.xml"
    path.write_text(HOLD)
    port = free_port_pair()
    assert main(["run", str(path), "--connect", "tcp:nowhere", "--groot2", str(port),
                 "--groot2-host", "127.0.0.1"]) == 2
    for p in (port, port + 1):
        with socket.socket() as s:
            s.bind(("127.0.0.1", p))


def test_groot2_port_defaults_to_btcpps(monkeypatch):
    from chaser_bt.cli import _parser

    args = _parser(["rehearse"]).parse_args(["rehearse", "trees/t.xml", "--scenario", "sitl/s.yaml", "--groot2"])
    assert (args.groot2, args.groot2_host) == (1667, "127.0.0.1")
    args = _parser(["run"]).parse_args(["run", "trees/t.xml", "--connect", "tcp:h:1", "--groot2", "5000",
                                        "--groot2-host", "0.0.0.0"])
    assert (args.groot2, args.groot2_host) == (5000, "0.0.0.0")
    assert _parser(["run"]).parse_args(["run", "trees/t.xml", "--connect", "tcp:h:1"]).groot2 is None


def test_run_serves_groot2_while_flying_the_simulator(tmp_path, capsys):
    from sitl.world.scenario import load_scenario
    from sitl.server import serve

    path = tmp_path / "hold.xml"
    path.write_text(HOLD.replace('duration_s="30"', 'duration_s="20"'))
    urls: list[str] = []
    ready = threading.Event()
    stop = threading.Event()

    def on_ready(found: list[str]) -> None:
        urls.extend(found)
        ready.set()

    sim = threading.Thread(target=serve, args=(load_scenario(SCENARIO),),
                           kwargs=dict(speedup=10.0, tcp_port=0, udp_port=0, ready=on_ready, stop=stop))
    sim.start()
    port = free_port_pair()
    result = {}
    try:
        assert ready.wait(30)
        url = next(u for u in urls if u.startswith("tcp:"))
        flight = threading.Thread(target=lambda: result.update(code=main(
            ["run", str(path), "--connect", url, "--groot2", str(port)])))
        flight.start()
        client = Client(port)
        try:
            uids = _uids(client.ask("T")[1][1])
            seen = []
            while flight.is_alive() and 1 not in seen:
                seen.append(statuses(client.ask("S")[1][1])[uids["/wait"]])
                time.sleep(0.01)
        finally:
            client.close()
            flight.join(60)
    finally:
        stop.set()
        sim.join(30)
    assert result["code"] == 0, capsys.readouterr()
    assert 1 in seen
    for p in (port, port + 1):
        with socket.socket() as s:
            s.bind(("127.0.0.1", p))


def test_a_retask_serves_the_new_tree_under_a_new_tree_id(served):
    tree, publisher, client = served
    _, (header_before, xml_before) = client.ask("T")
    other = load_tree_text("version: 1\ntrees:\n  Other:\n    Sequence:\n      children:\n        - AlwaysSuccess: {}\n",
                           source="<retask>")
    publisher.serve_tree(other)
    _, (header_after, xml_after) = client.ask("T")
    assert b'ID="Other"' in xml_after and b'ID="Other"' not in xml_before
    assert header_after[6:] != header_before[6:]  # the reply header's tree id: Groot2 reloads on a new one
