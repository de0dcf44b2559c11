"""Scenario files: the shipped patrol field loads; every mistake names file, key path and expectation."""

from __future__ import annotations

from pathlib import Path

import pytest

from sitl.world.scenario import Fault, OnboardCamera, Scenario, ScenarioError, load_scenario

PATROL = Path(__file__).resolve().parents[3] / "sitl" / "scenarios" / "patrol.yaml"
HOME = {"lat_deg": 42.5, "lon_deg": -71.6, "alt_m": 80.0}


def test_the_patrol_scenario_loads_with_its_documented_values():
    sc = load_scenario(PATROL)
    assert sc.name == "patrol"
    assert 42.0 < sc.home.lat_deg < 43.0 and -72.0 < sc.home.lon_deg < -71.0
    assert sc.home.alt_m == 80.0
    assert sc.wind.speed_mps == 3.0 and sc.wind.gust_std_mps > 0.0
    assert (sc.boot.gps_fix_s, sc.boot.ekf_ready_s, sc.boot.prearm_ok_s) == (5.0, 25.0, 40.0)
    assert sc.faults == () and sc.time_limit_s == 600.0
    assert sc.start_unix_s == 1767225600.0
    assert sc.airframe.mass_kg == 8.0


def test_defaults_fill_everything_but_home():
    sc = Scenario.from_dict({"home": HOME})
    assert sc.wind.speed_mps == 0.0 and sc.params == {} and sc.faults == ()
    assert sc.home_heading_deg == 0.0


def test_overrides_reach_their_dataclasses():
    sc = Scenario.from_dict({
        "home": {**HOME, "heading_deg": 450},
        "airframe": {"mass_kg": 9.5, "battery_cells": 12},
        "params": {"RTL_ALT": 3000, "SYSID_MYGCS": 250},
        "faults": [{"at_s": 10, "kind": "gps_loss", "duration_s": 5}, {"at_s": 20, "kind": "link_loss"}],
    })
    assert sc.home_heading_deg == 90.0
    assert sc.airframe.mass_kg == 9.5 and sc.airframe.battery_cells == 12
    assert sc.params == {"RTL_ALT": 3000.0, "SYSID_MYGCS": 250.0}
    assert sc.faults == (Fault(10.0, "gps_loss", 5.0), Fault(20.0, "link_loss", None))
    assert sc.fault_active("gps_loss", 12.0) and not sc.fault_active("gps_loss", 15.0)
    assert sc.fault_active("link_loss", 1e6) and not sc.fault_active("battery_drop", 30.0)


@pytest.mark.parametrize("doc, path, expected", [
    ({}, "home", "required"),
    ({"home": {"lat_deg": 42.5}}, "home.lon_deg", "required"),
    ({"home": {**HOME, "lat_deg": 95}}, "home.lat_deg", "latitude"),
    ({"home": HOME, "wind": {"speed_mps": "fast"}}, "wind.speed_mps", "finite number"),
    ({"home": HOME, "wind": {"speed": 3}}, "wind.speed", "unknown key"),
    ({"home": HOME, "airframe": {"mass_kg": -1}}, "airframe", "mass_kg must be > 0"),
    ({"home": HOME, "airframe": {"battery_cells": 6.5}}, "airframe.battery_cells", "integer"),
    ({"home": HOME, "params": {"RTL_ALTITUDE": 10}}, "params.RTL_ALTITUDE", "ArduCopter parameter"),
    ({"home": HOME, "boot": {"gps_fix_s": 30}}, "boot.ekf_ready_s", ">= boot.gps_fix_s"),
    ({"home": HOME, "faults": [{"at_s": 1, "kind": "engine_fire"}]}, "faults[0].kind", "one of link_loss"),
    ({"home": HOME, "faults": [{"kind": "gps_loss"}]}, "faults[0].at_s", "required"),
    ({"home": HOME, "faults": {"at_s": 1}}, "faults", "a list"),
    ({"home": HOME, "time_limit_s": -5}, "time_limit_s", ">= 0"),
    ({"home": HOME, "traffic": []}, "traffic", "unknown key"),
    ({"home": HOME, "camera": {"mount": "gimbal"}}, "camera.mount", "one of fixed, stabilised"),
    ({"home": HOME, "camera": {"tilt_deg": 95}}, "camera.tilt_deg", "in (-90, 90)"),
    ({"home": HOME, "camera": {"tilt": 10}}, "camera.tilt", "did you mean tilt_deg"),
])
def test_errors_name_the_source_and_key_path(doc, path, expected):
    with pytest.raises(ScenarioError) as e:
        Scenario.from_dict(doc, source="field.yaml")
    msg = str(e.value)
    assert msg.startswith(f"field.yaml: {path}")
    assert expected in msg


def test_a_broken_file_names_the_file(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("home: {lat_deg: 42.5, lon_deg: -71.6}\nwind: [1, 2\n")
    with pytest.raises(ScenarioError, match="bad.yaml: not valid YAML"):
        load_scenario(bad)
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.yaml")
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    with pytest.raises(ScenarioError, match="empty.yaml"):
        load_scenario(empty)


def test_a_misspelt_key_gets_the_closest_one_suggested():
    with pytest.raises(ScenarioError, match=r"wind\.sped_mps: .*did you mean speed_mps\?"):
        Scenario.from_dict({"home": HOME, "wind": {"sped_mps": 3}}, source="field.yaml")


def test_every_section_s_error_is_listed_at_once():
    doc = {"home": HOME, "wind": {"speed_mps": -1}, "time_limit_s": -5, "traffic": [], "faults": {"at_s": 1}}
    with pytest.raises(ScenarioError) as e:
        Scenario.from_dict(doc, source="field.yaml")
    lines = str(e.value).splitlines()
    assert len(lines) == 4 and all(line.startswith("field.yaml: ") for line in lines)
    assert [line.split(":")[1].strip() for line in lines] == ["traffic", "wind.speed_mps", "faults", "time_limit_s"]


def test_the_camera_key_says_how_the_chaser_carries_its_camera():
    assert Scenario.from_dict({"home": HOME}).camera == OnboardCamera("fixed", 10.0)
    held = Scenario.from_dict({"home": HOME, "camera": {"mount": "stabilised", "tilt_deg": 15}})
    assert held.camera == OnboardCamera("stabilised", 15.0)
    # The chase scenarios carry the paper's gimbal; search and rescue and the patrol keep the fixed camera.
    shipped = Path(__file__).resolve().parents[3] / "sitl" / "scenarios"
    for path in [shipped / "chase.yaml", shipped / "chase_radar_off.yaml", *sorted((shipped / "hard").glob("*.yaml"))]:
        assert load_scenario(path).camera.mount == "stabilised", path.name
    for name in ("sar.yaml", "sar_lying.yaml", "patrol.yaml"):
        assert load_scenario(shipped / name).camera.mount == "fixed", name
