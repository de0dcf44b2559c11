"""chaser-bt's ``.btlog`` writer against the files BT.CPP 4.10's own FileLogger2 wrote for the same trees and ticks.

The recordings in tests/log/data/groot2/btcpp_*.btlog were made once by
tests/log/groot2_reference/btlog_recorder.cpp (its README): the Groot2 reference trees, ticked with
``tickExactlyOnce`` at 100 ms, 200 ms, ... after the logger started (the ``_halted`` ones then
``haltTree`` one period later). Here the same trees are ticked as many times by py_trees with a
:class:`BtlogWriter` on a clock that reads 0.1 s, 0.2 s, ... at the ticks (and, for the halted ones,
``stop`` as ``MissionRunner.stop`` does, then ``close``). The files must be the same bytes after
normalising only:

- the start time (8 bytes after the XML): BT.CPP's wall clock when its logger was made; both must
  be microseconds since the epoch;
- the transitions' timestamps (their first 6 bytes): BT.CPP stamps each on the wall clock as it
  happens, a few microseconds to a few milliseconds after its tick began; each is replaced by its
  tick's time, ``timestamp // 100 000 µs * 100 000 µs`` (checked unambiguous: every one lies less
  than 50 ms after its tick). Ours must already be exactly that: the mission clock at the tick;
- the ``<TreeNodesModel>`` of the XML (and so the XML's size field): ours carries chaser-bt's node
  descriptions (``<MetadataFields>``, port descriptions worded afresh), so it is compared as
  tests/log/test_groot2_reference.py compares FULLTREE: the nodes the tree uses, their kinds, port
  names, directions, types and defaults. Everything before it, the trees with their ``_uid``\\ s,
  is byte for byte.

So every transition, uid, status and their order within each tick (BT.CPP's callback order) is
compared byte for byte. BT.CPP's XML is also checked to be byte for byte the FULLTREE its
Groot2Publisher sent for the tree (tests/log/data/groot2/btcpp_*.json), and ours to be what our
publisher serves: the .btlog's XML is the tree as Groot2 gets it.
"""

from __future__ import annotations

import argparse
import json
import struct
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import py_trees
import pytest

from chaser_bt.cli import main
from chaser_bt.log.groot2.btlog import (MAGIC, Btlog, BtlogError, BtlogWriter, encode_header, parse_btlog,
                                        read_btlog)
from chaser_bt.log.groot2.protocol import NodeStatus, Transition, encode_transitions
from chaser_bt.log.groot2.tree_xml import describe_tree
from chaser_bt.tree import load_tree

from groot2_support import DECORATORS_XML, HALTS_XML, SEMANTICS_XML, TREE_XML, reference_tree, ticked_bt

DATA = Path(__file__).parent / "data" / "groot2"
ROOT = Path(__file__).resolve().parents[2]
PERIOD_US = 100_000

# case: (tree, ticks, halted after them, the Groot2 reference recording of the same tree)
CASES = {
    "tree": (TREE_XML, 6, False, "btcpp_replies.json"),
    "semantics": (SEMANTICS_XML, 14, False, "btcpp_semantics.json"),
    "halts": (HALTS_XML, 10, False, "btcpp_halts.json"),
    "decorators": (DECORATORS_XML, 12, False, "btcpp_decorators.json"),
    "tree_halted": (TREE_XML, 4, True, "btcpp_replies.json"),
    "semantics_halted": (SEMANTICS_XML, 6, True, "btcpp_semantics.json"),
    "halts_halted": (HALTS_XML, 5, True, "btcpp_halts.json"),
}


def _ours(tree_path: Path, ticks: int, halted: bool, out: Path) -> tuple[bytes, str, int, int]:
    """Our file for the case, the XML our publisher would serve, and the wall time around the writer's start."""
    tree, registry = reference_tree(tree_path)
    now = [0.0]
    before = time.time_ns() // 1000
    writer = BtlogWriter(tree, out, clock=lambda: now[0], registry=registry)
    after = time.time_ns() // 1000
    bt = ticked_bt(tree, writer.visitor)
    for k in range(1, ticks + 1):
        now[0] = k * PERIOD_US / 1e6
        bt.tick()
    if halted:
        now[0] = (ticks + 1) * PERIOD_US / 1e6
        tree.root.stop(py_trees.common.Status.INVALID)  # MissionRunner.stop
    writer.close()
    return out.read_bytes(), describe_tree(tree, registry).xml, before, after


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request, tmp_path_factory):
    tree_path, ticks, halted, groot2 = CASES[request.param]
    ours, served, before, after = _ours(tree_path, ticks, halted, tmp_path_factory.mktemp("btlog") / "ours.btlog")
    theirs = (DATA / f"btcpp_{request.param}.btlog").read_bytes()
    fulltree = next(e for e in json.loads((DATA / groot2).read_text()) if e["name"] == "fulltree")["reply"][1]
    return {"name": request.param, "ticks": ticks + halted, "ours": ours, "theirs": theirs, "served": served,
            "fulltree": bytes.fromhex(fulltree).decode(), "wall": (before, after)}


