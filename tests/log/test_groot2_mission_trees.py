"""The mission trees as Groot2 receives them: our FULLTREE trees against BT.CPP 4.10's for the same files.

tests/log/groot2_reference/missions/ holds the mission trees as they were when BT.CPP's publisher
was asked for their FULLTREE (``groot2_recorder --fulltree``, with a stand-in registered for every
chaser-bt node from its declared ports: tests/log/groot2_reference/README.md). The trees must agree
element by element, attributes as mappings (BT.CPP writes ports in ``unordered_map`` order): names,
uids, SubTree paths, ports as written plus the defaults of the unwritten, pre-conditions. BT.CPP
4.10 refuses an explicit ``<Condition ID=...>`` under a ReactiveSequence (its XML check looks the
element name up as a node id), so patrol was recorded from ``patrol_compact.xml``, the same tree
with compact elements. If a behaviour's declared ports change, record again (the README).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from chaser_bt.log.groot2.tree_xml import describe_tree
from chaser_bt.tree import load_tree

HERE = Path(__file__).parent
MISSIONS = HERE / "groot2_reference" / "missions"
RECORDED = HERE / "data" / "groot2"


def _trees(xml_text: str) -> list[tuple]:
    def element(e: ET.Element) -> tuple:
        return e.tag, dict(e.attrib), [element(c) for c in e]

    return [element(t) for t in ET.fromstring(xml_text).findall("BehaviorTree")]


@pytest.mark.parametrize("tree_file, recording", [
    ("chase.xml", "btcpp_fulltree_chase.xml"),
    ("sar.xml", "btcpp_fulltree_sar.xml"),
    ("patrol.xml", "btcpp_fulltree_patrol.xml"),
    ("patrol_compact.xml", "btcpp_fulltree_patrol.xml"),
])
def test_mission_tree_is_described_as_btcpp_describes_it(tree_file, recording):
    ours = describe_tree(load_tree(MISSIONS / tree_file))
    theirs = (RECORDED / recording).read_text()
    assert _trees(ours.xml) == _trees(theirs)
    uids = [int(e.get("_uid")) for t in ET.fromstring(theirs).findall("BehaviorTree") for e in t.iter() if e.get("_uid")]
    assert sorted(uids) == sorted(n.uid for n in ours.nodes) == list(range(1, len(uids) + 1))


def test_a_yaml_twin_is_described_as_its_xml():
    """trees/chase.yaml is trees/chase.xml in YAML: typed literals are written as BT.CPP text."""
    root = HERE.parents[1] / "trees"
    assert _trees(describe_tree(load_tree(root / "chase.yaml")).xml) == _trees(describe_tree(load_tree(root / "chase.xml")).xml)
