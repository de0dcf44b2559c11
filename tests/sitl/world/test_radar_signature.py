"""Each object's radar signature: the radar equation for its cross-section, its own pd and drop rate."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import yaml

from chaser_bt.geo import GeoPoint, LocalFrame
from sitl.simulator import Simulator
from sitl.world.radar.config import RadarConfig, RadarFailureRates, RadarSignature
from sitl.world.radar.model import GroundRadar, detection_probability
from sitl.world.scenario import Scenario, ScenarioError

ORIGIN = GeoPoint(42.5445, -71.6105, 80.0)
BASE = RadarConfig(ORIGIN)  # pd 0.95, max range 1000 m, reference 0.01 m^2, pfa 1e-6


def test_the_default_and_phantom_class_cross_sections_keep_the_radar_pd_anywhere_in_coverage():
    for r in (10.0, 300.0, 999.0, 1000.0):
        assert detection_probability(BASE, None, r) == BASE.pd
        assert detection_probability(BASE, RadarSignature(), r) == BASE.pd
        for rcs in (0.01, 0.02, 0.03):
            assert detection_probability(BASE, RadarSignature(rcs_m2=rcs), r) == BASE.pd
    assert detection_probability(BASE, RadarSignature(pd=0.4), 900.0) == 0.4


def test_a_small_cross_section_far_out_follows_the_radar_equation():
    # Worked by hand: ratio = (0.001 / 0.01) * (1000 / 900)^4 = 0.152416; 1 + SNR0 = ln(1e-6) / ln(0.95)
    # = 13.815511 / 0.051293 = 269.343; Pd = exp(-13.815511 / (1 + 268.343 * 0.152416)) = exp(-0.329727)
    assert detection_probability(BASE, RadarSignature(rcs_m2=0.001), 900.0) == pytest.approx(0.71911, abs=2e-4)
    # the reference's strength is reached at 1000 m * 0.1^(1/4) = 562.3 m: pd from there in
    assert detection_probability(BASE, RadarSignature(rcs_m2=0.001), 562.0) == BASE.pd
    assert detection_probability(BASE, RadarSignature(rcs_m2=0.001), 563.0) < BASE.pd
    # monotone in range, down to the false-alarm floor
    pds = [detection_probability(BASE, RadarSignature(rcs_m2=0.001), r) for r in (600, 700, 800, 900, 1000)]
    assert pds == sorted(pds, reverse=True)
    assert detection_probability(BASE, RadarSignature(rcs_m2=1e-12), 1000.0) == pytest.approx(1e-6, rel=1e-3)


def test_the_measured_detection_rate_over_many_scans_is_the_predicted_one():
    r = GroundRadar(BASE, LocalFrame(ORIGIN), np.random.default_rng(5),
                    {"small": RadarSignature(rcs_m2=0.001), "phantom": RadarSignature(rcs_m2=0.02)})
    objs = {name: (np.array([e, 900.0, 0.0]), np.zeros(3)) for name, e in (("small", -300.0), ("phantom", 0.0), ("plain", 300.0))}
    ranges = {name: float(np.linalg.norm(r.pose.from_enu(p))) for name, (p, _) in objs.items()}
    n = 4000
    seen = {name: 0 for name in objs}
    for k in range(n):
        scan, truth = r.scan(k * 0.2, objs)
        for tr in scan.tracks:
            seen[truth.labels[tr.track_id]] += 1
    want_small = detection_probability(BASE, RadarSignature(rcs_m2=0.001), ranges["small"])
    assert 0.66 < want_small < 0.70  # 948.7 m away
    tol = 4.0 * math.sqrt(0.25 / n)  # 4 sigma at worst
    assert seen["small"] / n == pytest.approx(want_small, abs=tol)
    assert seen["phantom"] / n == pytest.approx(0.95, abs=tol)
    assert seen["plain"] / n == pytest.approx(0.95, abs=tol)


def test_an_object_s_own_drop_rate_replaces_the_radar_s():
    cfg = replace(BASE, pd=1.0, failures=RadarFailureRates(drop_per_s=0.0, drop_gap_s=0.4))
    r = GroundRadar(cfg, LocalFrame(ORIGIN), np.random.default_rng(0), {"flaky": RadarSignature(drop_per_s=1.0)})
    objs = {"flaky": (np.array([0.0, 100.0, 10.0]), np.zeros(3)), "steady": (np.array([20.0, 100.0, 10.0]), np.zeros(3))}
    ids: dict[str, set[int]] = {"flaky": set(), "steady": set()}
    for k in range(100):
        scan, truth = r.scan(k * 0.2, objs)
        for tr in scan.tracks:
            ids[truth.labels[tr.track_id]].add(tr.track_id)
    assert len(ids["steady"]) == 1 and len(ids["flaky"]) > 5


DOC = """
name: sig
home: {lat_deg: 42.5445, lon_deg: -71.6105, alt_m: 80.0}
radar: {lat_deg: 42.5440, lon_deg: -71.6105, alt_m: 81.0, pitch_deg: 10, failures: {drop_per_s: 0.05, swap_prob: 0.5}}
targets:
  - {name: a, circle: {center_enu_m: [0, 150, 30], radius_m: 30, speed_mps: 5}}
  - {name: hiker, kind: person, static: {position_enu_m: [20, 100, 0]}}
