"""Retasking a flying aircraft: what is refused (and changes nothing), and a hand-over in the air."""

from __future__ import annotations

import textwrap
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from chaser_bt.mission.retask import FileWatcher, RetaskRejected, RetaskRequest, prepare, spliced_hash, tree_hash
from chaser_bt.vehicle.state import VehicleState

HOVER_LONG = textwrap.dedent("""\
    version: 1
    main: Long
    trees:
      Long:
        Sequence:
          children:
            - ArmAndTakeoff: {altitude_m: 15}
            - Hover: {name: hold for ever, duration_s: 500}
    """)
LAND = textwrap.dedent("""\
    version: 1
    main: Down
    trees:
      Down:
        Sequence:
          children:
            - Hover: {name: settle, duration_s: 2}
            - Land: {name: land here, wait_landed: true}
    """)


def _link(sysid: int | None = 1, **state) -> SimpleNamespace:
    return SimpleNamespace(target_sysid=sysid, state=VehicleState(**state))


def _request(text: str | bytes, name: str = "new.yaml", sysid: int | None = None) -> RetaskRequest:
    data = text.encode() if isinstance(text, str) else text
    return RetaskRequest(data, name, Path("."), "test", sysid)


_JSON_TYPES = {"string": str, "number": (int, float), "integer": int, "boolean": bool, "null": type(None)}


def _assert_fits_retask_schema(record: dict) -> None:
    """``record`` has exactly the fields of the flight log's /tree/retask schema, each of a type it allows."""
    import json

    from chaser_bt.log.schemas import CHANNELS, TOPIC_RETASK

    properties = json.loads(CHANNELS[TOPIC_RETASK].schema_data)["properties"]
    assert set(record) == set(properties)
    for key, value in record.items():
        allowed = properties[key]["type"]
        allowed = [allowed] if isinstance(allowed, str) else allowed
        assert any(isinstance(value, _JSON_TYPES[t]) and not (isinstance(value, bool) and t != "boolean")
                   for t in allowed), (key, value, allowed)


@pytest.mark.parametrize("request_, link, resources, why", [
    (_request(b"\xff\xfe binary"), _link(), {}, "byte 0 is not UTF-8"),
    (_request("  \n"), _link(), {}, "empty"),
    (_request("version: 1\ntrees: [\n"), _link(), {}, "new.yaml:"),
    (_request("version: 1\ntrees:\n  T:\n    NoSuchNode: {}\n"), _link(), {}, "NoSuchNode"),
    (_request("version: 1\ntrees:\n  T:\n    RadarCue: {}\n"), _link(), {}, "radar"),
    (_request(LAND, sysid=7), _link(1), {}, "for vehicle 7, this is vehicle 1"),
    (_request(LAND), _link(armed=True, mode="RTL"), {}, "the autopilot is flying RTL"),
    (_request(LAND), _link(telemetry_fault="a second sender"), {}, "not trusted"),
])
def test_a_retask_that_cannot_be_taken_is_one_line_saying_why(request_, link, resources, why):
    with pytest.raises(RetaskRejected, match=why) as exc:
        prepare(request_, link, resources)
    assert "\n" not in str(exc.value) and str(exc.value).startswith("retask new.yaml (test): ")


def test_a_valid_retask_for_this_vehicle_is_built():
    tree = prepare(_request(LAND, sysid=1), _link(1, armed=True, mode="GUIDED"), {})
    assert tree.name == "Down"
    assert tree_hash(LAND.encode()) == tree_hash(LAND.encode()) != tree_hash(HOVER_LONG.encode())


def test_the_file_watcher_offers_a_change_once_it_has_settled(tmp_path):
    path, t = tmp_path / "next.yaml", [0.0]
    path.write_text(HOVER_LONG)
    watcher = FileWatcher(path, settle_s=0.5, monotonic=lambda: t[0])
    assert watcher.poll() is None  # the file as it was at start is not a retask
    path.write_text("version: 1\ntrees:\n")  # half-written ...
    t[0] = 0.1
    assert watcher.poll() is None
    path.write_text(LAND)  # ... and finished
    for t[0] in (0.2, 0.5):
        assert watcher.poll() is None  # still settling
    t[0] = 0.8
    offered = watcher.poll()
    assert offered is not None and offered.data == LAND.encode() and offered.name == "next.yaml"
    t[0] = 2.0
    assert watcher.poll() is None  # offered once


