"""The uplink: signed designate, retask and replace_subtree commands from the ground, everything else
dropped and counted."""

from __future__ import annotations

import json
import logging
import socket
import time

import py_trees
import pytest

from chaser_bt.ground.auth import StreamSigner, StreamVerifier
from chaser_bt.ground.protocol import json_datagram
from chaser_bt.ground import uplink as uplink_module
from chaser_bt.ground.uplink import (
    GroundCommand,
    UplinkReceiver,
    designate_datagram,
    parse_command,
    replace_subtree_datagram,
    retask_datagram,
)

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))


def _send(port: int, *datagrams: bytes) -> None:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for d in datagrams:
        s.sendto(d, ("127.0.0.1", port))
    s.close()


def _poll(rx: UplinkReceiver, want: int, timeout_s: float = 2.0) -> list[GroundCommand]:
    """Poll until ``want`` datagrams were handled (accepted or dropped), as a tick loop would."""
    out: list[GroundCommand] = []
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        out += rx.poll()
        c = rx.counters
        if c.accepted + c.not_allowed + c.malformed + sum(c.auth.values()) >= want:
            break
        time.sleep(0.01)
    return out


def test_a_signed_designation_is_believed_and_the_rest_is_dropped_by_kind():
    rx = UplinkReceiver("127.0.0.1", 0, KEY)
    port = rx.address[1]
    signer = StreamSigner(KEY, link_id=3)
    good = designate_datagram(signer, 4117, seq=1)
    unknown = signer.sign(json_datagram("command", 2, 0.0, {"command": "land"}))
    negative = signer.sign(json_datagram("command", 3, 0.0, {"command": "designate", "track_id": -1}))
    boolean = signer.sign(json_datagram("command", 4, 0.0, {"command": "designate", "track_id": True}))
    garbage = signer.sign(b"\xff\x00 not json")
    plain = json_datagram("command", 5, 0.0, {"command": "designate", "track_id": 9})
    forged = designate_datagram(StreamSigner(OTHER_KEY), 9)
    assert rx.poll() == []  # nothing yet: returns at once
    _send(port, good, unknown, negative, boolean, garbage, plain, forged, good)  # the last: a replay
    cmds = _poll(rx, 8)
    assert cmds == [GroundCommand("designate", 1, track_id=4117)]
    c = rx.counters
    assert (c.accepted, c.malformed) == (1, 4)
    assert c.auth == {"unsigned": 1, "forged": 1, "replayed": 1}
    rx.close()


def test_commands_from_a_host_not_allowed_are_dropped_even_when_signed():
    rx = UplinkReceiver("127.0.0.1", 0, KEY, allowed_hosts=["10.9.9.9"])
    _send(rx.address[1], designate_datagram(StreamSigner(KEY), 5))
    assert _poll(rx, 1) == [] and rx.counters.not_allowed == 1
    rx.close()


def test_parse_command_names_the_bad_field():
    with pytest.raises(ValueError, match="track_id 'x'"):
        parse_command(json.dumps({"v": 1, "type": "command", "seq": 1, "command": "designate", "track_id": "x"}).encode())
    with pytest.raises(ValueError, match="not a command"):
        parse_command(json_datagram("status", 1, 0.0, {}))
    with pytest.raises(ValueError, match="track id"):
        designate_datagram(StreamSigner(KEY), 2**31)
    retask = {"v": 1, "type": "command", "seq": 2, "command": "retask", "name": "hover.yaml", "tree": "x", "sysid": 1}
    assert parse_command(json.dumps(retask).encode()) == GroundCommand("retask", 2, name="hover.yaml", tree="x", sysid=1)
    with pytest.raises(ValueError, match="name '../x.yaml'"):
        parse_command(json.dumps({**retask, "name": "../x.yaml"}).encode())
    with pytest.raises(ValueError, match="sysid 0"):
        parse_command(json.dumps({**retask, "sysid": 0}).encode())


