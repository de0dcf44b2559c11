"""chaser-bt's Groot2 publisher against the bytes BT.CPP 4.10's own Groot2Publisher sent for the same tree.

tests/log/data/groot2/btcpp_replies.json was recorded once by tests/log/groot2_reference/recorder.cpp:
the same tree.xml, the same requests (fixed unique ids), the same ticks. Each request is sent again,
on a REQ socket, to our publisher after the same number of ticks, and the replies must be the same
bytes after normalising only what is random or a clock reading:

- the 16-byte tree UUID in every reply header (BT.CPP's must be a version-4 UUID, ours our own);
- the TOGGLE_RECORDING ``start`` reply, the wall time in microseconds (both must be decimal text);
- the GET_TRANSITIONS timestamps; the transitions themselves are compared node by node in order
  (BT.CPP lists a tick's transitions in callback order, ours in uid order);
- in FULLTREE, the ``<TreeNodesModel>`` after the trees: compared for the nodes the tree uses,
  without ``<MetadataFields>`` (ours carry the docstring); everything before it byte for byte.
"""

from __future__ import annotations

import json
import uuid
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

import pytest

from chaser_bt.log.groot2 import Groot2Publisher

from groot2_client import Client, free_port_pair
from groot2_support import TICKS, reference_tree, ticked_bt

RECORDING = Path(__file__).parent / "data" / "groot2" / "btcpp_replies.json"


@pytest.fixture(scope="module")
def replayed():
    """(name, request, BT.CPP's reply, our reply, our tree id) for every recorded exchange."""
    exchanges = json.loads(RECORDING.read_text())
    tree, registry = reference_tree()
    port = free_port_pair()
    out = []
    with Groot2Publisher(tree, port, registry=registry) as publisher:
        bt = ticked_bt(tree, publisher.visitor)
        client = Client(port)
        ticks = 0
        try:
            for exchange in exchanges:
                name = exchange["name"]
                if name.startswith("status_"):
                    while ticks < int(name.split("_")[1]):
                        bt.tick()
                        ticks += 1
                request = [bytes.fromhex(p) for p in exchange["request"]]
                theirs = [bytes.fromhex(p) for p in exchange["reply"]]
                out.append((name, request, theirs, client.ask_raw(request), publisher.tree_id))
        finally:
            client.close()
    assert ticks == TICKS
    return out


def _by_name(replayed, name):
    return next(entry for entry in replayed if entry[0] == name)


def test_every_reply_header_is_btcpps_but_the_tree_id(replayed):
    for name, request, theirs, ours, tree_id in replayed:
        assert len(ours) == len(theirs), name
        if len(theirs[0]) == 22:
            assert ours[0][:6] == theirs[0][:6] == request[0], name
            assert ours[0][6:] == tree_id
            assert uuid.UUID(bytes=theirs[0][6:]).version == 4
        else:
            assert ours[0] == theirs[0] == b"error", name


def test_fulltree_trees_are_byte_identical(replayed):
    _, _, theirs, ours, _ = _by_name(replayed, "fulltree")
    ours_xml, theirs_xml = ours[1].decode(), theirs[1].decode()
    assert ours_xml.split("<TreeNodesModel>")[0] == theirs_xml.split("<TreeNodesModel>")[0]
    assert ours_xml.endswith("    </TreeNodesModel>\n</root>\n")


def _models(xml_text: str, ids: set[str]) -> dict[str, tuple]:
    model = ET.fromstring(xml_text).find("TreeNodesModel")
    out = {}
    for node in model:
        if node.get("ID") in ids:
            ports = sorted((p.tag, p.get("name"), p.get("type"), p.get("default"), (p.text or "").strip())
                           for p in node if p.tag != "MetadataFields")
            out[node.get("ID")] = (node.tag, ports)
    return out


def test_fulltree_models_the_nodes_the_tree_uses_as_btcpp(replayed):
    _, _, theirs, ours, _ = _by_name(replayed, "fulltree")
    root = ET.fromstring(theirs[1])
    used = {e.tag for tree in root.findall("BehaviorTree") for e in tree.iter()} - {"BehaviorTree", "SubTree"}
    assert used == {"Sequence", "AlwaysSuccess", "Fallback", "Inverter", "Countdown"}
    assert _models(ours[1].decode(), used) == _models(theirs[1].decode(), used)


def test_status_after_every_tick_is_byte_identical(replayed):
    names = [f"status_{i}" for i in range(TICKS + 1)]
    for name in names:
        _, _, theirs, ours, _ = _by_name(replayed, name)
        assert ours[1] == theirs[1], name


def _per_node(payload: bytes) -> dict[int, list[int]]:
    nodes = defaultdict(list)
    for i in range(0, len(payload), 9):  # 6-byte timestamp, uid u16, status u8
        nodes[int.from_bytes(payload[i + 6:i + 8], "little")].append(payload[i + 8])
    return dict(nodes)


def test_transitions_of_every_tick_match_node_by_node(replayed):
    seen = 0
    for i in range(1, TICKS + 1):
        _, _, theirs, ours, _ = _by_name(replayed, f"transitions_{i}")
        assert _per_node(ours[1]) == _per_node(theirs[1]), f"tick {i}"
        seen += len(theirs[1]) // 9
        stamps = [int.from_bytes(ours[1][j:j + 6], "little") for j in range(0, len(ours[1]), 9)]
        assert all(0 <= s < 60_000_000 for s in stamps)  # microseconds since recording started
    assert seen == 38  # the recording is not trivially empty


def test_recording_start_answers_the_wall_time(replayed):
    _, _, theirs, ours, _ = _by_name(replayed, "recording_start")
    assert theirs[1].isdigit() and ours[1].isdigit()
    assert len(ours[1]) == len(theirs[1]) == 16  # microseconds since 1970: 16 digits until 2286


@pytest.mark.parametrize("name", ["recording_stop", "hooks_dump", "remove_all_hooks", "disable_all_hooks",
                                  "hook_remove", "hook_remove_one_part", "blackboard_one_part", "unknown_type",
                                  "short_header"])
def test_other_replies_are_byte_identical(replayed, name):
    _, _, theirs, ours, _ = _by_name(replayed, name)
    assert ours[1:] == theirs[1:]
    if ours[0] != b"error":
        assert ours[0][:6] == theirs[0][:6]