def _scenario(tmp_path: Path, retasks: str, faults: str = "[]"):
    from sitl.world.scenario import load_scenario

    (tmp_path / "long.yaml").write_text(HOVER_LONG)
    (tmp_path / "land.yaml").write_text(LAND)
    (tmp_path / "broken.yaml").write_text("version: 1\ntrees:\n  T:\n    Hover: {duration_s: -3}\n")
    (tmp_path / "scenario.yaml").write_text(textwrap.dedent(f"""\
        name: retask
        home: {{lat_deg: 42.5445, lon_deg: -71.6105, alt_m: 80.0}}
        boot: {{gps_fix_s: 1.0, ekf_ready_s: 2.0, prearm_ok_s: 3.0}}
        time_limit_s: 90
        faults: {faults}
        retask: {retasks}
        """))
    return load_scenario(tmp_path / "scenario.yaml")


def test_a_rehearsal_retasks_in_the_air_and_a_broken_retask_changes_nothing(tmp_path):
    from sitl.bench.rehearsal import rehearse
    from sitl.bench.sensors import SensorOptions

    import json

    from chaser_bt.log.recorder import Recorder, TopicSink
    from chaser_bt.log.schemas import TOPIC_RETASK

    scenario = _scenario(tmp_path, "[{at_s: 20, tree: broken.yaml}, {at_s: 30, tree: land.yaml}]")
    sink, recorders = TopicSink(TOPIC_RETASK), []

    def record(runner, vehicle, resources):  # the flight log's view (Foxglove shows this topic)
        recorders.append(Recorder([sink], runner.clock.now).attach(runner, vehicle.link, resources))

    report = rehearse(tmp_path / "long.yaml", scenario, 1, sensors=SensorOptions(camera=False, radar=False), trace=True,
                      on_start=record)
    recorders[0].close()
    assert [json.loads(r)["accepted"] for r in sink.records] == [False, True]
    for r in sink.records:  # a whole tree's retask: subtree null, as the schema allows
        assert json.loads(r)["subtree"] is None
        _assert_fits_retask_schema(json.loads(r))
    refused, taken = report.retasks
    assert report.retasks_scheduled == 2
    assert not refused["accepted"] and "broken.yaml" in refused["message"] and refused["t"] == pytest.approx(20, abs=0.1)
    assert taken["accepted"] and taken["old_hash"] == refused["old_hash"] == tree_hash(HOVER_LONG.encode())
    assert taken["new_hash"] == tree_hash(LAND.encode())
    # The long hover (500 s) was replaced: the aircraft landed and the new tree completed.
    assert report.outcome == "landed" and report.mission_outcome == "completed", report.message
    events = [e for e in report.trace.events if e.name == "retask"]
    assert [("taken" in e.detail) for e in events] == [False, True]
    # Held at the hand-over: from the retask to the new tree's landing, the aircraft never drifted.
    tr = report.trace
    window = (tr.t >= taken["t"]) & (tr.t <= taken["t"] + 2.0)
    assert np.all(np.linalg.norm(np.diff(tr.ownship_enu[window, :2], axis=0), axis=1) < 0.5)


def test_a_retask_during_a_link_loss_leaves_the_aircraft_safe(tmp_path):
    """The radio goes silent from 28 s to 40 s: the retask at 30 s is taken on the mission's side,
    its hold is lost in the silence, the autopilot's link-loss failsafe flies; the run ends safe and
    says what happened."""
    from sitl.bench.rehearsal import rehearse
    from sitl.bench.sensors import SensorOptions

    scenario = _scenario(tmp_path, "[{at_s: 30, tree: land.yaml}]", "[{at_s: 28, kind: link_loss, duration_s: 12}]")
    report = rehearse(tmp_path / "long.yaml", scenario, 1, sensors=SensorOptions(camera=False, radar=False))
    assert report.final_state not in ("moving", "falling", "crashed"), report
    # Mission time is the vehicle's: silent from 28 s, it reads 27.9 s when the retask is offered at 30 s.
    (retask,) = report.retasks
    assert retask["accepted"] and 27.5 <= retask["t"] <= 30.0
    assert report.mission_outcome != "completed" or report.outcome == "landed"


