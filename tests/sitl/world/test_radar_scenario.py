"""The scenario's radar and targets sections, and the simulator streaming radar datagrams."""

from __future__ import annotations

import math
import time

import pytest
import yaml

from chaser_bt.radar.stream import (
    QueueDatagramSource,
    RadarStreamReader,
    UdpDatagramSource,
)
from sitl.simulator import Simulator
from sitl.world.scenario import Scenario, ScenarioError

DOC = """
name: radar-test
home: {lat_deg: 42.5445, lon_deg: -71.6105, alt_m: 80.0}
radar:
  lat_deg: 42.5440
  lon_deg: -71.6105
  alt_m: 81.0
  pitch_deg: 10
  rate_hz: 5
  sigma_az_deg: 0.5
  failures: {drop_per_s: 0.01, swap_prob: 0.5}
  clutter: {birds_per_s: 0.01}
  off_at_s: 3.0
targets:
  - name: intruder
    circle: {center_enu_m: [0, 150, 30], radius_m: 30, speed_mps: 5}
  - name: leg
    waypoints: {points_enu_m: [[0, 100, 20], [0, 200, 20]], speed_mps: 6, loop: true}
    start_s: 1.0
"""


def scenario(**changes) -> Scenario:
    d = yaml.safe_load(DOC)
    for path, value in changes.items():
        node = d
        *head, last = path.split(".")
        for k in head:
            node = node[int(k)] if isinstance(node, list) else node[k]
        node[last] = value
    return Scenario.from_dict(d, "radar.yaml")


def test_radar_and_targets_sections_parse_into_si_units():
    s = scenario()
    assert math.isclose(s.radar.pitch_rad, math.radians(10)) and math.isclose(s.radar.sigma_az_rad, math.radians(0.5))
    assert s.radar.failures.swap_prob == 0.5 and s.radar.clutter.birds_per_s == 0.01 and s.radar.off_at_s == 3.0
    assert [t.name for t in s.targets] == ["intruder", "leg"] and not s.targets[1].present(0.5)


@pytest.mark.parametrize("change, where", [
    ({"radar.pd": 1.5}, "radar.pd"),
    ({"radar.rate_hz": 0}, "radar.rate_hz"),
    ({"radar.udp_port": 70000}, "radar.udp_port"),
    ({"radar.failures.swap_prob": 2}, "radar.failures.swap_prob"),
    ({"radar.failures.drop_rate": 1}, "radar.failures.drop_rate"),
    ({"radar.fov": 1}, "radar.fov"),
    ({"targets.0.name": "ownship"}, "targets[0].name"),
    ({"targets.0.circle.center_enu_m": [1, 2]}, "targets[0].circle.center_enu_m"),
    ({"targets.1.waypoints.points_enu_m": [[0, 0, 0]]}, "targets[1].waypoints.points_enu_m"),
])
def test_radar_mistakes_name_file_and_key(change, where):
    with pytest.raises(ScenarioError, match=f"radar.yaml: {where.replace('[', '.').replace(']', '.')}"):
        scenario(**change)


def test_scenarios_without_radar_are_unchanged():
    s = Scenario.from_dict({"home": {"lat_deg": 1.0, "lon_deg": 2.0}})
    assert s.radar is None and s.targets == ()
    assert Simulator(s, 1).radar is None


def test_simulator_streams_scans_in_process_and_over_udp_until_switched_off():
    s = scenario()
    rx = UdpDatagramSource("127.0.0.1", 0)
    try:
        s = Scenario.from_dict({**yaml.safe_load(DOC), "radar": {**yaml.safe_load(DOC)["radar"], "udp_port": rx.port}})
        sim = Simulator(s, 3)
        q = QueueDatagramSource()
        sim.add_radar_consumer(q.push)
        sim.run_until(5.0)
        scans = RadarStreamReader().accept_all(q.receive())
        assert len(scans) == 15 and scans[-1].t == pytest.approx(2.8)  # 5 Hz from 0 s, off at 3 s
        assert {sim.radar_truth.labels[r.track_id] for r in scans[-1].tracks} >= {"intruder", "leg"}
        got = []
        deadline = time.monotonic() + 2.0
        while len(got) < 15 and time.monotonic() < deadline:
            got += rx.receive()
        assert len(RadarStreamReader().accept_all(got)) == 15
    finally:
        rx.close()
