"""chaser-bt's Groot2 publisher against the bytes BT.CPP 4.10's own Groot2Publisher sent for the same trees.

The recordings in tests/log/data/groot2/ were made once by tests/log/groot2_reference/recorder.cpp
(its README): the same tree file, the same requests (fixed unique ids), the same ticks. Each request
is sent again, on a REQ socket, to our publisher after the same number of ticks, and the replies must
be the same bytes after normalising only what is random, a clock reading or unordered in BT.CPP:

- the 16-byte tree UUID in every reply header (BT.CPP's must be a version-4 UUID, ours our own);
- the TOGGLE_RECORDING ``start`` reply, the wall time in microseconds (both must be decimal text);
- the GET_TRANSITIONS timestamps; transitions are compared node by node in order (BT.CPP lists a
  tick's transitions in callback order, ours in uid order). Both tick the root exactly once a step
  (the recorder calls ``tickExactlyOnce``, as BT.CPP's conformance traces do);
- FULLTREE: the trees before ``<TreeNodesModel>`` byte for byte, but for semantics.xml element by
  element with attributes as a mapping (BT.CPP writes ports in its
  ``unordered_map`` order). The node model is compared for the nodes the tree uses, without
  ``<MetadataFields>`` (ours carry the docstring) and, for BT.CPP's built-in nodes, without the port
  descriptions (ours are worded afresh): kinds, port names, directions, types and defaults agree.

The STATUS payload, what Groot2 paints the tree with, is compared byte for byte after every tick; so
is the BLACKBOARD reply (msgpack) after the last.
"""

from __future__ import annotations

import json
import uuid
import xml.etree.ElementTree as ET
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import pytest

from chaser_bt.log.groot2 import Groot2Publisher

from groot2_client import Client, free_port_pair
from groot2_support import DECORATORS_XML, HALTS_XML, SEMANTICS_XML, TREE_XML, reference_tree, ticked_bt

DATA = Path(__file__).parent / "data" / "groot2"


@dataclass(frozen=True)
class Exchange:
    name: str
    request: list[bytes]
    theirs: list[bytes]
    ours: list[bytes]


@dataclass(frozen=True)
class Replay:
    exact: bool  # byte-exact tree text (all but semantics.xml: see the docstring)
    ticks: int
    tree_id: bytes
    exchanges: dict[str, Exchange]


CASES = {"tree": (TREE_XML, DATA / "btcpp_replies.json", True, 6),
         "semantics": (SEMANTICS_XML, DATA / "btcpp_semantics.json", False, 14),
         "halts": (HALTS_XML, DATA / "btcpp_halts.json", True, 10),
         "decorators": (DECORATORS_XML, DATA / "btcpp_decorators.json", True, 12)}


@pytest.fixture(scope="module", params=sorted(CASES))
def replay(request) -> Replay:
    tree_path, recording, exact, expected_ticks = CASES[request.param]
    recorded = json.loads(recording.read_text())
    tree, registry = reference_tree(tree_path)
    port = free_port_pair()
    exchanges = {}
    ticks = 0
    with Groot2Publisher(tree, port, registry=registry) as publisher:
        bt = ticked_bt(tree, publisher.visitor)
        client = Client(port)
        try:
            for entry in recorded:
                name = entry["name"]
                if name.startswith("status_"):
                    while ticks < int(name.split("_")[1]):
                        bt.tick()
                        ticks += 1
                parts = [bytes.fromhex(p) for p in entry["request"]]
                theirs = [bytes.fromhex(p) for p in entry["reply"]]
                exchanges[name] = Exchange(name, parts, theirs, client.ask_raw(parts))
        finally:
            client.close()
    assert ticks == expected_ticks
    return Replay(exact, ticks, publisher.tree_id, exchanges)


def test_every_reply_header_is_btcpps_but_the_tree_id(replay):
    for e in replay.exchanges.values():
        assert len(e.ours) == len(e.theirs), e.name
        if len(e.theirs[0]) == 22:
            assert e.ours[0][:6] == e.theirs[0][:6] == e.request[0], e.name
            assert e.ours[0][6:] == replay.tree_id
            assert uuid.UUID(bytes=e.theirs[0][6:]).version == 4
        else:
            assert e.ours[0] == e.theirs[0] == b"error", e.name


