"""The simulator looks like ArduCopter to a MAVLink client: heartbeat, modes, commands, failsafe, targets.

All over an in-memory pipe with pymavlink encoding and decoding on the client side; answers are
ArduCopter's (mode numbers, MAV_RESULT codes, STATUSTEXT before the refusing ACK).
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mavlink_gcs import PipeGcs, airborne_gcs, mav, quick_scenario, ready_gcs
from pymavlink import mavutil

from sitl.simulator import Simulator

ACCEPTED, FAILED, DENIED, UNSUPPORTED = (
    mav.MAV_RESULT_ACCEPTED,
    mav.MAV_RESULT_FAILED,
    mav.MAV_RESULT_DENIED,
    mav.MAV_RESULT_UNSUPPORTED,
)
CUSTOM = mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


def test_heartbeat_identifies_an_arducopter_octocopter_at_1hz():
    gcs = PipeGcs(Simulator(quick_scenario(), 0))
    gcs.run(9.9)  # sends at 0 (the first step), 1, ..., 9 s and 0, 0.25, ..., 9.75 s
    beats = gcs.of_type("HEARTBEAT")
    assert len(beats) == 10
    hb = beats[-1]
    assert (hb.type, hb.autopilot) == (mav.MAV_TYPE_OCTOROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA)
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == mav.MAV_COMP_ID_AUTOPILOT1
    assert hb.base_mode & CUSTOM
    assert not hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.system_status == mav.MAV_STATE_STANDBY
    assert mavutil.mode_string_v10(hb) == "STABILIZE"


def test_sysid_comes_from_sysid_thismav():
    gcs = PipeGcs(Simulator(quick_scenario(params={"SYSID_THISMAV": 7}), 0))
    assert gcs.wait_for("HEARTBEAT", 1.5).get_srcSystem() == 7


@pytest.mark.parametrize("name", ["GUIDED", "LOITER", "RTL", "LAND", "BRAKE", "ALT_HOLD", "STABILIZE"])
def test_mode_string_names_each_mode_after_do_set_mode(name):
    gcs = ready_gcs()
    number = {v: k for k, v in mavutil.mode_mapping_acm.items()}[name]
    if name == "STABILIZE":  # already in it: go elsewhere first so the change is visible
        assert gcs.set_mode(5).result == ACCEPTED
    assert gcs.set_mode(number).result == ACCEPTED
    hb = gcs.wait_for("HEARTBEAT", 1.5)
    assert hb.custom_mode == number
    assert mavutil.mode_string_v10(hb) == name


def test_heartbeat_shows_armed_guided_active_in_flight():
    gcs = airborne_gcs(5.0)
    hb = gcs.wait_for("HEARTBEAT", 1.5)
    assert hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.base_mode & mav.MAV_MODE_FLAG_GUIDED_ENABLED
    assert hb.system_status == mav.MAV_STATE_ACTIVE


def test_arming_without_gps_fix_is_refused_with_statustext_before_the_ack():
    gcs = PipeGcs(Simulator(quick_scenario(boot={"gps_fix_s": 60, "ekf_ready_s": 60, "prearm_ok_s": 60}), 0))
    gcs.run(1.0)
    ack, seen = gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert ack.result == FAILED
    texts = [m for m in seen if m.get_type() == "STATUSTEXT"]
    assert [t.text for t in texts] == ["PreArm: Need 3D Fix"]
    assert texts[0].severity == mav.MAV_SEVERITY_CRITICAL
    assert seen.index(texts[0]) < seen.index(ack)
    assert not gcs.wait_for("HEARTBEAT", 1.5).base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED


def test_force_arm_magic_skips_the_prearm_checks():
    gcs = PipeGcs(Simulator(quick_scenario(boot={"gps_fix_s": 60, "ekf_ready_s": 60, "prearm_ok_s": 60}), 0))
    gcs.run(1.0)
    ack, _ = gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1, 21196)
    assert ack.result == ACCEPTED
    assert gcs.wait_for("HEARTBEAT", 1.5).base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED


def test_arming_in_rtl_is_refused_as_not_armable():
    gcs = ready_gcs()
    assert gcs.set_mode(6).result == ACCEPTED
    ack, seen = gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert ack.result == FAILED
    assert "Arm: Mode not armable" in [m.text for m in seen if m.get_type() == "STATUSTEXT"]


# (command, params, expected result) on a booted, disarmed copter in STABILIZE
COMMAND_TABLE = [
    (mav.MAV_CMD_COMPONENT_ARM_DISARM, (1,), ACCEPTED),
    (mav.MAV_CMD_COMPONENT_ARM_DISARM, (0,), ACCEPTED),
    (mav.MAV_CMD_COMPONENT_ARM_DISARM, (2,), UNSUPPORTED),
    (mav.MAV_CMD_DO_SET_MODE, (CUSTOM, 5), ACCEPTED),
    (mav.MAV_CMD_DO_SET_MODE, (0, 5), DENIED),  # no custom-mode flag: ArduPilot denies
    (mav.MAV_CMD_DO_SET_MODE, (CUSTOM, 99), FAILED),
    (mav.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, 0, 0, 10), FAILED),  # not armed in GUIDED
    (mav.MAV_CMD_NAV_RETURN_TO_LAUNCH, (), ACCEPTED),
    (mav.MAV_CMD_NAV_LAND, (), ACCEPTED),
    (mav.MAV_CMD_DO_CHANGE_SPEED, (1, 5), FAILED),  # only GUIDED navigation takes a speed
    (mav.MAV_CMD_DO_CHANGE_SPEED, (2, 1), UNSUPPORTED),  # climb speed is not simulated
    (mav.MAV_CMD_SET_MESSAGE_INTERVAL, (mav.MAVLINK_MSG_ID_ATTITUDE, 100000), ACCEPTED),
    (mav.MAV_CMD_SET_MESSAGE_INTERVAL, (9999, 100000), DENIED),
    (mav.MAV_CMD_GET_MESSAGE_INTERVAL, (mav.MAVLINK_MSG_ID_ATTITUDE,), ACCEPTED),
    (mav.MAV_CMD_REQUEST_MESSAGE, (mav.MAVLINK_MSG_ID_HOME_POSITION,), ACCEPTED),
    (mav.MAV_CMD_REQUEST_MESSAGE, (9999,), FAILED),
    (mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, (1,), ACCEPTED),
    (mav.MAV_CMD_CONDITION_YAW, (90, 10, 1, 0), UNSUPPORTED),
    (31999, (), UNSUPPORTED),
]


@pytest.mark.parametrize("command,params,expected", COMMAND_TABLE, ids=lambda v: str(v))
def test_every_command_gets_exactly_one_ack(command, params, expected):
    gcs = ready_gcs()
    ack, _ = gcs.command_ack(command, *params)
    assert ack is not None, "no COMMAND_ACK"
    assert ack.result == expected
    assert (ack.target_system, ack.target_component) == (255, 190)
    gcs.run(1.0)
    assert len([m for m in gcs.of_type("COMMAND_ACK") if m.command == command]) == 1


def test_command_int_is_handled_like_command_long():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_command_int_message(1, 1, 0, mav.MAV_CMD_DO_SET_MODE, 0, 0, CUSTOM, 17, 0, 0, 0, 0, 0))
    ack = gcs.wait_for("COMMAND_ACK", 1.0)
    assert (ack.command, ack.result) == (mav.MAV_CMD_DO_SET_MODE, ACCEPTED)
    assert gcs.wait_for("HEARTBEAT", 1.5).custom_mode == 17


def test_legacy_set_mode_is_acked_with_its_message_id():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_set_mode_message(1, CUSTOM, 4))
    ack = gcs.wait_for("COMMAND_ACK", 1.0)
    assert (ack.command, ack.result) == (mav.MAVLINK_MSG_ID_SET_MODE, ACCEPTED)
    assert gcs.wait_for("HEARTBEAT", 1.5).custom_mode == 4


def test_commands_for_another_system_are_ignored_and_broadcast_is_obeyed():
    gcs = ready_gcs()
    ack, _ = gcs.command_ack(mav.MAV_CMD_DO_SET_MODE, CUSTOM, 5, target=(42, 1))
    assert ack is None
    ack, _ = gcs.command_ack(mav.MAV_CMD_DO_SET_MODE, CUSTOM, 5, target=(1, 99))
    assert ack is None
    assert gcs.sim.endpoint.stats.not_for_us == 2
    assert gcs.wait_for("HEARTBEAT", 1.5).custom_mode == 0
    ack, _ = gcs.command_ack(mav.MAV_CMD_DO_SET_MODE, CUSTOM, 5, target=(0, 0))
    assert ack.result == ACCEPTED


def test_autopilot_version_answers_capabilities_request_after_the_ack():
    gcs = ready_gcs()
    gcs.command_ack(mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1)
    gcs.run(0.1)
    (version,) = gcs.of_type("AUTOPILOT_VERSION")
    assert version.capabilities & mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert version.capabilities & mav.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    assert version.flight_sw_version >> 24 == 4
    types = [m.get_type() for _, m in gcs.log]
    assert types.index("COMMAND_ACK") < types.index("AUTOPILOT_VERSION")


def test_lost_gcs_heartbeat_switches_guided_flight_to_rtl():
    gcs = airborne_gcs(10.0)
    for _ in range(5):  # a GCS heartbeating at 1 Hz while flying GUIDED
        silent_from = gcs.sim.time_s
        gcs.heartbeat()
        gcs.run(1.0)
    assert gcs.of_type("HEARTBEAT")[-1].custom_mode == 4
    rtl = gcs.wait_for("HEARTBEAT", 10.0, lambda m: m.custom_mode == 6)
    assert rtl is not None
    timeout = gcs.sim.autopilot.params.get("FS_GCS_TIMEOUT")
    assert timeout <= gcs.sim.time_s - silent_from <= timeout + 1.1  # + up to one HEARTBEAT period
    assert rtl.system_status == mav.MAV_STATE_CRITICAL
    assert "GCS Failsafe" in [m.text for m in gcs.of_type("STATUSTEXT", silent_from)]


def test_heartbeats_from_another_sysid_do_not_arm_the_gcs_failsafe():
    gcs = airborne_gcs(10.0)
    stranger = mav.MAVLink(None, srcSystem=200, srcComponent=190)
    for _ in range(3):
        msg = mav.MAVLink_heartbeat_message(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3)
        gcs.send_raw(msg.pack(stranger))
        stranger.seq += 1
        gcs.run(1.0)
    gcs.run(10.0)  # failsafe only counts once our GCS has been heard
    assert gcs.of_type("HEARTBEAT")[-1].custom_mode == 4


def _rc_override(sender_sysid: int, throttle: int, target: int = 1) -> bytes:
    sender = mav.MAVLink(None, srcSystem=sender_sysid, srcComponent=190)
    channels = [65535, 65535, throttle, 65535] + [65535] * 4 + [0] * 10
    return mav.MAVLink_rc_channels_override_message(target, 1, *channels).pack(sender)


def test_rc_override_from_the_gcs_sysid_is_applied():
    gcs = ready_gcs()
    gcs.send_raw(_rc_override(255, 1700))
    rc = gcs.wait_for("RC_CHANNELS", 1.0, lambda m: m.chan3_raw == 1700)
    assert rc is not None
    assert (rc.chan1_raw, rc.chan2_raw, rc.chan4_raw) == (1500, 1500, 1500)


@pytest.mark.parametrize("sender,target", [(200, 1), (255, 42)], ids=["other-sysid", "other-target"])
def test_rc_override_from_another_sysid_or_for_another_vehicle_is_ignored(sender, target):
    gcs = ready_gcs()
    gcs.send_raw(_rc_override(sender, 1700, target))
    gcs.run(1.0)
    assert all(m.chan3_raw == 1000 for m in gcs.of_type("RC_CHANNELS"))
    assert gcs.sim.endpoint.stats.not_for_us == 1


def test_garbage_bytes_are_skipped_counted_and_the_next_command_still_works():
    gcs = ready_gcs()
    junk = bytes(range(1, 250)) + b"\xfd\x05\x00\x00" + b"\x00" * 40  # includes a bogus v2 header
    gcs.send_raw(junk)
    ack, _ = gcs.command_ack(mav.MAV_CMD_DO_SET_MODE, CUSTOM, 5)
    assert ack is not None and ack.result == ACCEPTED
    assert gcs.sim.endpoint.stats.bad_packets >= 1


def test_corrupted_packet_is_dropped_not_obeyed():
    gcs = ready_gcs()
    packet = bytearray(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_DO_SET_MODE, 0, CUSTOM, 5, 0, 0, 0, 0, 0).pack(gcs.mav))
    packet[-3] ^= 0xFF  # flip payload bits: the CRC no longer matches
    gcs.send_raw(bytes(packet))
    gcs.run(1.5)
    assert gcs.of_type("COMMAND_ACK") == []
    assert gcs.sim.endpoint.stats.bad_packets == 1
    assert gcs.of_type("HEARTBEAT")[-1].custom_mode == 0


_SHARED: list[PipeGcs] = []


def _shared_gcs() -> PipeGcs:
    """One booted simulator reused by the property tests (its state only accumulates)."""
    if not _SHARED:
        _SHARED.append(ready_gcs())
    return _SHARED[0]


_floats = st.floats(allow_nan=True, allow_infinity=True, width=32)


@settings(max_examples=150, deadline=None)
@given(
    command=st.one_of(st.sampled_from([c for c, _, _ in COMMAND_TABLE]), st.integers(0, 65535)),
    params=st.lists(_floats, min_size=7, max_size=7),
)
def test_any_command_long_gets_one_ack_and_never_raises(command, params):
    gcs = _shared_gcs()
    before = len(gcs.of_type("COMMAND_ACK"))
    gcs.send(mav.MAVLink_command_long_message(1, 1, command, 0, *params))
    gcs.run(0.04)
    acks = gcs.of_type("COMMAND_ACK")[before:]
    assert [a.command for a in acks] == [command]


@settings(max_examples=100, deadline=None)
@given(
    frame=st.integers(0, 21),
    mask=st.integers(0, 0xFFFF),
    values=st.lists(_floats, min_size=11, max_size=11),
    quat=st.lists(_floats, min_size=4, max_size=4),
)
def test_malformed_setpoints_never_raise_or_poison_the_estimate(frame, mask, values, quat):
    gcs = _shared_gcs()
    x, y, z, vx, vy, vz, ax, ay, az, yaw, rate = values
    gcs.send(mav.MAVLink_set_position_target_local_ned_message(0, 1, 1, frame, mask, x, y, z, vx, vy, vz, ax, ay, az, yaw, rate))
    gcs.send(mav.MAVLink_set_position_target_global_int_message(
        0, 1, 1, frame, mask, 425000000, -716000000, z, vx, vy, vz, ax, ay, az, yaw, rate))
    gcs.send(mav.MAVLink_set_attitude_target_message(0, 1, 1, mask & 0xFF, quat, x, y, rate, vz))
    gcs.run(0.04)
    assert all(math.isfinite(v) for v in gcs.sim.autopilot.position_estimate().pos_enu)


@settings(max_examples=100, deadline=None)
@given(junk=st.binary(max_size=600))
def test_random_bytes_never_raise_and_the_link_recovers(junk):
    gcs = _shared_gcs()
    gcs.send_raw(junk)
    gcs.run(0.02)
    gcs.send_raw(b"\x00" * 300)  # longer than any packet: completes a half-parsed bogus header
    ack, _ = gcs.command_ack(mav.MAV_CMD_GET_MESSAGE_INTERVAL, 0)
    assert ack is not None
