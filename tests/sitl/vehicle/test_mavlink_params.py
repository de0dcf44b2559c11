"""The parameter protocol as ArduPilot speaks it (GCS_Param.cpp): list, read, set, unknown names."""

from __future__ import annotations

import pytest
from mavlink_gcs import mav, ready_gcs

from sitl.vehicle.params import PARAM_SPECS


def _param_values(gcs, since_s: float = -1.0) -> list:
    return gcs.of_type("PARAM_VALUE", since_s)


def test_request_list_streams_every_parameter_once_with_index_and_count():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_param_request_list_message(1, 1))
    gcs.run(1.0)
    values = _param_values(gcs)
    assert sorted(v.param_index for v in values) == list(range(len(PARAM_SPECS)))
    assert {v.param_count for v in values} == {len(PARAM_SPECS)}
    by_name = {v.param_id: v for v in values}
    assert set(by_name) == {s.name for s in PARAM_SPECS}
    for spec in PARAM_SPECS:
        if spec.name != "BATT_CAPACITY":  # the scenario's airframe sets the pack's capacity
            assert by_name[spec.name].param_value == pytest.approx(spec.default)
        assert by_name[spec.name].param_type == spec.mav_type
    assert by_name["RTL_ALT"].param_type == mav.MAV_PARAM_TYPE_INT32


def test_request_list_is_paced_over_several_steps():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_param_request_list_message(1, 1))
    gcs.sim.step()
    assert 0 < len([m for m in gcs.poll() if m.get_type() == "PARAM_VALUE"]) < len(PARAM_SPECS)


def test_param_set_stores_the_value_and_echoes_it_to_every_gcs():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_param_set_message(1, 1, b"RTL_ALT", 3000.0, mav.MAV_PARAM_TYPE_INT32))
    reply = gcs.wait_for("PARAM_VALUE", 1.0)
    assert (reply.param_id, reply.param_value, reply.param_index) == ("RTL_ALT", 3000.0, 65535)  # index -1 in a uint16
    assert gcs.sim.autopilot.params.get("RTL_ALT") == 3000.0


def test_param_set_on_an_integer_parameter_echoes_the_rounded_stored_value():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_param_set_message(1, 1, b"LAND_SPEED", 72.6, mav.MAV_PARAM_TYPE_INT16))
    assert gcs.wait_for("PARAM_VALUE", 1.0).param_value == 73.0


def test_param_request_read_by_name_and_by_index():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_param_request_read_message(1, 1, b"FS_GCS_TIMEOUT", -1))
    by_name = gcs.wait_for("PARAM_VALUE", 1.0)
    assert (by_name.param_id, by_name.param_value, by_name.param_index) == ("FS_GCS_TIMEOUT", 5.0, 65535)
    index = [s.name for s in PARAM_SPECS].index("WPNAV_SPEED")
    gcs.send(mav.MAVLink_param_request_read_message(1, 1, b"", index))
    by_index = gcs.wait_for("PARAM_VALUE", 1.0)
    assert (by_index.param_id, by_index.param_value, by_index.param_index) == ("WPNAV_SPEED", 1000.0, index)


@pytest.mark.parametrize("msg", [
    mav.MAVLink_param_set_message(1, 1, b"NO_SUCH_PARAM", 1.0, mav.MAV_PARAM_TYPE_REAL32),
    mav.MAVLink_param_set_message(1, 1, b"RTL_ALT", float("nan"), mav.MAV_PARAM_TYPE_REAL32),
    mav.MAVLink_param_request_read_message(1, 1, b"NO_SUCH_PARAM", -1),
    mav.MAVLink_param_request_read_message(1, 1, b"", 9999),
    mav.MAVLink_param_set_message(2, 1, b"RTL_ALT", 3000.0, mav.MAV_PARAM_TYPE_INT32),  # another vehicle
], ids=["set-unknown", "set-nan", "read-unknown", "read-bad-index", "set-other-sysid"])
def test_unknown_or_invalid_parameter_requests_get_no_answer_and_change_nothing(msg):
    gcs = ready_gcs()
    gcs.send(msg)
    gcs.run(1.0)
    assert _param_values(gcs) == []
    assert gcs.sim.autopilot.params.get("RTL_ALT") == 1500.0


def test_setting_mav_gcs_sysid_by_its_old_name_moves_rc_override_authority():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_param_set_message(1, 1, b"SYSID_MYGCS", 200.0, mav.MAV_PARAM_TYPE_INT16))
    assert gcs.wait_for("PARAM_VALUE", 1.0).param_value == 200.0
    new_gcs = mav.MAVLink(None, srcSystem=200, srcComponent=190)
    gcs.send_raw(mav.MAVLink_rc_channels_override_message(1, 1, 65535, 65535, 1600, *([65535] * 5)).pack(new_gcs))
    assert gcs.wait_for("RC_CHANNELS", 1.0, lambda m: m.chan3_raw == 1600) is not None
