"""Scripted intruder manoeuvres: each kind flies what it says within the limits, then the pilot resumes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chaser_bt.geo import GeoPoint, LocalFrame
from sitl.world.intruders import Intruder, IntruderSpec, Manoeuvre, ManoeuvrePilot
from sitl.world.scenario import Scenario, ScenarioError

FRAME = LocalFrame(GeoPoint(42.5445, -71.6105, 80.0))
DT = 0.02
CIRCLE = dict(center=(0.0, 0.0, 30.0), radius_m=40.0, speed_mps=8.0)


def fly(spec: IntruderSpec, seconds: float):
    it = Intruder(spec, np.random.default_rng(0), FRAME)
    ts, ps, vs = [], [], []
    for k in range(1, int(round(seconds / DT)) + 1):
        it.step(k * DT, DT)
        ts.append(k * DT)
        ps.append(it.pos.copy())
        vs.append(it.vel.copy())
    return it, np.array(ts), np.array(ps), np.array(vs)


def circle(*manoeuvres: Manoeuvre) -> IntruderSpec:
    return IntruderSpec("c", 2, (40.0, 0.0, 30.0), "circle", dict(CIRCLE), manoeuvres=manoeuvres)


def northbound(*manoeuvres: Manoeuvre) -> IntruderSpec:
    """Flies north at 8 m/s towards a corner 2 km away (a straight leg for a long while)."""
    corners = ((0.0, 2000.0, 30.0), (0.0, 0.0, 30.0))
    return IntruderSpec("n", 2, (0.0, 0.0, 30.0), "rectangle", dict(corners=corners, speed_mps=8.0, pause_s=1.0),
                        manoeuvres=manoeuvres)


def test_dash_reaches_its_speed_and_heading_within_the_acceleration_limit():
    t0 = 20.0
    it, t, p, v = fly(circle(Manoeuvre(t0, "dash", 5.0, heading_deg=90.0, speed_mps=18.0)), 40.0)
    assert isinstance(it.pilot, ManoeuvrePilot)
    k0 = int(np.searchsorted(t, t0 - 1e-9))
    v0 = v[k0 - 1]  # the velocity the dash starts from
    want = np.array([18.0, 0.0, 0.0])  # compass 90: east
    # velocity moves straight toward the command at the horizontal limit, 8 m/s^2
    reach = float(np.linalg.norm(want - v0)) / 8.0
    close = np.flatnonzero(np.linalg.norm(v - want, axis=1) < 1e-6)
    first = t[close[0]]
    assert first == pytest.approx(t0 + reach, abs=DT + 1e-9)
    during = (t >= first) & (t < t0 + 5.0 - 1e-9)
    assert np.allclose(v[during], want, atol=1e-6)
    a = np.diff(v, axis=0) / DT
    assert np.hypot(a[:, 0], a[:, 1]).max() <= 8.0 + 1e-6 and np.abs(a[:, 2]).max() <= 4.0 + 1e-6
    # the dash ends at t0 + 5 s: the circle's pilot pulls the intruder back onto its circle
    assert it.pilot.active is None
    after = t > t0 + 5.0 + 1e-9
    assert np.linalg.norm(v[after][0] - want) > 0.1
    late = t > 38.0
    assert np.abs(np.hypot(p[late, 0], p[late, 1]) - 40.0).max() < 1.5


def test_turn_swings_the_heading_at_a_constant_rate_and_then_the_pilot_resumes():
    t0, dur = 20.0, 4.0
    m = Manoeuvre(t0, "turn", dur, heading_deg=90.0)  # from north to east at the speed it has
    it, t, p, v = fly(northbound(m), t0)
    assert np.allclose(v[-2], [0.0, 8.0, 0.0], atol=1e-6)  # northbound at 8 m/s when the turn begins
    it, t, p, v = fly(northbound(m), t0 + dur / 2)
    assert it.pilot.active is m
    # halfway: the command is half way round, compass 45, at the speed of the turn's start (8 m/s)
    cmd = it.pilot.desired_velocity(t0 + dur / 2, it.pos, it.vel, it.spec.limits)
    assert cmd == pytest.approx([8.0 * math.sin(math.radians(45)), 8.0 * math.cos(math.radians(45)), 0.0], abs=1e-9)
    it, t, p, v = fly(northbound(m), t0 + dur)
    heading = math.degrees(math.atan2(v[-1][0], v[-1][1]))  # compass
    assert heading == pytest.approx(90.0, abs=6.0)  # a quarter turn of 0.39 rad/s: 3.1 m/s^2, tracked with a small lag
    assert np.abs(p[:, 2] - 30.0).max() < 1e-9  # altitude held
    # after the turn the rectangle's pilot resumes: heading back to its corner, north
    it, t, p, v = fly(northbound(m), t0 + dur + 10.0)
    assert it.pilot.active is None
    to_corner = math.degrees(math.atan2(-p[-1][0], 2000.0 - p[-1][1]))
    assert math.degrees(math.atan2(v[-1][0], v[-1][1])) == pytest.approx(to_corner, abs=1.0)


def test_dive_with_a_duration_ends_by_the_clock_where_the_limits_take_it():
    t0 = 10.0
    it, t, p, v = fly(circle(Manoeuvre(t0, "dive", 3.0, to_alt_m=5.0)), t0 + 3.0 - DT)
    # from level flight: 1.25 s at 4 m/s^2 to 5 m/s (3.125 m), then 1.75 s at 5 m/s (8.75 m), still
    # 13 m above 5 m, too far to slow down yet (sqrt(2 * 0.5 * 4 * 13) > 5)
    assert p[-1][2] == pytest.approx(30.0 - 3.125 - 8.75, abs=0.05)
    assert v[:, 2].min() == pytest.approx(-5.0, abs=1e-9) and it.pilot.active is not None
    it.step(t0 + 3.0, DT)
    assert it.pilot.active is None  # over by the clock, though 5 m was not reached


def test_climb_without_a_duration_ends_at_its_altitude():
    t0 = 10.0
    it, t, p, v = fly(circle(Manoeuvre(t0, "climb", to_alt_m=60.0)), 30.0)
    top = int(np.argmax(p[:, 2]))
    assert 59.5 <= p[top, 2] <= 60.5 and v[:, 2].max() == pytest.approx(6.0, abs=1e-9)
    assert it.pilot.active is None and p[-1, 2] < 59.0  # done: the circle's pilot brings it back to 30 m
    # the horizontal velocity of t0 is kept while climbing
    k0 = int(np.searchsorted(t, t0 - 1e-9))
    climbing = (t > t0 + 2.0) & (t < t[top] - 2.0)
    assert np.allclose(v[climbing, :2], v[k0 - 1, :2], atol=1e-6)


def test_a_dive_already_below_its_altitude_is_skipped():
    it, *_ = fly(circle(Manoeuvre(5.0, "dive", to_alt_m=50.0)), 6.0)
    assert it.pilot.active is None


SCEN = {
    "name": "m", "home": {"lat_deg": 42.5445, "lon_deg": -71.6105, "alt_m": 80.0},
    "intruders": [{"name": "runner", "sysid": 2, "start_enu_m": [40, 0, 30], "start_s": 10,
                   "circle": {"center_enu_m": [0, 0, 30], "radius_m": 40},
                   "manoeuvres": [{"at_s": 40, "kind": "turn", "heading_deg": 180, "speed_mps": 12, "duration_s": 4},
                                  {"at_s": 60, "kind": "dive", "to_alt_m": 15, "duration_s": 3},
                                  {"at_s": 80, "kind": "climb", "to_alt_m": 60},
                                  {"at_s": 100, "kind": "dash", "heading_deg": 90, "speed_mps": 18, "duration_s": 5}]}],
}


def test_the_documented_example_parses():
    spec = Scenario.from_dict(SCEN, "<x>").intruders[0]
    assert spec.manoeuvres == (Manoeuvre(40.0, "turn", 4.0, 180.0, 12.0), Manoeuvre(60.0, "dive", 3.0, to_alt_m=15.0),
                               Manoeuvre(80.0, "climb", to_alt_m=60.0), Manoeuvre(100.0, "dash", 5.0, 90.0, 18.0))
    assert isinstance(spec.make_pilot(np.random.default_rng(0)), ManoeuvrePilot)
    plain = dict(SCEN["intruders"][0])
    del plain["manoeuvres"]
    assert Scenario.from_dict({**SCEN, "intruders": [plain]}).intruders[0].manoeuvres == ()


@pytest.mark.parametrize("k, edit, where, expected", [
    (0, {"kind": "loop"}, "manoeuvres[0].kind", "one of turn, dash, climb, dive"),
    (0, {"heading_deg": None}, "manoeuvres[0].heading_deg", "required for a turn"),
    (3, {"duration_s": None}, "manoeuvres[3].duration_s", "required for a dash"),
    (1, {"to_alt_m": None}, "manoeuvres[1].to_alt_m", "required for a dive"),
    (2, {"heading_deg": 90}, "manoeuvres[2].heading_deg", "unknown key"),
    (0, {"at_s": 5}, "manoeuvres[0].at_s", "start_s (10.0)"),
    (1, {"at_s": 42}, "manoeuvres[1].at_s", "end of the previous manoeuvre (44.0)"),
    (3, {"at_s": 80}, "manoeuvres[3].at_s", "after the previous manoeuvre's at_s (80.0)"),
    (3, {"speed_mps": 25}, "manoeuvres[3].speed_mps", "limit (20.0 m/s)"),
    (2, {"speed_mps": 7}, "manoeuvres[2].speed_mps", "limit (6.0 m/s)"),
    (0, {"duration_s": 0}, "manoeuvres[0].duration_s", "> 0"),
    (1, {"to_alt_m": -3}, "manoeuvres[1].to_alt_m", ">= 0"),
])
def test_bad_manoeuvres_name_their_key_path(k, edit, where, expected):
    ms = [dict(m) for m in SCEN["intruders"][0]["manoeuvres"]]
    for key, value in edit.items():
        if value is None:
            ms[k].pop(key)
        else:
            ms[k][key] = value
    doc = {**SCEN, "intruders": [{**SCEN["intruders"][0], "manoeuvres": ms}]}
    with pytest.raises(ScenarioError) as e:
        Scenario.from_dict(doc, source="<x>")
    assert str(e.value).startswith(f"<x>: intruders[0].{where}") and expected in str(e.value)


def test_manoeuvres_must_be_a_list_of_mappings():
    for bad, where in (({"at_s": 1}, "intruders[0].manoeuvres"), ([3], "intruders[0].manoeuvres[0]")):
        doc = {**SCEN, "intruders": [{**SCEN["intruders"][0], "manoeuvres": bad}]}
        with pytest.raises(ScenarioError, match=rf"^<x>: {where.replace('[', '.').replace(']', '.')}: expected"):
            Scenario.from_dict(doc, source="<x>")