def test_run_takes_retasks_from_the_watched_file_and_the_uplink(tmp_path):
    import argparse

    from chaser_bt.cli import _retask_sources
    from chaser_bt.ground.uplink import GroundCommand

    class _Uplink:
        def __init__(self):
            self.queued = [GroundCommand("retask", 1, name="a.yaml", tree="old", sysid=1),
                           GroundCommand("replace_subtree", 2, name="leg.yaml", tree="old", sysid=1, subtree="Leg"),
                           GroundCommand("designate", 3, track_id=5),
                           GroundCommand("retask", 4, name="b.yaml", tree=LAND, sysid=1)]

        def take(self, *kinds):
            taken = [c for c in self.queued if c.kind in kinds]
            self.queued = [c for c in self.queued if c.kind not in kinds]
            return taken

    runner = SimpleNamespace(retask_sources=[])
    args = argparse.Namespace(reload_from=tmp_path / "next.yaml", reload_subtree=None, tree=str(tmp_path / "flying.yaml"))
    fake = _Uplink()
    _retask_sources(runner, args, {"uplink": fake})
    watch, uplink = runner.retask_sources
    assert watch() is None  # no file yet
    offered = uplink()
    assert (offered.name, offered.data, offered.sysid, offered.base_dir) == ("b.yaml", LAND.encode(), 1, tmp_path)
    assert offered.subtree is None
    assert uplink() is None
    assert [c.kind for c in fake.queued] == ["designate"]  # the designation is left for its leaves


# -- replacing one subtree -------------------------------------------------------------------------

MISSION = textwrap.dedent("""\
    version: 1
    main: Mission
    trees:
      Mission:
        Sequence:
          name: mission
          children:
            - ArmAndTakeoff: {name: take off, altitude_m: 15}
            - SubTree: {ID: Leg, name: leg}
            - Land: {name: land, wait_landed: true}
      Leg:
        Sequence:
          name: old leg
          children:
            - Hover: {name: hold, duration_s: 500}
    """)
NEW_LEG = textwrap.dedent("""\
    version: 1
    main: Leg
    trees:
      Leg:
        Sequence:
          name: new leg
          children:
            - Hover: {name: settle, duration_s: 2}
    """)
# Two instances of Climb, each remapping the subtree's altitude_m; a helper tree Pause.
CLIMBS = textwrap.dedent("""\
    version: 1
    main: Mission
    trees:
      Mission:
        Sequence:
          children:
            - SubTree: {ID: Climb, name: climb, altitude_m: 20}
            - SubTree: {ID: Pause}
            - SubTree: {ID: Climb, name: climb again, altitude_m: 30}
      Climb:
        ArmAndTakeoff: {name: old climb, altitude_m: "{altitude_m}"}
      Pause:
        Hover: {name: pause, duration_s: 1}
    """)


def _running(tmp_path: Path, text: str):
    from chaser_bt.tree import load_tree
    from chaser_bt.tree.documents import read_document

    path = tmp_path / "running.yaml"
    path.write_text(text)
    tree = load_tree(path)
    return tree, read_document(path)[0]


def _subtree_request(text: str | bytes, subtree: str, sysid: int | None = None) -> RetaskRequest:
    data = text.encode() if isinstance(text, str) else text
    return RetaskRequest(data, "new.yaml", Path("."), "test", sysid, subtree)


def _shape(node) -> list:
    """The running tree as (name, id of the behaviour, status) for every node, depth first."""
    return [(n.name, id(n), n.status) for n in node.iterate()]


def _climb(step: str, more: str = "") -> str:
    """A replacement Climb that fits the call sites (it reads altitude_m), then does ``step``."""
    return textwrap.dedent(f"""\
        version: 1
        main: Climb
        trees:
          Climb:
            Sequence:
              children:
                - ArmAndTakeoff: {{altitude_m: "{{altitude_m}}"}}
                - {step}
        """) + more