def _records(data: bytes, log: Btlog) -> bytes:
    return data[len(data) - 9 * len(log.transitions):]


def _tick_times(log: Btlog) -> list[Transition]:
    """The transitions, each stamped with its tick's time (BT.CPP's: less than half a period after it)."""
    for t in log.transitions:
        assert t.timestamp_us % PERIOD_US < PERIOD_US // 2, t
    return [Transition(t.timestamp_us // PERIOD_US * PERIOD_US, t.uid, t.status) for t in log.transitions]


def test_the_header_is_btcpps(case):
    ours, theirs = case["ours"], case["theirs"]
    assert ours[:19] == theirs[:19] == b"BTCPP4-FileLogger2\x01"
    for data in (ours, theirs):
        log = parse_btlog(data)
        assert struct.unpack_from("<i", data, 19)[0] == len(log.xml.encode())
        assert not log.partial


def test_the_xml_is_the_tree_as_groot2_gets_it(case):
    ours, theirs = parse_btlog(case["ours"]), parse_btlog(case["theirs"])
    assert theirs.xml == case["fulltree"]  # BT.CPP: FileLogger2 writes what its Groot2Publisher serves
    assert ours.xml == case["served"]  # and so do we
    assert ours.xml.split("<TreeNodesModel>")[0] == theirs.xml.split("<TreeNodesModel>")[0]
    root = ET.fromstring(theirs.xml)
    used = {x.tag for tree in root.findall("BehaviorTree") for x in tree.iter()} - {"BehaviorTree", "SubTree"}
    assert _models(ours.xml, used) == _models(theirs.xml, used)
    assert set(_models(ours.xml, used)) == used


def _models(xml_text: str, ids: set[str]) -> dict[str, tuple]:
    """Kind, then (direction, name, type, default) of each port, of the nodes ``ids``."""
    out = {}
    for node in ET.fromstring(xml_text).find("TreeNodesModel"):
        if node.get("ID") in ids:
            out[node.get("ID")] = (node.tag, sorted((p.tag, p.get("name"), p.get("type"), p.get("default"))
                                                    for p in node if p.tag != "MetadataFields"))
    return out


def test_the_start_is_the_wall_time_in_microseconds(case):
    ours, theirs = parse_btlog(case["ours"]), parse_btlog(case["theirs"])
    before, after = case["wall"]
    assert before <= ours.start_us <= after
    assert len(str(theirs.start_us)) == len(str(ours.start_us)) == 16  # µs since 1970: 16 digits until 2286


def test_our_timestamps_are_the_mission_clock_at_each_tick(case):
    ours = parse_btlog(case["ours"])
    assert [t.timestamp_us for t in ours.transitions] == [t.timestamp_us for t in _tick_times(ours)]
    assert {t.timestamp_us // PERIOD_US for t in ours.transitions} <= set(range(1, case["ticks"] + 1))


def test_every_transition_is_btcpps_byte_for_byte(case):
    ours, theirs = parse_btlog(case["ours"]), parse_btlog(case["theirs"])
    assert _records(case["ours"], ours) == encode_transitions(_tick_times(ours))
    assert encode_transitions(_tick_times(ours)) == encode_transitions(_tick_times(theirs))
    assert len(ours.transitions) >= 32  # the recordings are not trivially short


def test_the_whole_file_is_btcpps_but_the_start_timestamps_and_node_models(case):
    """BT.CPP's file with our start, our XML and its timestamps at their ticks is ours, byte for byte."""
    ours, theirs = parse_btlog(case["ours"]), parse_btlog(case["theirs"])
    spliced = encode_header(ours.xml, ours.start_us) + encode_transitions(_tick_times(theirs))
    assert spliced == case["ours"]


def test_every_tick_is_on_disk_before_the_next_and_a_cut_file_reads(tmp_path):
    tree, registry = reference_tree(TREE_XML)
    now = [0.0]
    path = tmp_path / "flight.btlog"
    writer = BtlogWriter(tree, path, clock=lambda: now[0], registry=registry)
    bt = ticked_bt(tree, writer.visitor)
    seen = []
    for k in range(1, 5):
        now[0] = k * 0.1
        bt.tick()
        seen.append(len(read_btlog(path).transitions))  # not closed: a killed flight leaves this
    assert seen == sorted(seen) and seen[0] > 0
    assert writer.transitions == seen[-1]
    data = path.read_bytes()
    cut = parse_btlog(data[:-4])
    assert cut.partial and len(cut.transitions) == seen[-1] - 1
    writer.close()
    writer.close()  # idempotent
    assert read_btlog(path).transitions == parse_btlog(data).transitions  # nothing was running: no halt


def test_not_a_btlog_is_refused(tmp_path):
    with pytest.raises(BtlogError, match="not a BT.CPP FileLogger2 log"):
        parse_btlog(b"\x89MCAP0\r\n" + bytes(40))
    with pytest.raises(BtlogError, match="version"):
        parse_btlog(MAGIC + b"\x02" + bytes(12))
    with pytest.raises(BtlogError, match="ends inside its header"):
        parse_btlog(encode_header("<root/>", 1)[:-3])
    tree, registry = reference_tree(TREE_XML)
    with pytest.raises(BtlogError, match=r"\.btlog"):
        BtlogWriter(tree, tmp_path / "flight.log", registry=registry)


class _Runner:
    """What the writer uses of a MissionRunner: its tree, clock, visitors and retasks."""

    def __init__(self, tree):
        self.tree, self.now, self.retasks = tree, 0.0, []
        self.clock = type("Clock", (), {"now": lambda _self: self.now})()
        self.bt = None

    def add_visitor(self, visitor):
        self.bt = ticked_bt(self.tree, visitor)

    def on_retask(self, listener):
        self.retasks.append(listener)


def test_a_retask_halts_the_old_tree_and_goes_on_in_a_new_file(tmp_path):
    tree, registry = reference_tree(TREE_XML)
    runner = _Runner(tree)
    path = tmp_path / "flight.btlog"
    writer = BtlogWriter(tree, path, registry=registry).attach(runner)
    runner.now = 1.0
    runner.bt.tick()
    new, _ = reference_tree(HALTS_XML)
    tree.root.stop(py_trees.common.Status.INVALID)  # MissionRunner's hand-over halts the old tree
    runner.tree = new
    for listener in runner.retasks:
        listener(type("Retask", (), {"accepted": True})())
    runner.add_visitor(writer.visitor)
    runner.now = 2.5
    runner.bt.tick()
    writer.close()
    first, second = read_btlog(path), read_btlog(tmp_path / "flight-2.btlog")
    assert first.transitions[-1] == Transition(1_000_000, 1, NodeStatus.IDLE)  # the old root, halted at the retask
    assert "ID=\"Main\"" in first.xml and "name=\"gating\"" in second.xml
    assert second.transitions and all(t.timestamp_us == 1_500_000 for t in second.transitions)  # since the retask


def test_btlog_flag_wants_the_suffix_groot2_opens(tmp_path, capsys):
    from chaser_bt.log.commands import RecordingHook, add_recording_arguments

    parser = argparse.ArgumentParser()
    add_recording_arguments(parser)
    with pytest.raises(SystemExit):
        parser.parse_args(["--btlog", str(tmp_path / "flight.mcap")])
    assert ".btlog" in capsys.readouterr().err
    hook = RecordingHook.from_args(parser.parse_args(["--btlog", str(tmp_path / "flight.btlog")]))
    assert hook is not None and hook.record is None and hook.live is None


# -- a rehearsal, and its MCAP log converted --------------------------------------------------------------

TAKEOFF = ROOT / "trees" / "takeoff_land.yaml"
SCENARIO = ROOT / "sitl" / "scenarios" / "patrol.yaml"


@pytest.fixture(scope="module")
def rehearsed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rehearsed")
    btlog, mcap = folder / "flight.btlog", folder / "flight.mcap"
    before = time.time_ns() // 1000
    code = main(["rehearse", str(TAKEOFF), "--scenario", str(SCENARIO), "--no-camera", "--no-radar",
                 "--progress", "never", "--btlog", str(btlog), "--record", str(mcap)])
    return code, btlog, mcap, before


def test_rehearse_btlog_holds_the_tree_and_every_transition_of_the_flight(rehearsed):
    from chaser_bt.log.replay import read_log, recorded_status_changes

    code, btlog, mcap, before = rehearsed
    assert code == 0
    log = read_btlog(btlog)
    assert not log.partial
    assert log.xml == describe_tree(load_tree(TAKEOFF)).xml
    assert before <= log.start_us <= time.time_ns() // 1000
    names = {int(e.get("_uid")): e.get("name") for e in ET.fromstring(log.xml).iter() if e.get("_uid")}
    assert names == {1: "take off and land", 2: "ArmAndTakeoff", 3: "hold over home", 4: "land here"}
    # The flight as the MCAP log recorded it (py_trees' statuses): each node's RUNNING and finishing, at the same times.
    changes = recorded_status_changes(read_log(mcap))
    finishing = {"RUNNING": NodeStatus.RUNNING, "SUCCESS": NodeStatus.SUCCESS, "FAILURE": NodeStatus.FAILURE}
    recorded = [(round((c.t - changes[0].t) * 1e6), c.node, finishing[c.new]) for c in changes if c.new in finishing]
    first = log.transitions[0].timestamp_us
    ours = [(t.timestamp_us - first, names[t.uid], NodeStatus(t.status))
            for t in log.transitions if t.status != NodeStatus.IDLE]
    assert sorted(ours) == sorted(recorded)
    assert [t.status for t in log.transitions[-5:]] == [NodeStatus.IDLE] * 3 + [NodeStatus.SUCCESS, NodeStatus.IDLE]
    assert [t.uid for t in log.transitions[-5:]] == [2, 3, 4, 1, 1]  # BT.CPP: the children's resets, then the root
    every_node = {t.uid for t in log.transitions}
    assert every_node == set(names)


def test_the_converted_mcap_log_is_the_flights_btlog(rehearsed, tmp_path, capsys):
    from chaser_bt.log.replay import read_log

    code, btlog, mcap, _ = rehearsed
    assert code == 0
    out = tmp_path / "converted.btlog"
    assert main(["btlog", str(mcap), str(TAKEOFF), "-o", str(out)]) == 0
    assert str(out) in capsys.readouterr().out
    flown, converted = btlog.read_bytes(), out.read_bytes()
    flown_log, converted_log = parse_btlog(flown), parse_btlog(converted)
    assert converted_log.xml == flown_log.xml
    assert _records(converted, converted_log) == _records(flown, flown_log)  # byte for byte
    assert converted_log.start_us == round(float(read_log(mcap).meta["recorded_at_unix_s"]) * 1e6)


def test_btlog_conversion_refuses_bad_input(tmp_path, capsys):
    assert main(["btlog", str(tmp_path / "nope.mcap"), str(TAKEOFF), "-o", str(tmp_path / "x.btlog")]) == 2
    assert "no such log file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["btlog", str(tmp_path / "nope.mcap"), str(TAKEOFF), "-o", str(tmp_path / "x.txt")])


def test_a_changed_tree_converts_but_exits_1(rehearsed, tmp_path, capsys):
    code, _, mcap, _ = rehearsed
    assert code == 0
    changed = tmp_path / "takeoff_land.yaml"
    changed.write_text(TAKEOFF.read_text().replace("duration_s: 5", "duration_s: 3"))
    out = tmp_path / "changed.btlog"
    assert main(["btlog", str(mcap), str(changed), "-o", str(out)]) == 1
    assert "differ" in capsys.readouterr().err
    assert read_btlog(out).transitions


def test_a_log_fault_never_ends_the_flight(tmp_path, caplog):
    tree, registry = reference_tree(TREE_XML)
    writer = BtlogWriter(tree, tmp_path / "flight.btlog", clock=lambda: 1.0, registry=registry)
    bt = ticked_bt(tree, writer.visitor)
    writer._fh.close()  # the disk went away
    bt.tick()
    bt.tick()
    assert "recording a tick failed" in caplog.text
    assert caplog.text.count("recording a tick failed") == 1  # once, not at every tick
    writer.close()