def test_a_retask_datagram_is_as_it_always_was_and_a_subtree_replacement_is_its_own_kind():
    signer = StreamSigner(KEY)
    whole = retask_datagram(signer, "hover.yaml", "version: 1", 1, seq=1, unix_time=5.0)
    part = replace_subtree_datagram(signer, "leg.yaml", "version: 1", 1, "Leg", seq=2, unix_time=5.0)
    # What goes over the air, written out: a retask has no subtree field; the replacement is another command.
    assert json.loads(StreamVerifier(KEY).open(whole)) == {
        "v": 1, "type": "command", "seq": 1, "t": 5.0, "command": "retask", "name": "hover.yaml", "tree": "version: 1",
        "sysid": 1}
    assert json.loads(StreamVerifier(KEY).open(part)) == {
        "v": 1, "type": "command", "seq": 2, "t": 5.0, "command": "replace_subtree", "name": "leg.yaml",
        "tree": "version: 1", "sysid": 1, "subtree": "Leg"}
    rx = UplinkReceiver("127.0.0.1", 0, KEY)
    _send(rx.address[1], whole, part, designate_datagram(signer, 9, seq=3))
    _poll(rx, 3)
    assert (rx.counters.accepted, rx.counters.malformed) == (3, 0)
    # Each kind to whoever takes it; several kinds come back in the order they arrived.
    assert rx.take("retask", "replace_subtree") == [
        GroundCommand("retask", 1, name="hover.yaml", tree="version: 1", sysid=1),
        GroundCommand("replace_subtree", 2, name="leg.yaml", tree="version: 1", sysid=1, subtree="Leg")]
    assert rx.take("retask", "replace_subtree") == [] and rx.take("designate") == [GroundCommand("designate", 3, track_id=9)]
    with pytest.raises(ValueError, match="land"):
        rx.take("land")
    rx.close()


def test_a_subtree_replacement_names_a_tree_id():
    msg = {"v": 1, "type": "command", "seq": 3, "command": "replace_subtree", "name": "leg.yaml", "tree": "x", "sysid": 2}
    for bad in ("", 7, "a/b", "Leg two", None):
        with pytest.raises(ValueError, match="replace_subtree: subtree"):
            parse_command(json.dumps({**msg, "subtree": bad}).encode())
    with pytest.raises(ValueError, match="replace_subtree: subtree None"):
        parse_command(json.dumps(msg).encode())  # no subtree at all
    with pytest.raises(ValueError, match="replace_subtree: sysid 0"):
        parse_command(json.dumps({**msg, "subtree": "Leg", "sysid": 0}).encode())
    with pytest.raises(ValueError, match="expected a tree ID"):
        replace_subtree_datagram(StreamSigner(KEY), "leg.yaml", "version: 1", 1, "../Leg")


def test_a_retask_that_names_a_subtree_is_refused_and_counted_as_malformed(caplog):
    """A retask with a subtree field (never sent as such) is not flown as the whole tree: dropped, and said why."""
    signer = StreamSigner(KEY)
    fields = {"command": "retask", "name": "leg.yaml", "tree": "version: 1", "sysid": 1}
    rx = UplinkReceiver("127.0.0.1", 0, KEY)
    with caplog.at_level(logging.WARNING, logger="chaser_bt.ground.uplink"):
        _send(rx.address[1], signer.sign(json_datagram("command", 1, 5.0, {**fields, "subtree": "Leg"})),
              signer.sign(json_datagram("command", 2, 5.0, {**fields, "subtree": None})))
        _poll(rx, 2)
    assert (rx.counters.accepted, rx.counters.malformed) == (0, 2)
    assert rx.take("retask", "replace_subtree") == []
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2 and all("dropped a signed datagram" in line for line in lines)
    assert "retask: carries subtree 'Leg'" in lines[0] and "replace_subtree" in lines[0]
    assert "retask: carries subtree None" in lines[1]
    rx.close()