intruders:
  - {name: p, sysid: 2, start_enu_m: [10, 200, 25], circle: {radius_m: 20}}
"""


def _stream(doc: dict, seconds: float = 20.0) -> list:
    sim = Simulator(Scenario.from_dict(doc, "<sig>"), 4)
    out = []
    sim.add_radar_consumer(out.append)
    sim.run_until(seconds)
    return out


def test_phantom_class_signatures_leave_the_radar_stream_unchanged():
    doc = yaml.safe_load(DOC)
    before = _stream(doc)
    doc["targets"][0]["radar"] = {"rcs_m2": 0.03}
    doc["intruders"][0]["radar"] = {"rcs_m2": 0.01}
    assert _stream(doc) == before  # byte for byte: same draws, same detections
    doc["intruders"][0]["radar"] = {"rcs_m2": 0.01, "drop_per_s": 0.5}
    assert _stream(doc) != before


def test_signatures_parse_and_reach_the_radar():
    doc = yaml.safe_load(DOC)
    doc["targets"][0]["radar"] = {"rcs_m2": 0.1, "pd": 0.8}
    doc["intruders"][0]["radar"] = {"drop_per_s": 0.2}
    s = Scenario.from_dict(doc, "<sig>")
    assert s.targets[0].radar == RadarSignature(0.1, 0.8, None) and s.targets[1].radar is None
    assert s.intruders[0].radar == RadarSignature(None, None, 0.2)
    assert Simulator(s, 1).radar.signatures == {"a": RadarSignature(0.1, 0.8, None), "p": RadarSignature(None, None, 0.2)}
    doc["radar"].update(reference_rcs_m2=0.02, pfa=1e-4)
    cfg = Scenario.from_dict(doc, "<sig>").radar
    assert (cfg.reference_rcs_m2, cfg.pfa) == (0.02, 1e-4)


@pytest.mark.parametrize("where, value, path, expected", [
    ("targets.0", {"rcs_m2": 0}, "targets[0].radar.rcs_m2", "> 0"),
    ("targets.0", {"pd": 1.2}, "targets[0].radar.pd", "probability in [0, 1]"),
    ("targets.0", {"rcs": 0.1}, "targets[0].radar.rcs", "unknown key"),
    ("targets.0", 0.02, "targets[0].radar", "a mapping"),
    ("targets.1", {"rcs_m2": 0.5}, "targets[1].radar", "does not see a person"),
    ("intruders.0", {"drop_per_s": -1}, "intruders[0].radar.drop_per_s", ">= 0.0"),
    ("radar", None, "radar.pfa", "false-alarm probability"),
    ("radar", None, "radar.reference_rcs_m2", "> 0"),
])
def test_bad_signatures_name_their_key_path(where, value, path, expected):
    doc = yaml.safe_load(DOC)
    if where == "radar":
        doc["radar"][path.split(".")[1]] = 0 if "rcs" in path else 1.0
    else:
        section, k = where.split(".")
        doc[section][int(k)]["radar"] = value
    with pytest.raises(ScenarioError) as e:
        Scenario.from_dict(doc, "<sig>")
    assert str(e.value).startswith(f"<sig>: {path}") and expected in str(e.value)
