"""Retasking a flying aircraft: what is refused (and changes nothing), and a hand-over in the air."""

from __future__ import annotations

import textwrap
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from chaser_bt.mission.retask import FileWatcher, RetaskRejected, RetaskRequest, prepare, tree_hash
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
    refused, taken = report.retasks
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
                           GroundCommand("retask", 2, name="b.yaml", tree=LAND, sysid=1)]

        def take(self, kind):
            taken, self.queued = ([c for c in self.queued if c.kind == kind], [])
            return taken

    runner = SimpleNamespace(retask_sources=[])
    args = argparse.Namespace(reload_from=tmp_path / "next.yaml", tree=str(tmp_path / "flying.yaml"))
    _retask_sources(runner, args, {"uplink": _Uplink()})
    watch, uplink = runner.retask_sources
    assert watch() is None  # no file yet
    offered = uplink()
    assert (offered.name, offered.data, offered.sysid, offered.base_dir) == ("b.yaml", LAND.encode(), 1, tmp_path)
    assert uplink() is None
