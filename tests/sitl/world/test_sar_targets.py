"""Scripted targets for search and rescue: `kind`, the `static` shape, seeded placement, and a radar blind to people."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl.simulator import Simulator
from sitl.world.scenario import Scenario, ScenarioError
from sitl.world.targets import StaticPoint

HOME = {"lat_deg": 42.5445, "lon_deg": -71.6105, "alt_m": 80.0}
RADAR = {"lat_deg": 42.5445, "lon_deg": -71.6105, "alt_m": 80.0, "yaw_deg": 0.0, "pd": 1.0}


def scenario(*targets, radar=None) -> Scenario:
    doc = {"home": HOME, "targets": list(targets)}
    if radar is not None:
        doc["radar"] = radar
    return Scenario.from_dict(doc, "sar-test.yaml")


def test_a_static_person_is_parsed_with_its_kind():
    s = scenario({"name": "hiker", "kind": "person",
                  "static": {"position_enu_m": [100, 200, 0], "scatter_m": 60, "heading_deg": 90, "lying": True}})
    (t,) = s.targets
    assert t.kind == "person" and not t.radar_visible
    assert t.path == StaticPoint((100.0, 200.0, 0.0), 60.0, math.pi / 2, True)
    np.testing.assert_allclose(t.path.position_enu(12.0), [100, 200, 0.16])  # lying: the torso's half-depth up
    np.testing.assert_array_equal(t.path.velocity_enu(12.0), [0, 0, 0])
    # Lying: the body's up axis (head) is horizontal; standing it is up.
    assert abs(t.path.attitude(0.0).apply([0, 0, 1])[2]) < 1e-9
    assert StaticPoint((0, 0, 0)).attitude(0.0).apply([0, 0, 1])[2] == pytest.approx(1.0)


def test_targets_default_to_the_papers_drone_which_the_radar_sees():
    (t,) = scenario({"name": "drone", "circle": {"center_enu_m": [0, 100, 30]}}).targets
    assert t.kind == "s1000" and t.radar_visible


@pytest.mark.parametrize("target, path", [
    ({"name": "p", "kind": "horse", "static": {"position_enu_m": [0, 0, 0]}}, "targets[0].kind"),
    ({"name": "p", "static": {"scatter_m": 5}}, "targets[0].static.position_enu_m"),
    ({"name": "p", "static": {"position_enu_m": [0, 0, 0], "scatter_m": -1}}, "targets[0].static.scatter_m"),
    ({"name": "p", "static": {"position_enu_m": [0, 0, 0], "lying": "yes"}}, "targets[0].static.lying"),
    ({"name": "p", "static": {"position_enu_m": [0, 0, 0], "radius_m": 3}}, "targets[0].static.radius_m"),
    ({"name": "p", "static": {"position_enu_m": [0, 0, 0]}, "waypoints": {"points_enu_m": [[0, 0, 0], [1, 0, 0]]}},
     "targets[0]"),
])
def test_bad_static_targets_are_refused_naming_the_key(target, path):
    with pytest.raises(ScenarioError, match=rf"sar-test.yaml: {path.replace('[', '.').replace(']', '.')}"):
        scenario(target)


def test_placement_is_seeded_inside_the_scatter_disc_and_spread_over_it():
    s = scenario({"name": "hiker", "kind": "person", "static": {"position_enu_m": [100, 200, 0], "scatter_m": 50}},
                 {"name": "drone", "circle": {"center_enu_m": [0, 100, 30]}})
    points = np.array([s.placed(seed).targets[0].path.position for seed in range(400)])
    offsets = points[:, :2] - [100, 200]
    radii = np.hypot(*offsets.T)
    assert radii.max() <= 50.0 and np.all(points[:, 2] == 0.0)
    # Uniform over the disc's area: P(r <= R/2) = 1/4; each quadrant a quarter.
    assert np.mean(radii <= 25.0) == pytest.approx(0.25, abs=0.07)
    assert np.mean((offsets[:, 0] > 0) & (offsets[:, 1] > 0)) == pytest.approx(0.25, abs=0.07)
    # Same seed, same place; different seeds, different places; other targets untouched.
    assert s.placed(3) == s.placed(3)
    assert s.placed(3).targets[0] != s.placed(4).targets[0]
    assert s.placed(3).targets[1] is s.targets[1]
    assert s.placed(3).targets[0].path.scatter_m == 0.0
    # No scatter: the scenario itself.
    fixed = scenario({"name": "hiker", "kind": "person", "static": {"position_enu_m": [1, 2, 0]}})
    assert fixed.placed(9) is fixed


def test_the_simulator_places_the_person_and_its_radar_does_not_see_people():
    s = scenario({"name": "hiker", "kind": "person", "static": {"position_enu_m": [0, 150, 0], "scatter_m": 30}},
                 {"name": "drone", "circle": {"center_enu_m": [0, 150, 30], "radius_m": 20}}, radar=RADAR)
    sim = Simulator(s, seed=5)
    assert sim.scenario.targets[0] == s.placed(5).targets[0]
    assert set(sim.radar_objects()) == {"drone"}  # not the person; not the ownship, which is on the ground
