"""The simulated ArduCopter's parameter store: names, order, types, aliases, rejection of unknowns."""

from __future__ import annotations

import math

import pytest

from sitl.vehicle.params import (
    MAV_PARAM_TYPE_INT8,
    MAV_PARAM_TYPE_REAL32,
    PARAM_SPECS,
    ParamStore,
)

REQUIRED = (
    "SYSID_THISMAV MAV_GCS_SYSID RTL_ALT RTL_ALT_FINAL RTL_SPEED RTL_LOIT_TIME LAND_SPEED "
    "LAND_SPEED_HIGH WPNAV_SPEED WPNAV_SPEED_UP WPNAV_SPEED_DN WPNAV_ACCEL ANGLE_MAX PILOT_SPEED_UP "
    "PILOT_SPEED_DN PILOT_Y_RATE DISARM_DELAY FS_GCS_ENABLE FS_GCS_TIMEOUT RC_OVERRIDE_TIME "
    "GUID_OPTIONS GUID_TIMEOUT BATT_CAPACITY BATT_LOW_VOLT BATT_FS_LOW_ACT ARMING_CHECK"
).split()


def test_the_parameters_the_mission_touches_exist_with_arducopter_defaults():
    ps = ParamStore()
    for name in REQUIRED:
        assert name in ps
    assert ps.get("RTL_ALT") == 1500.0  # cm
    assert ps.get("WPNAV_SPEED") == 1000.0  # cm/s
    assert ps.get("ANGLE_MAX") == 3000.0  # cdeg
    assert ps.get("MAV_GCS_SYSID") == 255.0
    assert ps.get("FS_GCS_ENABLE") == 1.0
    assert ps.get("RTL_LOIT_TIME") == 5000.0  # ms


def test_order_and_index_match_the_declaration():
    ps = ParamStore()
    names = ps.names()
    assert names == [s.name for s in PARAM_SPECS]
    assert len(set(names)) == len(names) == ps.count()
    assert all(ps.index(n) == i for i, n in enumerate(names))
    assert all(len(n) <= 16 for n in names)  # PARAM_VALUE.param_id is 16 chars


def test_unknown_names_are_rejected():
    ps = ParamStore()
    assert not ps.set("NOT_A_PARAM", 1.0)
    assert "NOT_A_PARAM" not in ps
    with pytest.raises(KeyError):
        ps.get("NOT_A_PARAM")
    with pytest.raises(KeyError):
        ParamStore({"NOT_A_PARAM": 1.0})


def test_sysid_mygcs_is_the_old_name_of_mav_gcs_sysid():
    ps = ParamStore()
    assert ps.set("SYSID_MYGCS", 250)
    assert ps.get("MAV_GCS_SYSID") == 250.0
    assert ps.index("SYSID_MYGCS") == ps.index("MAV_GCS_SYSID")
    assert "SYSID_MYGCS" not in ps.names()


def test_integer_parameters_round_and_clip_and_floats_keep_their_value():
    ps = ParamStore()
    assert ps.mav_type("DISARM_DELAY") == MAV_PARAM_TYPE_INT8
    assert ps.set("DISARM_DELAY", 7.6) and ps.get("DISARM_DELAY") == 8.0
    assert ps.set("DISARM_DELAY", 1000) and ps.get("DISARM_DELAY") == 127.0
    assert ps.mav_type("FS_GCS_TIMEOUT") == MAV_PARAM_TYPE_REAL32
    assert ps.set("FS_GCS_TIMEOUT", 2.5) and ps.get("FS_GCS_TIMEOUT") == 2.5


def test_non_finite_values_are_rejected():
    ps = ParamStore()
    assert not ps.set("RTL_ALT", math.nan)
    assert not ps.set("RTL_ALT", math.inf)
    assert not ps.set("RTL_ALT", "high")
    assert ps.get("RTL_ALT") == 1500.0


def test_a_changed_parameter_changes_the_behaviour(airborne, run_for):
    ap = airborne(alt=10.0)
    assert ap.params.set("RTL_ALT", 2500)
    assert ap.params.set("RTL_CONE_SLOPE", 0)  # over home the cone would hold it at 10 m (as ArduCopter)
    ap.request_mode(6)
    run_for(ap, 12.0)
    assert ap.truth.pos_enu[2] == pytest.approx(25.0, abs=0.3)