@pytest.mark.parametrize("text, subtree, link, resources, document, why", [
    (NEW_LEG, "Nope", _link(), {}, True, "the running tree has no subtree 'Nope'; its subtrees: Climb, Pause"),
    (NEW_LEG, "Mission", _link(), {}, True, "no subtree 'Mission'"),
    # the call sites remap altitude_m, which the replacement does not use (it reads alt)
    ('version: 1\ntrees:\n  Climb:\n    ArmAndTakeoff: {altitude_m: "{alt}"}\n', "Climb", _link(), {}, True,
     "SubTree 'Climb' uses no key 'altitude_m'; its keys: alt"),
    (_climb("Hover: {duration_s: -3}"), "Climb", _link(), {}, True,
     "new.yaml:8:31: port 'duration_s' of Hover must be 0..86400, got -3"),
    (_climb("NoSuchNode: {}"), "Climb", _link(), {}, True, "unknown node 'NoSuchNode'"),
    ("version: 1\ntrees: [\n", "Climb", _link(), {}, True, "new.yaml:"),
    (b"\xff binary", "Climb", _link(), {}, True, "byte 0 is not UTF-8"),
    (_climb("Hover: {duration_s: 1}"), "Climb", _link(1), {}, True, None),  # wrong vehicle: sysid below
    (_climb("RadarCue: {}"), "Climb", _link(), {}, True, "radar"),
    (_climb("Hover: {duration_s: 1}"), "Climb", _link(armed=True, mode="RTL"), {}, True, "the autopilot is flying RTL"),
    # the replacement brings its own Pause, unlike the running one
    (_climb("SubTree: {ID: Pause}", "  Pause:\n    Hover: {duration_s: 9}\n"), "Climb", _link(), {}, True,
     "the replacement's tree 'Pause' differs from the running tree's"),
    (_climb("Hover: {duration_s: 1}"), "Climb", _link(), {}, False, "not read from a file"),
])
def test_a_subtree_retask_that_cannot_be_taken_says_why_and_changes_nothing(tmp_path, text, subtree, link, resources,
                                                                           document, why):
    from chaser_bt.mission.retask import prepare_subtree

    running, running_document = _running(tmp_path, CLIMBS)
    before, wiring = _shape(running.root), dict(running.wiring)
    sysid = 7 if why is None else None
    why = why or "for vehicle 7, this is vehicle 1"
    with pytest.raises(RetaskRejected) as exc:
        prepare_subtree(_subtree_request(text, subtree, sysid), link, resources, running,
                        running_document if document else None)
    message = str(exc.value)
    assert why in message and "\n" not in message and message.startswith(f"retask new.yaml (test): subtree {subtree}: ")
    assert _shape(running.root) == before and running.wiring == wiring


def test_a_subtree_replacement_goes_in_at_every_instance_under_its_call_sites_remapping(tmp_path):
    """The replacement file's tree named like the subtree is taken (not its main tree); both Climb
    instances get one, each reading its own call site's altitude; Pause and the root stay the same objects."""
    from chaser_bt.log.groot2.tree_xml import describe_tree
    from chaser_bt.mission.retask import prepare_subtree
    from chaser_bt.tree.decorators import SubTree

    running, document = _running(tmp_path, CLIMBS)
    replacement = textwrap.dedent("""\
        version: 1
        main: Other
        trees:
          Other:
            Hover: {name: other}
          Climb:
            Sequence:
              name: new climb
              children:
                - ArmAndTakeoff: {name: up, altitude_m: "{altitude_m}", tolerance_m: 2}
                - Hover: {name: steady, duration_s: 3}
        """)
    splice = prepare_subtree(_subtree_request(replacement, "Climb"), _link(), {}, running, document)
    wrappers = [n for n in running.root.iterate() if isinstance(n, SubTree) and n.name.startswith("climb")]
    assert [site.wrapper for site in splice.sites] == wrappers
    assert [site.path for site in splice.sites] == ["/climb", "/climb_again"]
    assert [site.old.name for site in splice.sites] == ["old climb", "old climb"]
    assert [[n.name for n in site.new.iterate()] for site in splice.sites] == [["up", "steady", "new climb"]] * 2
    ups = [site.new.children[0] for site in splice.sites]
    assert [splice.tree.wiring[up.id]["altitude_m"] for up in ups] == ["20.0", "30.0"]
    assert splice.tree.wiring[ups[0].id]["tolerance_m"] == "2.0"
    pause, root = running.root.children[1], running.root
    splice.apply()
    assert [w.decorated.name for w in wrappers] == ["new climb", "new climb"]
    assert running.root.children[1] is pause and splice.tree.root is root
    names = [m.behaviour.name for m in describe_tree(splice.tree).nodes]  # Groot2 sees the spliced tree
    assert "old climb" not in names and names.count("up") == 2 and "pause" in names


