"""VehicleLink against a scripted ArduCopter over an in-memory pipe, on a manual clock."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from vehicle_fakes import HOME, make_rig

from chaser_bt.geo import LocalFrame
from chaser_bt.vehicle import (
    CommandRejected,
    CommandStatus,
    LinkConfig,
    LinkTimeout,
    VehicleError,
    VehicleQuiet,
)

ARM = mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
SET_MODE = mavlink2.MAV_CMD_DO_SET_MODE
TAKEOFF = mavlink2.MAV_CMD_NAV_TAKEOFF


def _no_answer(msg):
    return None, "", False


# ----------------------------------------------------------------------------- link upkeep
def test_heartbeat_sent_at_1hz_on_the_injected_clock():
    r = make_rig()
    r.run(10.0, dt=0.1)  # t = 0.0 .. 9.9: due at 0, 1, ..., 9
    beats = [m for m in r.fake.sent_by_link("HEARTBEAT")]
    assert len(beats) == 10
    assert all(m.type == mavlink2.MAV_TYPE_GCS and m.autopilot == mavlink2.MAV_AUTOPILOT_INVALID for m in beats)
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in beats} == {(255, 190)}


def test_gcs_identity_is_configurable():
    r = make_rig(LinkConfig(gcs_sysid=254, gcs_compid=191))
    r.run(0.5)
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in r.fake.received} == {(254, 191)}


def test_streams_requested_per_message_once_the_vehicle_is_heard():
    r = make_rig(LinkConfig(stream_rates_hz={"GLOBAL_POSITION_INT": 10.0, "SYS_STATUS": 2.0, "VFR_HUD": 0.0}))
    r.run(0.5)
    asked = {int(m.param1): m.param2 for m in r.fake.sent_by_link("COMMAND_LONG", mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL)}
    assert asked == {
        mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 100_000.0,
        mavlink2.MAVLINK_MSG_ID_SYS_STATUS: 500_000.0,
        mavlink2.MAVLINK_MSG_ID_VFR_HUD: -1.0,  # rate 0 = switch the stream off
    }


def test_missing_streams_are_asked_for_again_and_arriving_ones_are_not():
    r = make_rig(LinkConfig(stream_rates_hz={"GLOBAL_POSITION_INT": 1.0, "VFR_HUD": 4.0}))
    r.run(11.0)  # the fake sends GLOBAL_POSITION_INT each second but never VFR_HUD
    asked = [int(m.param1) for m in r.fake.sent_by_link("COMMAND_LONG", mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL)]
    assert asked.count(mavlink2.MAVLINK_MSG_ID_VFR_HUD) == 3  # t = 0, 5, 10
    assert asked.count(mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT) == 1


def test_home_requested_until_it_arrives_and_then_defines_the_frame():
    r = make_rig(send_home=False)
    r.run(5.0)
    requests = r.fake.sent_by_link("COMMAND_LONG", mavlink2.MAV_CMD_REQUEST_MESSAGE)
    assert len(requests) == 3 and all(m.param1 == mavlink2.MAVLINK_MSG_ID_HOME_POSITION for m in requests)
    assert r.link.frame is None and np.isnan(r.link.state.position_enu).all()
    r.fake.send_home = True
    r.run(4.0)
    assert len(r.fake.sent_by_link("COMMAND_LONG", mavlink2.MAV_CMD_REQUEST_MESSAGE)) == 4  # stops once home is in
    assert r.link.frame == LocalFrame(HOME)
    assert r.link.state.position_enu == pytest.approx([0.0, 0.0, 0.0], abs=0.01)


def test_configured_origin_is_the_frame_from_the_start():
    origin = HOME.__class__(HOME.lat_deg, HOME.lon_deg, HOME.alt_m - 10.0)
    r = make_rig(LinkConfig(origin=origin), send_home=False)
    r.run(1.5)
    assert r.link.state.position_enu == pytest.approx([0.0, 0.0, 10.0], abs=0.01)


def test_only_the_first_autopilot_is_followed():
    r = make_rig()
    other = mavlink2.MAVLink(r.fake.end, srcSystem=7, srcComponent=1)
    gcs = mavlink2.MAVLink(r.fake.end, srcSystem=200, srcComponent=190)
    gcs.heartbeat_send(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    r.run(1.0)
    other.heartbeat_send(mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 129, 6, 4)  # armed, RTL
    r.run(0.2)
    assert r.link.target_sysid == 1
    assert (r.link.state.mode, r.link.state.armed) == ("STABILIZE", False)
    assert r.link.counters.other_systems == 2


def test_configured_target_sysid_ignores_other_autopilots():
    r = make_rig(LinkConfig(target_sysid=3))
    r.run(2.0)
    assert r.link.target_sysid == 3 and r.link.target_compid is None and r.link.state.mode == ""


def test_garbage_bytes_are_counted_and_skipped():
    r = make_rig()
    r.fake.end.write(b"\x01\x02garbage\xfd\x09\x00\x00\x00\x01\x01\x00\x00\x00" + b"\x00" * 20)
    r.run(1.5)
    assert r.link.counters.bad_packets >= 1
    assert r.link.state.mode == "STABILIZE"  # good frames after the junk still parse


# ----------------------------------------------------------------------------- quiet link
def test_vehicle_quiet_raised_after_quiet_timeout_with_what_was_last_heard():
    r = make_rig()
    r.run(2.0)  # the fake's last heartbeat and telemetry go out at t = 1.0
    r.fake.end.connected = False  # then the vehicle's radio dies
    r.clock.set(5.9)
    r.link.poll()  # 4.9 s of silence: fine
    r.clock.set(6.2)
    with pytest.raises(VehicleQuiet, match=r"quiet for 5\.2 s: last heard GLOBAL_POSITION_INT at vehicle time 1\.0"):
        r.link.poll()
    r.fake.tick()
    beats_before = len(r.fake.sent_by_link("HEARTBEAT"))
    r.clock.set(7.0)
    with pytest.raises(VehicleQuiet):
        r.link.poll()  # still quiet: raised again, and the heartbeat still goes out first
    r.fake.tick()
    assert len(r.fake.sent_by_link("HEARTBEAT")) == beats_before + 1
    r.fake.end.connected = True
    r.fake.tick()  # the vehicle talks again
    assert r.link.poll() > 0


def test_vehicle_quiet_when_nothing_was_ever_heard():
    r = make_rig()
    r.fake.end.connected = False
    r.clock.set(4.9)
    r.link.poll()  # not yet
    r.clock.set(5.1)
    with pytest.raises(VehicleQuiet, match="no MAVLink from an autopilot"):
        r.link.poll()


# ----------------------------------------------------------------------------- commands
def test_accepted_ack_completes_the_command(rig):
    cmd = rig.link.takeoff(15.0)
    assert cmd.status is CommandStatus.SENT
    rig.run(1.0, until=lambda: cmd.done)
    assert cmd.ok and cmd.result == mavlink2.MAV_RESULT_ACCEPTED and cmd.attempts == 1
    (sent,) = rig.fake.sent_by_link("COMMAND_LONG", TAKEOFF)
    assert sent.param7 == 15.0 and (sent.target_system, sent.target_component) == (1, 1)


@pytest.mark.parametrize("text_first", [True, False])
def test_failed_ack_captures_the_statustext_reason(rig, text_first):
    rig.fake.answers[TAKEOFF] = lambda m: (mavlink2.MAV_RESULT_FAILED, "Takeoff: not armed", text_first)
    cmd = rig.link.takeoff(10.0)
    rig.run(1.0)
    assert cmd.status is CommandStatus.FAILED and cmd.result == mavlink2.MAV_RESULT_FAILED
    assert cmd.reason == "MAV_RESULT_FAILED; Takeoff: not armed"


def test_no_ack_retries_then_times_out(rig):
    rig.fake.answers[TAKEOFF] = _no_answer
    cmd = rig.link.takeoff(10.0)
    rig.run(5.9)
    assert cmd.status is CommandStatus.SENT and cmd.attempts == 4
    rig.run(0.2)
    assert cmd.status is CommandStatus.TIMED_OUT and cmd.reason == "no answer after 4 attempts"
    sent = rig.fake.sent_by_link("COMMAND_LONG", TAKEOFF)
    assert [m.confirmation for m in sent] == [0, 1, 2, 3]
    assert rig.link.counters.commands_retried == 3


def test_retry_succeeds_when_a_later_attempt_is_answered(rig):
    answers = iter([(None, "", False), (mavlink2.MAV_RESULT_ACCEPTED, "", False)])
    rig.fake.answers[TAKEOFF] = lambda m: next(answers)
    cmd = rig.link.takeoff(10.0)
    rig.run(3.0, until=lambda: cmd.done)
    assert cmd.ok and cmd.attempts == 2


def test_in_progress_ack_waits_without_resending(rig):
    answers = iter([(mavlink2.MAV_RESULT_IN_PROGRESS, "", False)])
    rig.fake.answers[TAKEOFF] = lambda m: next(answers)
    cmd = rig.link.takeoff(10.0)
    rig.run(1.4)
    rig.fake.mav.command_ack_send(TAKEOFF, mavlink2.MAV_RESULT_IN_PROGRESS, 50, 0, 255, 190)
    rig.run(1.4)
    assert cmd.status is CommandStatus.SENT and cmd.attempts == 1
    rig.fake.mav.command_ack_send(TAKEOFF, mavlink2.MAV_RESULT_ACCEPTED, 100, 0, 255, 190)
    rig.run(0.2)
    assert cmd.ok and cmd.attempts == 1


def test_arm_waits_for_readiness_then_succeeds():
    r = make_rig(ready=False)
    r.run(1.2)
    cmd = r.link.arm()
    r.run(30.0)
    assert cmd.status is CommandStatus.WAITING
    assert not r.fake.sent_by_link("COMMAND_LONG", ARM)  # never asked while not ready
    r.fake.ready = True
    r.run(3.0, until=lambda: cmd.done)
    assert cmd.ok and r.link.state.armed
    (sent,) = r.fake.sent_by_link("COMMAND_LONG", ARM)
    assert sent.param1 == 1 and sent.param2 == 0


def test_arm_gives_up_after_ready_timeout_with_the_prearm_reason():
    r = make_rig(LinkConfig(ready_timeout_s=10.0), ready=False)
    r.run(1.2)
    cmd = r.link.arm()
    r.run(3.0)
    r.fake.statustext("PreArm: Need 3D Fix")
    r.run(8.0)
    assert cmd.status is CommandStatus.TIMED_OUT
    assert "pre-arm checks failing" in cmd.reason and "GPS fix type 1" in cmd.reason
    assert cmd.reason.endswith("PreArm: Need 3D Fix")


def test_arm_refused_by_the_autopilot_is_failed_with_its_reason(rig):
    rig.link.state.prearm_ok = True  # the link believes it is ready; the autopilot disagrees
    rig.fake.ready = False
    cmd = rig.link.arm()
    rig.run(1.0)
    assert cmd.status is CommandStatus.FAILED and cmd.reason.endswith("PreArm: Need 3D Fix")


def test_arm_when_already_armed_succeeds_without_sending(rig):
    rig.fake.armed = True
    rig.run(1.0)
    cmd = rig.link.arm()
    assert cmd.ok
    rig.run(1.0)
    assert not rig.fake.sent_by_link("COMMAND_LONG", ARM)


def test_arm_is_accepted_only_once_the_heartbeat_shows_armed(rig):
    cmd = rig.link.arm()
    rig.run(0.3)
    assert rig.fake.armed and not rig.link.state.armed
    assert cmd.status is CommandStatus.SENT  # acked; waiting for the next heartbeat
    rig.run(1.0, until=lambda: cmd.done)
    assert cmd.ok and rig.link.state.armed


def test_force_disarm_sends_the_magic_number(rig):
    rig.fake.armed = True
    rig.run(1.0)
    cmd = rig.link.disarm(force=True)
    rig.run(2.0, until=lambda: cmd.done)
    assert cmd.ok
    (sent,) = rig.fake.sent_by_link("COMMAND_LONG", ARM)
    assert (sent.param1, sent.param2) == (0, 21196)


def test_set_mode_to_the_current_mode_succeeds_immediately(rig):
    cmd = rig.link.set_mode("STABILIZE")
    assert cmd.ok
    rig.run(1.0)
    assert not rig.fake.sent_by_link("COMMAND_LONG", SET_MODE)


def test_set_mode_needs_heartbeat_confirmation():
    r = make_rig(apply_modes=False)
    r.run(1.2)
    cmd = r.link.set_mode("GUIDED")
    r.run(1.0)
    assert cmd.result == mavlink2.MAV_RESULT_ACCEPTED and cmd.status is CommandStatus.SENT
    (sent,) = r.fake.sent_by_link("COMMAND_LONG", SET_MODE)
    assert (sent.param1, sent.param2) == (mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4)
    r.fake.mode_number = 4
    r.run(1.5, until=lambda: cmd.done)
    assert cmd.ok and r.link.state.mode == "GUIDED"


def test_set_mode_times_out_when_the_heartbeat_never_shows_it():
    r = make_rig(apply_modes=False)
    r.run(1.2)
    cmd = r.link.set_mode("LOITER")
    r.run(5.0)
    assert cmd.status is CommandStatus.TIMED_OUT and "telemetry did not show it" in cmd.reason


def test_a_lost_ack_is_not_a_refusal_when_the_heartbeat_shows_the_mode():
    # The vehicle switched (its heartbeat says RTL) but every ack was lost on a noisy link: done, not
    # "no answer after 4 attempts".
    r = make_rig()
    r.run(1.2)
    r.fake.answers[SET_MODE] = _no_answer
    cmd = r.link.set_mode("RTL")
    r.run(0.5)
    assert cmd.status is CommandStatus.SENT
    r.fake.mode_number = 6
    r.run(1.5, until=lambda: cmd.done)
    assert cmd.ok and cmd.attempts == 1


def test_heartbeats_lost_after_the_ack_are_not_the_vehicle_saying_no():
    # A noisy link eats the heartbeats for 4 s after the ack; the mode did change. Unconfirmed is
    # called only after two heartbeats that do not show it (bounded at 3 x confirm_timeout_s).
    r = make_rig()
    r.run(1.2)
    beat = r.fake.heartbeat
    r.fake.heartbeat = lambda: None
    cmd = r.link.set_mode("RTL")
    r.run(4.0)
    assert cmd.status is CommandStatus.SENT and cmd.result == mavlink2.MAV_RESULT_ACCEPTED
    r.fake.heartbeat = beat
    r.run(2.0, until=lambda: cmd.done)
    assert cmd.ok and r.link.state.mode == "RTL"


def test_position_mode_on_the_ground_waits_for_a_position_estimate():
    r = make_rig(ready=False)
    r.run(1.2)
    cmd = r.link.set_mode("GUIDED")
    r.run(10.0)
    assert cmd.status is CommandStatus.WAITING and not r.fake.sent_by_link("COMMAND_LONG", SET_MODE)
    r.fake.ready = True
    r.run(3.0, until=lambda: cmd.done)
    assert cmd.ok


def test_position_mode_in_the_air_is_sent_at_once_even_without_a_position():
    r = make_rig(ready=False, armed=True)
    r.run(1.2)
    cmd = r.link.set_mode("LOITER")
    assert cmd.status is CommandStatus.SENT


def test_set_mode_rejects_unknown_names_listing_the_known_ones(rig):
    with pytest.raises(ValueError, match="GUIDED.*ALT_HOLD|ALT_HOLD.*GUIDED"):
        rig.link.set_mode("GUIDE")


def test_a_newer_mode_request_supersedes_an_older_one_in_flight(rig):
    rig.fake.answers[SET_MODE] = _no_answer
    first = rig.link.set_mode("GUIDED")
    rig.run(0.2)
    del rig.fake.answers[SET_MODE]
    second = rig.link.set_mode("RTL")
    rig.run(2.0, until=lambda: second.done)
    assert first.status is CommandStatus.FAILED and "superseded" in first.reason
    assert second.ok and rig.link.state.mode == "RTL"


def test_rtl_is_accepted_when_the_vehicle_shows_rtl(rig):
    cmd = rig.link.rtl()
    rig.run(2.0, until=lambda: cmd.done)
    assert cmd.ok and rig.link.state.mode == "RTL"
    assert rig.link.rtl().ok  # already there


def test_commands_wait_for_the_vehicle_to_be_heard():
    r = make_rig()
    cmd = r.link.takeoff(5.0)
    assert cmd.status is CommandStatus.WAITING
    r.run(1.0, until=lambda: cmd.done)
    assert cmd.ok


def test_set_param_is_done_when_the_value_is_echoed(rig):
    cmd = rig.link.set_param("RTL_ALT", 2000)
    rig.run(1.0, until=lambda: cmd.done)
    assert cmd.ok and rig.link.params["RTL_ALT"] == 2000.0 and rig.fake.params["RTL_ALT"] == 2000.0


def test_set_param_fails_when_the_vehicle_keeps_another_value(rig):
    cmd = rig.link.set_param("DISARM_DELAY", 2.5)  # the fake stores it as an integer
    rig.run(8.0, until=lambda: cmd.done)
    assert cmd.status is CommandStatus.FAILED and cmd.reason == "vehicle reports DISARM_DELAY = 2"


def test_set_param_of_an_unknown_name_times_out(rig):
    cmd = rig.link.set_param("NO_SUCH_PARAM", 1.0)
    rig.run(8.0, until=lambda: cmd.done)
    assert cmd.status is CommandStatus.TIMED_OUT


def test_request_param_fills_params(rig):
    cmd = rig.link.request_param("RTL_ALT")
    assert rig.link.request_param("RTL_ALT") is cmd  # one read in flight per name
    rig.run(1.0, until=lambda: cmd.done)
    assert cmd.ok and rig.link.params == {"RTL_ALT": 1500.0}


# ----------------------------------------------------------------------------- set-points
def test_goto_enu_sends_a_relative_altitude_global_target(rig):
    rig.link.goto_enu((100.0, 0.0, 20.0), yaw_enu_rad=0.0)
    rig.fake.tick()
    (m,) = rig.fake.sent_by_link("SET_POSITION_TARGET_GLOBAL_INT")
    expected = LocalFrame(HOME).to_geodetic((100.0, 0.0, 20.0))
    assert m.coordinate_frame == mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    assert (m.lat_int, m.lon_int) == (round(expected.lat_deg * 1e7), round(expected.lon_deg * 1e7))
    assert m.alt == pytest.approx(20.0, abs=1e-3)
    assert m.yaw == pytest.approx(math.pi / 2)  # ENU yaw 0 = facing east = NED yaw 90 deg
    assert m.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_VX_IGNORE
    assert not m.type_mask & (mavlink2.POSITION_TARGET_TYPEMASK_X_IGNORE | mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE)
    assert rig.link.last_setpoint.kind == "position"


def test_goto_without_yaw_leaves_yaw_to_the_autopilot(rig):
    rig.link.goto_global(HOME, 30.0)
    rig.fake.tick()
    (m,) = rig.fake.sent_by_link("SET_POSITION_TARGET_GLOBAL_INT")
    assert m.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE and m.alt == 30.0


def test_goto_enu_before_any_frame_is_an_error():
    r = make_rig(send_home=False)
    r.run(1.2)
    with pytest.raises(VehicleError, match="HOME_POSITION"):
        r.link.goto_enu((0.0, 0.0, 10.0))


def test_velocity_enu_becomes_local_ned_velocity(rig):
    rig.link.velocity_enu((1.0, 2.0, 3.0), yaw_rate=0.5)
    rig.fake.tick()
    (m,) = rig.fake.sent_by_link("SET_POSITION_TARGET_LOCAL_NED")
    assert (m.vx, m.vy, m.vz) == (2.0, 1.0, -3.0)
    assert m.yaw_rate == -0.5  # counter-clockwise ENU = negative NED yaw rate
    assert m.coordinate_frame == mavlink2.MAV_FRAME_LOCAL_NED
    assert m.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_X_IGNORE
    assert not m.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE


def test_velocity_enu_with_a_heading_lets_the_autopilot_turn(rig):
    """ENU yaw 0 (east) is NED heading +90 deg; the yaw is sent and the yaw rate masked."""
    rig.link.velocity_enu((1.0, 0.0, 0.0), yaw_enu_rad=0.0)
    rig.fake.tick()
    (m,) = rig.fake.sent_by_link("SET_POSITION_TARGET_LOCAL_NED")
    assert m.yaw == pytest.approx(math.pi / 2)
    assert not m.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
    assert m.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
    with pytest.raises(ValueError, match="not both"):
        rig.link.velocity_enu((1.0, 0.0, 0.0), yaw_rate=0.1, yaw_enu_rad=0.0)


def test_rc_override_is_resent_at_5hz_until_released(rig):
    rig.link.rc_override(pitch=1300, throttle=1500)
    rig.run(2.0)
    overrides = rig.fake.sent_by_link("RC_CHANNELS_OVERRIDE")
    assert len(overrides) == 10
    m = overrides[0]
    assert (m.chan1_raw, m.chan2_raw, m.chan3_raw, m.chan4_raw, m.chan5_raw) == (65535, 1300, 1500, 65535, 65535)
    rig.link.release_rc()
    rig.run(2.0)
    overrides = rig.fake.sent_by_link("RC_CHANNELS_OVERRIDE")
    assert len(overrides) == 11
    assert [getattr(overrides[-1], f"chan{i}_raw") for i in range(1, 19)] == [0] * 18


def test_rc_override_rejects_out_of_range_pwm(rig):
    with pytest.raises(ValueError, match="pitch"):
        rig.link.rc_override(pitch=3000)


def test_rc_override_is_released_when_the_vehicle_switches_to_rtl(rig):
    rig.link.rc_override(1500, 1500, 1500, 1500)
    rig.fake.mode_number = 6  # e.g. the GCS failsafe or the pilot
    rig.run(1.5)
    count = len(rig.fake.sent_by_link("RC_CHANNELS_OVERRIDE"))
    assert rig.fake.sent_by_link("RC_CHANNELS_OVERRIDE")[-1].chan3_raw == 0
    rig.run(1.0)
    assert len(rig.fake.sent_by_link("RC_CHANNELS_OVERRIDE")) == count


def test_switching_to_alt_hold_first_holds_throttle_at_1500(rig):
    cmd = rig.link.set_mode("ALT_HOLD")
    rig.run(2.0, until=lambda: cmd.done)
    assert cmd.ok
    kinds = [m.get_type() for m in rig.fake.received if m.get_type() in ("RC_CHANNELS_OVERRIDE", "COMMAND_LONG")
             and getattr(m, "command", SET_MODE) == SET_MODE]
    assert kinds[:2] == ["RC_CHANNELS_OVERRIDE", "COMMAND_LONG"]
    assert rig.fake.sent_by_link("RC_CHANNELS_OVERRIDE")[0].chan3_raw == 1500


def test_hover_in_guided_holds_the_current_position(rig):
    rig.fake.mode_number, rig.fake.armed = 4, True
    lat, lon = LocalFrame(HOME).to_geodetic((30.0, -40.0, 0.0)).lat_deg, LocalFrame(HOME).to_geodetic((30.0, -40.0, 0.0)).lon_deg
    rig.fake.position = (lat, lon, HOME.alt_m + 12.0, 12.0)
    rig.run(1.0)
    rig.link.hover()
    rig.fake.tick()
    (m,) = rig.fake.sent_by_link("SET_POSITION_TARGET_GLOBAL_INT")
    assert (m.lat_int, m.lon_int) == (round(lat * 1e7), round(lon * 1e7)) and m.alt == pytest.approx(12.0, abs=1e-3)


def test_hover_in_alt_hold_centres_the_sticks_and_in_rtl_does_nothing(rig):
    rig.fake.mode_number, rig.fake.armed = 2, True
    rig.run(1.0)
    rig.link.hover()
    rig.fake.tick()
    m = rig.fake.sent_by_link("RC_CHANNELS_OVERRIDE")[-1]
    assert (m.chan1_raw, m.chan2_raw, m.chan3_raw, m.chan4_raw) == (1500, 1500, 1500, 1500)
    rig.fake.mode_number = 6
    rig.run(1.0)
    before = len(rig.fake.received)
    rig.link.hover()
    rig.fake.tick()
    assert not [m for m in rig.fake.received[before:] if m.get_type() != "HEARTBEAT"]


def test_hover_on_a_disarmed_vehicle_sends_nothing(rig):
    rig.fake.mode_number = 0  # STABILIZE, on the ground
    rig.fake.armed = False
    rig.run(1.0)
    before = len(rig.fake.received)
    rig.link.hover()
    rig.fake.tick()
    assert not [m for m in rig.fake.received[before:] if m.get_type() != "HEARTBEAT"]


# ----------------------------------------------------------------------------- wait helper
def test_wait_pumps_until_the_command_is_accepted(rig):
    def pump():
        rig.clock.advance(0.05)
        rig.fake.tick()

    cmd = rig.link.wait(rig.link.set_mode("GUIDED"), 5.0, pump=pump)
    assert cmd.ok
    assert rig.link.wait(lambda s: s.mode == "GUIDED", 1.0, pump=pump) is True
    assert rig.link.wait(lambda: rig.link.state.mode == "GUIDED", 1.0, pump=pump) is True


def test_wait_raises_for_refused_commands_and_on_timeout(rig):
    def pump():
        rig.clock.advance(0.05)
        rig.fake.tick()

    rig.fake.answers[TAKEOFF] = lambda m: (mavlink2.MAV_RESULT_DENIED, "", False)
    with pytest.raises(CommandRejected, match="takeoff.*failed: MAV_RESULT_DENIED"):
        rig.link.wait(rig.link.takeoff(5.0), 5.0, pump=pump)
    with pytest.raises(LinkTimeout):
        rig.link.wait(lambda s: s.armed, 2.0, pump=pump)


def test_listeners_see_every_message_in_and_out(rig):
    received, sent = [], []
    heartbeats_before = rig.link.counters.received["HEARTBEAT"]
    rig.link.add_listener(on_receive=lambda m: received.append(m.get_type()), on_send=lambda m: sent.append(m.get_type()))
    rig.run(2.0)
    rig.link.set_mode("GUIDED")
    rig.run(1.0)
    assert "HEARTBEAT" in received and received.count("HEARTBEAT") == rig.link.counters.received["HEARTBEAT"] - heartbeats_before
    assert "COMMAND_LONG" in sent and sent.count("HEARTBEAT") >= 2  # the GCS heartbeat at 1 Hz



# ----------------------------------------------------------------------------- the wire tap
def test_wire_tap_sees_every_byte_the_vehicle_sent_and_the_time_of_every_poll():
    r = make_rig()
    sent = bytearray()
    fake_write = r.fake.end.write
    r.fake.end.write = lambda data: (sent.extend(data), fake_write(data))[1]
    read, polls = bytearray(), []
    remove = r.link.add_wire_tap(read.extend, polls.append)
    r.run(1.0, dt=0.25)  # fake ticks, link polls, clock moves on: 4 polls at 0, 0.25, 0.5, 0.75
    assert polls == [0.0, 0.25, 0.5, 0.75]
    assert len(sent) > 0 and bytes(read) == bytes(sent)
    assert r.link.opened_at_s == 0.0 and r.link.now() == 1.0
    remove()
    r.run(0.5, dt=0.25)
    assert polls == [0.0, 0.25, 0.5, 0.75] and len(read) < len(sent)  # removed: sees nothing more


def test_wire_tap_reports_a_poll_that_raised():
    r = make_rig(LinkConfig(quiet_timeout_s=1.0))
    polls = []
    r.link.add_wire_tap(lambda data: None, polls.append)
    r.clock.set(5.0)  # nothing ever heard for longer than the quiet timeout
    with pytest.raises(VehicleQuiet):
        r.link.poll()
    assert polls == [5.0]
