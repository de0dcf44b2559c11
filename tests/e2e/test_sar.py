"""Search and rescue (issue 8 part 3): the same tree as the chase but for subtrees and parameters, and a rehearsal that finds the person."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import py_trees
import pytest

from chaser_bt.tree import default_registry, validate_tree
from chaser_bt.tree.conversion import typed_document
from chaser_bt.tree.documents import read_document
from chaser_bt.tree.model import SUBTREE_ID, NodeSpec, TreeDocument

ROOT = Path(__file__).resolve().parents[2]
TREES = ROOT / "trees"


def typed(path: Path) -> TreeDocument:
    doc, problems = read_document(path)
    assert problems == [], problems
    return typed_document(doc, default_registry())


def model_diff(chase: TreeDocument, sar: TreeDocument) -> tuple[list[tuple[str, str]], set[str]]:
    """Every difference between two missions' models, as (kind, where), and the subtrees both instantiate in the same slot.

    Kinds: ``subtree`` (a SubTree slot instantiates another tree), ``param`` (a port value or a
    subtree parameter, including given vs default), ``name`` (an instance label: no effect on what
    the node does), ``structure`` (anything else: another node, other children, other
    pre-conditions, a subtree both use in the same slot defined differently).
    """
    out: list[tuple[str, str]] = []
    shared: set[str] = set()

    def walk(c: NodeSpec, s: NodeSpec, where: str) -> None:
        here = f"{where}/{c.display_name}"
        if c.node_id != s.node_id:
            out.append(("structure", f"{here}: {c.node_id} -> {s.node_id}"))
            return
        if c.conditions != s.conditions or len(c.children) != len(s.children):
            out.append(("structure", f"{here}: pre-conditions or children"))
            return
        if c.name != s.name:
            out.append(("name", f"{here} -> {s.display_name}"))
        if c.node_id == SUBTREE_ID:
            if c.subtree.autoremap != s.subtree.autoremap:
                out.append(("structure", f"{here}: _autoremap"))
            if c.subtree.tree_id != s.subtree.tree_id:
                out.append(("subtree", f"{here}: {c.subtree.tree_id} -> {s.subtree.tree_id}"))
                return
            shared.add(c.subtree.tree_id)
        for port in sorted(set(c.ports) | set(s.ports)):
            a, b = c.ports.get(port), s.ports.get(port)
            if (a is None) != (b is None) or (a is not None and a.value != b.value):
                out.append(("param", f"{here}.{port}: {None if a is None else a.value!r} -> {None if b is None else b.value!r}"))
        for k, (cc, sc) in enumerate(zip(c.children, s.children)):
            walk(cc, sc, f"{here}[{k}]")

    walk(chase.trees[chase.main].root, sar.trees[sar.main].root, "")
    for tree_id in sorted(shared):  # a subtree both missions instantiate must be the same tree in both
        if tree_id not in sar.trees or chase.trees[tree_id].root != sar.trees[tree_id].root:
            out.append(("structure", f"subtree {tree_id} is defined differently"))
    return out, shared


def test_sar_yaml_and_xml_are_the_same_tree():
    a, b = typed(TREES / "sar.yaml"), typed(TREES / "sar.xml")
    assert (a.main, a.trees) == (b.main, b.trees)
    assert validate_tree(TREES / "sar.yaml") == [] and validate_tree(TREES / "sar.xml") == []


def test_sar_differs_from_the_chase_only_in_subtrees_and_parameters():
    chase, sar = typed(TREES / "chase.yaml"), typed(TREES / "sar.yaml")
    diff, shared = model_diff(chase, sar)
    assert [d for d in diff if d[0] == "structure"] == [], json.dumps(diff, indent=1)
    # The slots swapped: the radar's (the operator's cue), the launch (the chase climbs towards the
    # radar cue, LaunchToCue; the search climbs straight up, Launch), the last state (report the find
    # and hold over it instead of following) and the search (tuned for a person); safety and fly-out
    # are the chase's own subtrees, in the same slots.
    swapped_in = {where.rsplit(" -> ", 1)[1] for kind, where in diff if kind == "subtree"}
    assert swapped_in == {"SarCue", "Launch", "SarFind", "SarSearch"}, diff
    assert {"Safety", "FlyOut"} <= shared
    params = [where for kind, where in diff if kind == "param"]
    assert any(p.endswith(".detector: None -> 'PERSON_YOLO'") for p in params)  # the person detector in the detector slot


def test_the_diff_sees_a_node_swapped_outside_a_subtree_slot():
    sar = typed(TREES / "sar.yaml")
    changed = copy.deepcopy(sar)
    pursue = changed.trees[changed.main].root.children[1].children[1]
    pursue.children[0] = copy.deepcopy(pursue.children[0])
    pursue.children[0].node_id = "Hover"
    kinds = {k for k, _ in model_diff(sar, changed)[0]}
    assert kinds == {"structure"}
    assert model_diff(sar, sar)[0] == []
    # A parameter and a subtree choice are seen as such.
    changed = copy.deepcopy(sar)
    launch = changed.trees[changed.main].root.children[1].children[1].children[2].children[0]  # launch, then search
    launch.ports["altitude_m"].value = 40.0
    assert [k for k, _ in model_diff(sar, changed)[0]] == ["param"]
    launch.subtree.tree_id = "SarCue"
    assert [k for k, _ in model_diff(sar, changed)[0]] == ["subtree"]
    # A subtree both use in the same slot but defined differently is structure.
    changed = copy.deepcopy(sar)
    changed.trees["Launch"].root.children[0].node_id = "Hover"
    assert [k for k, _ in model_diff(sar, changed)[0]] == ["structure"]


PERSON_WEIGHTS = ROOT / "chaser_bt" / "vision" / "weights" / "person_yolo.pt"
SEED = 5  # the person lies 56 m from the last-known position: fly out, search, find (~140 s simulated)
CAMERA_SIZE = (416, 312)
EXPECTED_PHASES = ["launch", "fly_to_cue", "search", "check", "loiter", "return"]  # "wait" lasts less than a tick


@pytest.mark.slow
@pytest.mark.skipif(not PERSON_WEIGHTS.exists(), reason="the person detector's weights are not shipped")
def test_sar_rehearsal_finds_the_person_reports_and_lands():
    import torch

    from sitl.bench.rehearsal import rehearse
    from sitl.bench.sensors import SensorOptions

    torch.set_num_threads(1)
    phases: list[str] = []

    def on_start(runner, vehicle, resources):
        def phase(changes) -> None:
            p = py_trees.blackboard.Blackboard.storage.get("/mission/phase")
            if p and (not phases or phases[-1] != p):
                phases.append(p)

        runner.on_tick(phase)

    report = rehearse(TREES / "sar.yaml", ROOT / "sitl" / "scenarios" / "sar.yaml", SEED,
                      sensors=SensorOptions(camera_size=CAMERA_SIZE), on_start=on_start)
    assert report.sar_found, (report.sar_find_error_m, report.message)  # scored by the rehearsal (sitl/bench/sar_scoring.py)
    assert report.sar_find_error_m < 10.0 and report.sar_t_find_s > 0.0
    # Found, held over the find, came home and landed on its own, through the chase's states.
    assert report.outcome == "landed" and report.landed_dist_m < 3.0, report.message
    assert phases == EXPECTED_PHASES, phases