def _subtree_scenario(tmp_path: Path, retasks: str, faults: str = "[]"):
    from sitl.world.scenario import load_scenario

    (tmp_path / "mission.yaml").write_text(MISSION)
    (tmp_path / "leg.yaml").write_text(NEW_LEG)
    (tmp_path / "scenario.yaml").write_text(textwrap.dedent(f"""\
        name: retask subtree
        home: {{lat_deg: 42.5445, lon_deg: -71.6105, alt_m: 80.0}}
        boot: {{gps_fix_s: 1.0, ekf_ready_s: 2.0, prearm_ok_s: 3.0}}
        time_limit_s: 90
        faults: {faults}
        retask: {retasks}
        """))
    return load_scenario(tmp_path / "scenario.yaml")


def _spied_rehearsal(tmp_path: Path, scenario, on_start=None):
    """Rehearse mission.yaml; the runner, and how many hover commands each retask sent."""
    from sitl.bench.rehearsal import rehearse
    from sitl.bench.sensors import SensorOptions

    seen: dict = {"hovers": [], "in_retask": []}

    def start(runner, vehicle, resources):
        seen["runner"] = runner
        link, retask = vehicle.link, runner.retask
        hover = link.hover

        def counted_hover():
            seen["hovers"].append(runner.clock.now())
            return hover()

        def counted_retask(request):
            before = len(seen["hovers"])
            record = retask(request)
            seen["in_retask"].append(len(seen["hovers"]) - before)
            return record

        link.hover, runner.retask = counted_hover, counted_retask
        if on_start is not None:
            on_start(runner, vehicle, resources)

    report = rehearse(tmp_path / "mission.yaml", scenario, 1, sensors=SensorOptions(camera=False, radar=False),
                      trace=True, on_start=start)
    return report, seen


def _changes(runner) -> list[tuple[str, str, str]]:
    """The tick log up to the root's end (after it the runner's stop resets every node)."""
    out = []
    for c in runner.tick_log:
        out.append((c.node, c.old, c.new))
        if c.node == "mission" and c.new == "SUCCESS":
            break
    return out


def test_a_subtree_replaced_mid_mission_keeps_the_parents_progress(tmp_path):
    """Take off, then the leg hovers for 500 s; at 20 s a retask names a subtree the tree has not
    (refused: nothing changes), at 30 s the leg is replaced by a 2 s hover. The mission's Sequence
    stays past its take-off: the old leg is halted, the new one runs from its start, then the land."""
    import json

    from chaser_bt.log.groot2.btlog import BtlogWriter, read_btlog
    from chaser_bt.log.recorder import Recorder, TopicSink
    from chaser_bt.log.schemas import TOPIC_RETASK

    scenario = _subtree_scenario(tmp_path, "[{at_s: 20, tree: leg.yaml, subtree: Nope}, "
                                           "{at_s: 30, tree: leg.yaml, subtree: Leg}]")
    sink, kept = TopicSink(TOPIC_RETASK), []

    def record(runner, vehicle, resources):
        kept.append(Recorder([sink], runner.clock.now).attach(runner, vehicle.link, resources))
        kept.append(BtlogWriter(runner.tree, tmp_path / "flight.btlog").attach(runner))

    report, seen = _spied_rehearsal(tmp_path, scenario, record)
    for k in kept:
        k.close()
    runner = seen["runner"]
    assert report.outcome == "landed" and report.mission_outcome == "completed", report.message
    # Worked out by hand: the Sequence's statuses, children before parents within a tick (the tick log's order).
    assert _changes(runner) == [
        ("take off", "INVALID", "RUNNING"), ("mission", "INVALID", "RUNNING"),
        ("take off", "RUNNING", "SUCCESS"), ("hold", "INVALID", "RUNNING"), ("old leg", "INVALID", "RUNNING"),
        ("leg", "INVALID", "RUNNING"),
        ("hold", "RUNNING", "INVALID"), ("old leg", "RUNNING", "INVALID"),  # the hand-over: the old leg alone halted
        ("settle", "INVALID", "RUNNING"), ("new leg", "INVALID", "RUNNING"),  # the next tick: the new leg from its start
        ("settle", "RUNNING", "SUCCESS"), ("new leg", "RUNNING", "SUCCESS"), ("leg", "RUNNING", "SUCCESS"),
        ("land", "INVALID", "RUNNING"),
        ("land", "RUNNING", "SUCCESS"), ("mission", "RUNNING", "SUCCESS"),
    ]
    refused, taken = report.retasks
    assert not refused["accepted"] and "no subtree 'Nope'" in refused["message"]
    assert taken["accepted"] and taken["subtree"] == "Leg" and taken["t"] == pytest.approx(30, abs=0.1)
    old = tree_hash(MISSION.encode())
    assert taken["old_hash"] == refused["old_hash"] == old
    assert taken["new_hash"] == spliced_hash(old, "Leg", NEW_LEG.encode()) != old
    assert "/leg halted, aircraft held" in taken["message"]
    halted = [c.t for c in runner.tick_log if c.node == "hold" and c.new == "INVALID"]
    settled = [c.t for c in runner.tick_log if c.node == "settle" and c.new == "SUCCESS"]
    assert halted == [pytest.approx(taken["t"], abs=0.05)] and settled[0] - halted[0] == pytest.approx(2.1, abs=0.15)
    # The halted Hover's exit hold and the runner's hold; nothing at the refused one.
    assert seen["in_retask"] == [0, 2]
    # The flight log, the trace and Groot2's log show it as they show a whole-tree retask.
    assert [(json.loads(r)["accepted"], json.loads(r)["subtree"]) for r in sink.records] == [(False, "Nope"), (True, "Leg")]
    for r in sink.records:
        _assert_fits_retask_schema(json.loads(r))
    assert [("taken" in e.detail) for e in report.trace.events if e.name == "retask"] == [False, True]
    first, second = read_btlog(tmp_path / "flight.btlog"), read_btlog(tmp_path / "flight-2.btlog")
    assert 'name="hold"' in first.xml and 'name="settle"' in second.xml and 'name="hold"' not in second.xml
    assert 'name="take off"' in second.xml


