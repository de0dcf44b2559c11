"""Search-and-rescue scoring on truth: found within 10 m of the person, the find's error, time to find."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import py_trees

from chaser_bt.find import Find
from sitl.bench.sar_scoring import FIND_KEY, SarObserver, people_enu, score_find
from sitl.world.scenario import Scenario

HOME = {"lat_deg": 42.5445, "lon_deg": -71.6105, "alt_m": 80.0}


def sar_scenario(*people) -> Scenario:
    targets = [{"name": f"p{k}", "kind": "person", "static": {"position_enu_m": list(p)}} for k, p in enumerate(people)]
    targets.append({"name": "drone", "circle": {"center_enu_m": [0, 0, 30]}})
    return Scenario.from_dict({"home": HOME, "targets": targets})


def find_at(e: float, n: float) -> Find:
    return Find(t=0.0, position_enu=np.array([e, n, 0.5]), geodetic=None, std_m=1.0, confidence=0.9, fixes=5)


def test_found_within_ten_metres_of_the_nearest_person_horizontally():
    people = [np.array([100.0, 200.0, 0.0]), np.array([-50.0, 0.0, 0.0])]
    # 6-8-10: exactly 10 m from the first person counts; the height of the find does not matter.
    assert score_find(np.array([106.0, 208.0, 40.0]), people) == {"sar_found": True, "sar_find_error_m": 10.0}
    assert score_find(np.array([106.0, 209.0, 0.0]), people) == {"sar_found": False, "sar_find_error_m": 10.82}
    assert score_find(np.array([-47.0, 4.0, 0.0]), people) == {"sar_found": True, "sar_find_error_m": 5.0}
    assert score_find(None, people) == {"sar_found": False, "sar_find_error_m": None}
    assert score_find(np.zeros(3), []) == {"sar_found": None, "sar_find_error_m": None}


def test_people_are_the_person_targets_only():
    s = sar_scenario((1, 2, 0), (3, 4, 0))
    np.testing.assert_array_equal(people_enu(s), [[1, 2, 0], [3, 4, 0]])


class FakeSim:
    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.time_s = 0.0
        self.truth = SimpleNamespace(on_ground=True)


def test_observer_scores_the_last_find_and_times_the_first_from_launch():
    sim = FakeSim(sar_scenario((100, 200, 0)))
    obs = SarObserver(sim)
    bb = py_trees.blackboard.Blackboard
    for t, airborne, find in [(1.0, False, None), (5.0, True, None), (40.0, True, find_at(150, 150)),
                              (60.0, True, find_at(103, 196)), (90.0, False, None)]:
        sim.time_s, sim.truth.on_ground = t, not airborne
        if find is not None:
            bb.set(FIND_KEY, find)
        obs.after_tick()
    # Launched at 5 s, first find at 40 s; the last find (3, -4) from the person is the one scored.
    assert obs.report_keys() == {"sar_found": True, "sar_find_error_m": 5.0, "sar_t_find_s": 35.0}


def test_no_find_and_no_person():
    obs = SarObserver(FakeSim(sar_scenario((100, 200, 0))))
    obs.after_tick()
    assert obs.report_keys() == {"sar_found": False, "sar_find_error_m": None, "sar_t_find_s": None}
    obs = SarObserver(FakeSim(Scenario.from_dict({"home": HOME})))
    py_trees.blackboard.Blackboard.set(FIND_KEY, find_at(0, 0))
    obs.after_tick()
    assert obs.report_keys() == {"sar_found": None, "sar_find_error_m": None, "sar_t_find_s": None}


def test_a_wrong_kind_on_the_key_is_not_a_find():
    obs = SarObserver(FakeSim(sar_scenario((0, 0, 0))))
    py_trees.blackboard.Blackboard.set(FIND_KEY, "not a find")
    obs.after_tick()
    assert obs.report_keys()["sar_found"] is False
    assert obs.first_find_s is None
