"""Intruders: Phantom 4 limits, each trajectory's shape, their own MAVLink, the scenario format."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from chaser_bt.geo import GeoPoint, LocalFrame  # noqa: E402
from chaser_bt.target_telemetry import TargetTelemetry  # noqa: E402
from chaser_bt.vehicle.pipe import byte_pipe  # noqa: E402
from sitl.bench.in_process import InProcessVehicle  # noqa: E402
from sitl.simulator import Simulator  # noqa: E402
from sitl.world.intruders import Intruder, IntruderSpec  # noqa: E402
from sitl.world.scenario import Scenario, ScenarioError  # noqa: E402

FRAME = LocalFrame(GeoPoint(42.5445, -71.6105, 80.0))
DT = 0.02


def fly(spec: IntruderSpec, seconds: float, seed: int = 0):
    it = Intruder(spec, np.random.default_rng(seed), FRAME)
    ts, ps, vs = [], [], []
    for k in range(1, int(seconds / DT) + 1):
        it.step(k * DT, DT)
        ts.append(k * DT)
        ps.append(it.pos.copy())
        vs.append(it.vel.copy())
    return np.array(ts), np.array(ps), np.array(vs)


def evasive(seed_params=None):
    return IntruderSpec("e", 2, (0.0, 0.0, 30.0), "evasive", dict(center=(0.0, 0.0, 35.0), **(seed_params or {})))


def test_evasive_pilot_reaches_and_respects_phantom_4_limits():
    t, p, v = fly(evasive(), 600.0, seed=3)
    h = np.hypot(v[:, 0], v[:, 1])
    assert h.max() <= 20.0 + 1e-9 and h.max() > 19.5  # dashes at full speed
    assert v[:, 2].max() <= 6.0 + 1e-9 and v[:, 2].max() > 5.9  # climbs at 6 m/s
    assert v[:, 2].min() >= -5.0 - 1e-9 and v[:, 2].min() < -4.9  # dives at 5 m/s
    a = np.diff(v, axis=0) / DT
    assert np.hypot(a[:, 0], a[:, 1]).max() <= 8.0 + 1e-6 and np.abs(a[:, 2]).max() <= 4.0 + 1e-6
    # kept in its box and altitude band (a dash may overshoot the band edge briefly)
    assert np.abs(p[:, :2]).max() < 220.0 and p[:, 2].min() > 5.0 and p[:, 2].max() < 70.0


def test_random_pilots_repeat_with_the_seed_and_differ_across_seeds():
    spec = IntruderSpec("r", 2, (0.0, 0.0, 20.0), "random_waypoints", dict(center=(0.0, 0.0, 30.0)))
    _, a, _ = fly(spec, 60.0, seed=1)
    _, b, _ = fly(spec, 60.0, seed=1)
    _, c, _ = fly(spec, 60.0, seed=2)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 10.0


def test_rectangle_pauses_at_each_corner_in_order():
    corners = ((0.0, 100.0, 20.0), (60.0, 100.0, 20.0), (60.0, 0.0, 20.0), (0.0, 0.0, 20.0))
    spec = IntruderSpec("r", 2, (0.0, 0.0, 20.0), "rectangle", dict(corners=corners, speed_mps=6.0, pause_s=5.0))
    t, p, v = fly(spec, 120.0)
    speed = np.linalg.norm(v, axis=1)
    assert speed.max() == pytest.approx(6.0, abs=0.01)
    stopped = speed < 1e-6
    # stops: runs of stillness, each ~5 s long, at the corners in order
    runs, start = [], None
    for k, still in enumerate(stopped):
        if still and start is None:
            start = k
        elif not still and start is not None:
            runs.append((start, k - 1))
            start = None
    visited = [int(np.argmin([np.linalg.norm(p[s] - c) for c in corners])) for s, _ in runs]
    assert visited[:4] == [0, 1, 2, 3]
    for s, e in runs[:4]:
        assert (t[e] - t[s]) == pytest.approx(5.0, abs=0.1)
        assert min(np.linalg.norm(p[s] - np.array(c)) for c in corners) < 0.5


def test_circle_holds_its_radius_and_speed():
    spec = IntruderSpec("c", 2, (40.0, 0.0, 20.0), "circle", dict(center=(0.0, 0.0, 20.0), radius_m=40.0, speed_mps=8.0))
    t, p, v = fly(spec, 120.0)
    late = t > 20.0
    r = np.hypot(p[late, 0], p[late, 1])
    assert np.abs(r - 40.0).max() < 1.0
    assert np.linalg.norm(v[late], axis=1).mean() == pytest.approx(8.0, abs=0.3)


def test_figure_eight_crosses_its_centre_and_spans_its_length():
    spec = IntruderSpec("f", 2, (0.0, 0.0, 20.0), "figure_eight",
                        dict(center=(0.0, 0.0, 20.0), half_length_m=60.0, speed_mps=8.0, heading_rad=math.pi / 2))
    t, p, v = fly(spec, 100.0)
    assert p[:, 1].max() > 55.0 and p[:, 1].min() < -55.0  # long axis north-south
    assert np.abs(p[:, 0]).max() < 35.0  # lobes half as wide
    assert np.sum(np.diff(np.sign(p[:, 1])) != 0) >= 2  # through the centre both ways
    assert np.linalg.norm(v[t > 5], axis=1).mean() == pytest.approx(8.0, abs=0.6)


SCEN = {
    "name": "i", "home": {"lat_deg": 42.5445, "lon_deg": -71.6105, "alt_m": 80.0},
    "intruders": [{"name": "phantom", "sysid": 2, "start_enu_m": [10, 40, 20], "telemetry_hz": 5,
                   "circle": {"center_enu_m": [0, 40, 20], "radius_m": 10, "speed_mps": 4}}],
}


def test_simulator_sends_the_intruders_own_mavlink():
    sim = Simulator(Scenario.from_dict(SCEN), seed=1)
    vehicle_end, ground_end = byte_pipe()
    sim.attach(vehicle_end)
    mav = mavlink2.MAVLink(None)
    msgs = []
    while sim.time_s < 9.9:
        sim.step()
        msgs += mav.parse_buffer(ground_end.read()) or []
    ours = [m for m in msgs if m.get_srcSystem() == 2]
    hb = [m for m in ours if m.get_type() == "HEARTBEAT"]
    pos = [m for m in ours if m.get_type() == "GLOBAL_POSITION_INT"]
    assert len(hb) == 9 and hb[0].type == mavlink2.MAV_TYPE_QUADROTOR  # 1 Hz from t = 1 s
    assert len(pos) == pytest.approx(5 * 9, abs=1)  # 5 Hz
    last = pos[-1]
    enu = LocalFrame(Scenario.from_dict(SCEN).home).to_enu(last.lat * 1e-7, last.lon * 1e-7, last.alt * 1e-3)
    truth = sim.intruders[0]
    assert np.linalg.norm(enu - truth.pos) < 4 * 0.2 + 0.05  # sent up to one period (<= 0.8 m) ago
    assert last.relative_alt == pytest.approx(20_000, abs=5)
    assert any(m.get_srcSystem() == 1 for m in msgs)  # the vehicle still speaks


def test_the_link_locks_onto_the_vehicle_and_telemetry_cues_the_intruder():
    v = InProcessVehicle(Scenario.from_dict(SCEN), seed=1)  # default LinkConfig: the first autopilot heard
    tel = TargetTelemetry.attach(v.link, v.clock.now)
    v.run_until(lambda: v.link.frame is not None and tel.latest_fix(2) is not None and v.sim.time_s > 5, 30)
    assert v.link.target_sysid == 1
    assert tel.systems == [2]  # the vehicle's own position reports are not a target
    cue = tel.cue(v.link.frame)
    assert cue.source == "telemetry" and cue.track_id == 2
    assert np.linalg.norm(cue.position_enu - v.sim.intruders[0].pos) < 1.0
    assert np.linalg.norm(cue.velocity_enu - v.sim.intruders[0].vel) < 1.0
    assert cue.age(v.clock.now()) < 0.25


def test_radar_sees_intruders():
    sim = Simulator(Scenario.from_dict(SCEN), seed=1)
    sim.run_until(2.0)
    assert "phantom" in sim.radar_objects()


@pytest.mark.parametrize("edit, where", [
    (lambda i: i.update(sysid=1), "intruders[0].sysid"),
    (lambda i: i.update(figure_eight={}), "intruders[0]"),
    (lambda i: i.update(colour="red"), "intruders[0].colour"),
    (lambda i: i.pop("start_enu_m"), "intruders[0].start_enu_m"),
    (lambda i: i.update(circle={"radius_m": -3}), "intruders[0].circle.radius_m"),
    (lambda i: i.update(limits={"speed_h_mps": 0}), "intruders[0].limits.speed_h_mps"),
    (lambda i: i.update(circle={"clockwise": "yes"}), "intruders[0].circle.clockwise"),
    (lambda i: i.update(airframe="blimp"), "intruders[0].airframe"),
])
def test_bad_intruders_are_reported_with_their_key_path(edit, where):
    doc = {**SCEN, "intruders": [dict(SCEN["intruders"][0])]}
    edit(doc["intruders"][0])
    with pytest.raises(ScenarioError, match=rf"<x>: {where.replace('[', '.').replace(']', '.')}"):
        Scenario.from_dict(doc, source="<x>")


def test_intruder_names_and_sysids_are_unique():
    doc = {**SCEN, "intruders": [SCEN["intruders"][0], dict(SCEN["intruders"][0], sysid=3)]}
    with pytest.raises(ScenarioError, match="intruders.1..name"):
        Scenario.from_dict(doc, source="<x>")
    doc = {**SCEN, "intruders": [SCEN["intruders"][0], dict(SCEN["intruders"][0], name="b")]}
    with pytest.raises(ScenarioError, match="intruders.1..sysid"):
        Scenario.from_dict(doc, source="<x>")
    doc = {**SCEN, "targets": [{"name": "phantom", "circle": {"center_enu_m": [0, 0, 10]}}]}
    with pytest.raises(ScenarioError, match="intruders.0..name"):
        Scenario.from_dict(doc, source="<x>")


def test_the_shipped_follow_scenario_loads():
    from pathlib import Path

    from sitl.world.scenario import load_scenario
    sc = load_scenario(Path(__file__).resolve().parents[3] / "sitl" / "scenarios" / "follow_rectangle.yaml")
    assert sc.intruders[0].trajectory == "rectangle" and sc.intruders[0].params["pause_s"] == 8.0


def test_intruder_airframe_defaults_to_the_phantom_and_takes_the_s1000():
    assert Scenario.from_dict(SCEN, source="<x>").intruders[0].airframe == "phantom"
    doc = {**SCEN, "intruders": [dict(SCEN["intruders"][0], airframe="s1000")]}
    assert Scenario.from_dict(doc, source="<x>").intruders[0].airframe == "s1000"