def test_a_subtree_not_running_is_swapped_without_a_hold(tmp_path):
    """At 5 s the aircraft is still taking off: the leg has not started, so it is swapped as it is
    (nothing halted, no hover sent) and the new leg is the one that runs after the take-off."""
    scenario = _subtree_scenario(tmp_path, "[{at_s: 5, tree: leg.yaml, subtree: Leg}]")
    report, seen = _spied_rehearsal(tmp_path, scenario)
    assert report.outcome == "landed" and report.mission_outcome == "completed", report.message
    (taken,) = report.retasks
    assert taken["accepted"] and "/leg not running, swapped" in taken["message"]
    assert seen["in_retask"] == [0]
    assert _changes(seen["runner"]) == [
        ("take off", "INVALID", "RUNNING"), ("mission", "INVALID", "RUNNING"),
        ("take off", "RUNNING", "SUCCESS"), ("settle", "INVALID", "RUNNING"), ("new leg", "INVALID", "RUNNING"),
        ("leg", "INVALID", "RUNNING"),
        ("settle", "RUNNING", "SUCCESS"), ("new leg", "RUNNING", "SUCCESS"), ("leg", "RUNNING", "SUCCESS"),
        ("land", "INVALID", "RUNNING"),
        ("land", "RUNNING", "SUCCESS"), ("mission", "RUNNING", "SUCCESS"),
    ]


def test_a_subtree_retask_in_a_link_fault_still_ends_with_a_command_in_force(tmp_path):
    """The radio is silent from 29 s to 32 s; the subtree retask at 30 s is taken in the silence
    (the halted leg's hold and the runner's are sent, and lost). The aircraft keeps the last hold it
    heard, and once the link is back the new leg commands it: it holds, then lands the mission."""
    scenario = _subtree_scenario(tmp_path, "[{at_s: 30, tree: leg.yaml, subtree: Leg}]",
                                 "[{at_s: 29, kind: link_loss, duration_s: 3}]")
    report, seen = _spied_rehearsal(tmp_path, scenario)
    runner = seen["runner"]
    (taken,) = report.retasks
    # Mission time is the vehicle's: silent from 29 s, it reads 28.9 s when the retask is offered.
    assert taken["accepted"] and 28.5 <= taken["t"] <= 29.0 and seen["in_retask"] == [2]
    started = [c.t for c in runner.tick_log if c.node == "settle" and c.new == "RUNNING"]
    assert len(started) == 1 and started[0] >= 31.9  # the first tick with the link back
    assert report.outcome == "landed" and report.mission_outcome == "completed", report.message
    assert [c.new for c in runner.tick_log if c.node == "take off"][:2] == ["RUNNING", "SUCCESS"]
    assert sum(1 for c in runner.tick_log if c.node == "take off" and c.new == "RUNNING") == 1
    # From the hand-over until the new leg's hold, the aircraft never drifted.
    tr = report.trace
    window = (tr.t >= 30.0) & (tr.t <= 32.5)
    assert np.all(np.linalg.norm(np.diff(tr.ownship_enu[window, :2], axis=0), axis=1) < 0.5)