def test_an_aircraft_that_knows_only_designate_and_retask_drops_a_subtree_replacement(monkeypatch):
    """An older reader (its COMMANDS without replace_subtree) drops the replacement as an unknown command:
    counted, and nothing to fly; a retask beside it still gets through."""
    monkeypatch.setattr(uplink_module, "COMMANDS", ("designate", "retask"))
    signer = StreamSigner(KEY)
    rx = UplinkReceiver("127.0.0.1", 0, KEY)
    _send(rx.address[1], replace_subtree_datagram(signer, "leg.yaml", "version: 1", 1, "Leg", seq=1),
          retask_datagram(signer, "hover.yaml", "version: 1", 1, seq=2))
    assert _poll(rx, 2) == [GroundCommand("retask", 2, name="hover.yaml", tree="version: 1", sysid=1)]
    assert (rx.counters.accepted, rx.counters.malformed) == (1, 1)
    with pytest.raises(ValueError, match="command 'replace_subtree': expected one of designate, retask"):
        parse_command(StreamVerifier(KEY).open(replace_subtree_datagram(signer, "leg.yaml", "x", 1, "Leg")))
    rx.close()


def test_each_consumer_takes_its_own_kind():
    rx = UplinkReceiver("127.0.0.1", 0, KEY)
    signer = StreamSigner(KEY)
    _send(rx.address[1], designate_datagram(signer, 7, seq=1), retask_datagram(signer, "hover.yaml", "version: 1", 1, seq=2))
    _poll(rx, 2)
    assert [c.track_id for c in rx.take("designate")] == [7] and rx.take("designate") == []
    (retask,) = rx.take("retask")
    assert (retask.name, retask.tree, retask.sysid) == ("hover.yaml", "version: 1", 1)
    rx.close()


def test_ground_designation_writes_the_operators_track_and_is_off_without_an_uplink():
    from chaser_bt.clock import ManualClock
    from chaser_bt.tree import load_tree_text
    from chaser_bt.vehicle import VehicleLink, byte_pipe

    clock = ManualClock(0.0)
    link = VehicleLink.over_pipe(byte_pipe()[0], monotonic=clock.now)
    py_trees.blackboard.Blackboard.set("/vehicle/state", link.state)
    rx = UplinkReceiver("127.0.0.1", 0, KEY)
    for uplink, expect in ((rx, 77), (None, None)):
        py_trees.blackboard.Blackboard.unset("/radar/operator_confirmed_track")
        tree = load_tree_text("version: 1\ntrees:\n  Main:\n    GroundDesignation: {}\n", source="<test>")
        bt = py_trees.trees.BehaviourTree(tree.root)
        bt.setup(link=link, clock=clock, uplink=uplink)
        if uplink is not None:
            _send(rx.address[1], designate_datagram(StreamSigner(KEY), expect))
            end = time.monotonic() + 2.0
            while py_trees.blackboard.Blackboard.storage.get("/radar/operator_confirmed_track") is None and time.monotonic() < end:
                bt.tick()
                time.sleep(0.01)
            assert "1 command(s), 0 dropped" in bt.root.feedback_message
        else:
            bt.tick()
            assert "uplink off" in bt.root.feedback_message
        assert bt.root.status == py_trees.common.Status.SUCCESS
        assert py_trees.blackboard.Blackboard.storage.get("/radar/operator_confirmed_track") == expect
    rx.close()


def test_chaser_bt_retask_sends_a_retask_and_with_subtree_a_replacement(tmp_path, capsys):
    from chaser_bt.cli import main

    (tmp_path / "uplink.key").write_text(KEY.hex() + "\n")
    tree = "version: 1\nmain: Leg\ntrees:\n  Leg:\n    Hover: {name: settle, duration_s: 2}\n"
    (tmp_path / "leg.yaml").write_text(tree)
    rx = UplinkReceiver("127.0.0.1", 0, KEY)
    common = [str(tmp_path / "leg.yaml"), "--to", f"127.0.0.1:{rx.address[1]}", "--key", str(tmp_path / "uplink.key"),
              "--sysid", "3"]
    assert main(["retask", *common]) == 0
    assert main(["retask", *common, "--subtree", "Leg"]) == 0
    out = capsys.readouterr().out
    assert "retask leg.yaml: sent to vehicle 3" in out and "retask leg.yaml as subtree Leg: sent to vehicle 3" in out
    _poll(rx, 2)
    assert rx.take("retask", "replace_subtree") == [
        GroundCommand("retask", 0, name="leg.yaml", tree=tree, sysid=3),
        GroundCommand("replace_subtree", 0, name="leg.yaml", tree=tree, sysid=3, subtree="Leg")]
    rx.close()