def _elements(element: ET.Element) -> tuple:
    return element.tag, dict(element.attrib), [_elements(child) for child in element]


def test_fulltree_trees_are_btcpps(replay):
    e = replay.exchanges["fulltree"]
    ours, theirs = e.ours[1].decode(), e.theirs[1].decode()
    assert ours.endswith("    </TreeNodesModel>\n</root>\n")
    if replay.exact:
        assert ours.split("<TreeNodesModel>")[0] == theirs.split("<TreeNodesModel>")[0]
    trees = [[_elements(t) for t in ET.fromstring(x).findall("BehaviorTree")] for x in (ours, theirs)]
    assert trees[0] == trees[1]
    assert ET.fromstring(ours).attrib == ET.fromstring(theirs).attrib == {"BTCPP_format": "4"}


CUSTOM = {"Countdown", "Tally"}  # declared alike in recorder.cpp, descriptions included


def _models(xml_text: str, ids: set[str]) -> dict[str, tuple]:
    out = {}
    for node in ET.fromstring(xml_text).find("TreeNodesModel"):
        node_id = node.get("ID")
        if node_id in ids:
            ports = sorted((p.tag, p.get("name"), p.get("type"), p.get("default"),
                            (p.text or "").strip() if node_id in CUSTOM else "")
                           for p in node if p.tag != "MetadataFields")
            out[node_id] = (node.tag, ports)
    return out


def test_fulltree_models_the_nodes_the_tree_uses_as_btcpp(replay):
    e = replay.exchanges["fulltree"]
    root = ET.fromstring(e.theirs[1])
    used = {x.tag for tree in root.findall("BehaviorTree") for x in tree.iter()} - {"BehaviorTree", "SubTree"}
    assert "Countdown" in used
    models = _models(e.ours[1].decode(), used)
    assert models == _models(e.theirs[1].decode(), used)
    assert set(models) == used


def test_status_after_every_tick_is_byte_identical(replay):
    for i in range(replay.ticks + 1):
        e = replay.exchanges[f"status_{i}"]
        assert e.ours[1] == e.theirs[1], e.name


def _per_node(payload: bytes) -> dict[int, list[int]]:
    nodes = defaultdict(list)
    for i in range(0, len(payload), 9):  # 6-byte timestamp, uid u16, status u8
        nodes[int.from_bytes(payload[i + 6:i + 8], "little")].append(payload[i + 8])
    return dict(nodes)


def test_transitions_of_every_tick_match_node_by_node(replay):
    recorded = 0
    for i in range(1, replay.ticks + 1):
        e = replay.exchanges[f"transitions_{i}"]
        ours, theirs = _per_node(e.ours[1]), _per_node(e.theirs[1])
        assert ours == theirs, f"tick {i}"
        recorded += len(e.theirs[1]) // 9
        stamps = [int.from_bytes(e.ours[1][j:j + 6], "little") for j in range(0, len(e.ours[1]), 9)]
        assert all(0 <= s < 60_000_000 for s in stamps)  # microseconds since recording started
    assert recorded >= 38  # the recordings are not trivially empty


def test_recording_start_answers_the_wall_time(replay):
    e = replay.exchanges["recording_start"]
    assert e.theirs[1].isdigit() and e.ours[1].isdigit()
    assert len(e.ours[1]) == len(e.theirs[1]) == 16  # microseconds since 1970: 16 digits until 2286


@pytest.mark.parametrize("name", ["recording_stop", "blackboard", "blackboard_unknown", "hooks_dump", "remove_all_hooks",
                                  "disable_all_hooks", "hook_remove", "hook_remove_one_part", "blackboard_one_part",
                                  "unknown_type", "short_header"])
def test_other_replies_are_byte_identical(replay, name):
    e = replay.exchanges[name]
    assert e.ours[1:] == e.theirs[1:]
    if e.ours[0] != b"error":
        assert e.ours[0][:6] == e.theirs[0][:6]