def test_a_watched_file_and_the_uplink_can_name_a_subtree(tmp_path):
    """The file watcher's subtree; over the uplink, a replace_subtree command after a retask (the latest wins)."""
    import argparse
    import socket
    import time

    from chaser_bt.cli import _retask_sources
    from chaser_bt.ground.auth import StreamSigner
    from chaser_bt.ground.uplink import UplinkReceiver, replace_subtree_datagram, retask_datagram

    path, t = tmp_path / "leg.yaml", [0.0]
    watcher = FileWatcher(path, settle_s=0.5, monotonic=lambda: t[0], subtree="Leg")
    path.write_text(NEW_LEG)
    assert watcher.poll() is None
    t[0] = 1.0
    offered = watcher.poll()
    assert (offered.data, offered.subtree, offered.label) == (NEW_LEG.encode(), "Leg",
                                                              f"retask leg.yaml (file {path}): subtree Leg")
    key, signer = bytes(range(32)), StreamSigner(bytes(range(32)))
    rx = UplinkReceiver("127.0.0.1", 0, key)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for d in (retask_datagram(signer, "land.yaml", LAND, 1, seq=1),
                  replace_subtree_datagram(signer, "leg.yaml", NEW_LEG, 1, "Leg", seq=2)):
            s.sendto(d, rx.address)
    end = time.monotonic() + 2.0
    while rx.counters.accepted < 2 and time.monotonic() < end:
        rx.poll()
        time.sleep(0.01)
    runner = SimpleNamespace(retask_sources=[])
    args = argparse.Namespace(reload_from=None, reload_subtree=None, tree=str(tmp_path / "mission.yaml"))
    _retask_sources(runner, args, {"uplink": rx})
    (uplink,) = runner.retask_sources
    offered, again = uplink(), uplink()
    rx.close()
    assert (offered.name, offered.data, offered.sysid, offered.subtree, offered.origin) == (
        "leg.yaml", NEW_LEG.encode(), 1, "Leg", "uplink")
    assert offered.label == "retask leg.yaml (uplink): subtree Leg"
    assert again is None


def test_a_scenario_retask_may_name_a_subtree(tmp_path):
    from sitl.world.scenario import ScenarioError, ScheduledRetask

    scenario = _subtree_scenario(tmp_path, "[{at_s: 30, tree: leg.yaml, subtree: Leg}, {at_s: 10, tree: leg.yaml}]")
    assert scenario.retasks == (ScheduledRetask(10.0, tmp_path / "leg.yaml"),
                                ScheduledRetask(30.0, tmp_path / "leg.yaml", "Leg"))
    with pytest.raises(ScenarioError, match="retask.0..subtree"):
        _subtree_scenario(tmp_path, "[{at_s: 30, tree: leg.yaml, subtree: 3}]")


def test_a_scenario_retask_may_name_a_shipped_tree(tmp_path):
    from chaser_bt.shipped import resolve_tree
    from sitl.world.scenario import ScenarioError, ScheduledRetask

    scenario = _subtree_scenario(tmp_path, "[{at_s: 90, tree: sar}]")
    assert scenario.retasks == (ScheduledRetask(90.0, resolve_tree("sar")),)
    assert scenario.retasks[0].tree.name == "sar.yaml"
    with pytest.raises(ScenarioError, match=r"retask.0..tree.*shipped tree's name"):
        _subtree_scenario(tmp_path, "[{at_s: 90, tree: no_such_tree}]")


def test_retasks_chain_on_one_runner_whole_and_subtree_alike(tmp_path):
    """A tick loop on the mission clock, no vehicle needed (Script and Sleep only): a running subtree
    replaced, then the same subtree again once finished, then the whole tree, then a subtree of that
    new tree (known from the retask's own file). Each record's old hash is the previous one's new hash."""
    from chaser_bt.clock import ManualClock
    from chaser_bt.log.groot2.tree_xml import describe_tree
    from chaser_bt.mission.runner import MissionRunner
    from chaser_bt.tree import load_tree
    from chaser_bt.vehicle import VehicleLink, byte_pipe

    running = textwrap.dedent("""\
        version: 1
        main: Main
        trees:
          Main:
            Sequence:
              name: main
              children:
                - Script: {name: first, code: "n := 1"}
                - SubTree: {ID: Stay, name: wait}
                - Sleep: {name: after, msec: 3000}
          Stay:
            Sleep: {name: long, msec: 5000}
        """)
    short = "version: 1\ntrees:\n  Stay:\n    Sleep: {name: short, msec: 1000}\n"
    again = "version: 1\ntrees:\n  Brief:\n    Sleep: {name: brief, msec: 100}\n"
    whole = textwrap.dedent("""\
        version: 1
        main: Next
        trees:
          Next:
            Sequence:
              name: next
              children:
                - SubTree: {ID: Pause, name: pause}
          Pause:
            Sleep: {name: pause sleep, msec: 4000}
        """)
    (tmp_path / "running.yaml").write_text(running)
    clock = ManualClock(0.0)
    runner = MissionRunner(load_tree(tmp_path / "running.yaml"), VehicleLink.over_pipe(byte_pipe()[0], monotonic=clock.now),
                           clock)

    def at(t: float, text: str | None = None, subtree: str | None = None):
        clock.set(t)
        if text is None:
            runner.tick()
            return None
        return runner.retask(RetaskRequest(text.encode(), "r.yaml", tmp_path, "test", subtree=subtree))

    at(0.0)
    first = at(1.0, short, "Stay")
    at(1.0)
    at(2.5)
    second = at(2.6, again, "Stay")  # finished: swapped as it is
    at(3.0)
    third = at(4.0, whole)
    fourth = at(4.0, short, "Pause")
    at(4.1)
    records = [first, second, third, fourth]
    assert all(r.accepted for r in records), [r.message for r in records]
    assert [r.subtree for r in records] == ["Stay", "Stay", None, "Pause"]
    h0 = tree_hash(running.encode())
    h1 = spliced_hash(h0, "Stay", short.encode())
    h2 = spliced_hash(h1, "Stay", again.encode())
    h3 = tree_hash(whole.encode())
    assert [(r.old_hash, r.new_hash) for r in records] == [(h0, h1), (h1, h2), (h2, h3),
                                                           (h3, spliced_hash(h3, "Pause", short.encode()))]
    assert "/wait halted" in first.message and "held" not in first.message  # Sleep commands no aircraft
    assert "/wait not running, swapped" in second.message
    assert [(c.t, c.node, c.old, c.new) for c in runner.tick_log] == [
        (0.0, "first", "INVALID", "SUCCESS"), (0.0, "long", "INVALID", "RUNNING"), (0.0, "wait", "INVALID", "RUNNING"),
        (0.0, "main", "INVALID", "RUNNING"),
        (1.0, "long", "RUNNING", "INVALID"),  # the subtree alone is halted; main stays past "first"
        (1.0, "short", "INVALID", "RUNNING"),
        (2.5, "short", "RUNNING", "SUCCESS"), (2.5, "wait", "RUNNING", "SUCCESS"), (2.5, "after", "INVALID", "RUNNING"),
        # 2.6: "brief" goes in where "short" finished; main is past it and does not run it
        # 4.0, the whole tree: everything halted ("short" is out of the tree, "brief" never ran)
        (4.0, "first", "SUCCESS", "INVALID"), (4.0, "wait", "SUCCESS", "INVALID"), (4.0, "after", "RUNNING", "INVALID"),
        (4.0, "main", "RUNNING", "INVALID"),
        (4.1, "short", "INVALID", "RUNNING"), (4.1, "pause", "INVALID", "RUNNING"), (4.1, "next", "INVALID", "RUNNING"),
    ]
    names = [m.behaviour.name for m in describe_tree(runner.tree).nodes]
    assert names == ["next", "pause", "short"]


def test_a_document_that_is_not_the_running_tree_refuses_a_subtree_retask(tmp_path):
    from chaser_bt.mission.retask import prepare_subtree
    from chaser_bt.tree.documents import parse_document

    running, _ = _running(tmp_path, CLIMBS)
    other, _ = parse_document(CLIMBS.replace("name: pause", "name: rest"), "other.yaml")
    with pytest.raises(RetaskRejected, match="the running tree is not the one its document describes .at 'pause'."):
        prepare_subtree(_subtree_request(_climb("Hover: {duration_s: 1}"), "Climb"), _link(), {}, running, other)
