"""Telemetry on the wire: default rates, SET_MESSAGE_INTERVAL / REQUEST_DATA_STREAM, units and frames.

Rates are counted over simulated time (the messages' own time_boot_ms), never wall time. Expected
positions are worked out by hand from the WGS84 metres-per-degree series at 42.5 deg N.
"""

from __future__ import annotations

import math

import pytest
from mavlink_gcs import FIELD, PipeGcs, airborne_gcs, mav, quick_scenario, ready_gcs

from sitl.simulator import Simulator

ATTITUDE = mav.MAVLINK_MSG_ID_ATTITUDE


def _count_between(gcs: PipeGcs, kind: str, t0_ms: int, t1_ms: int) -> int:
    return sum(1 for m in gcs.of_type(kind) if t0_ms <= m.time_boot_ms < t1_ms)


def _now_ms(gcs: PipeGcs) -> int:
    return int(round(gcs.sim.time_s * 1000))


def test_default_rates_are_arducopter_sitl_with_mavproxy():
    gcs = PipeGcs(Simulator(quick_scenario(), 0))
    gcs.run(9.9)  # sends at 0 (the first step), 1, ..., 9 s and 0, 0.25, ..., 9.75 s
    counts = {k: len(gcs.of_type(k)) for k in (
        "HEARTBEAT", "ATTITUDE", "GLOBAL_POSITION_INT", "LOCAL_POSITION_NED", "SYS_STATUS", "GPS_RAW_INT",
        "VFR_HUD", "RC_CHANNELS", "SYSTEM_TIME", "EXTENDED_SYS_STATE", "EKF_STATUS_REPORT", "BATTERY_STATUS",
        "ATTITUDE_QUATERNION",
    )}
    assert counts.pop("HEARTBEAT") == 10
    assert counts.pop("ATTITUDE_QUATERNION") == 0  # ArduPilot streams it only when asked
    assert set(counts.values()) == {40}  # every stream at 4 Hz


def test_set_message_interval_changes_the_rate_and_minus_one_and_zero_mean_off_and_default():
    gcs = ready_gcs()
    ack, _ = gcs.command_ack(mav.MAV_CMD_SET_MESSAGE_INTERVAL, ATTITUDE, 50_000)  # 20 Hz
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    t0 = _now_ms(gcs) + 100
    gcs.run(10.5)
    assert _count_between(gcs, "ATTITUDE", t0, t0 + 10_000) == 200

    gcs.command_ack(mav.MAV_CMD_SET_MESSAGE_INTERVAL, ATTITUDE, -1)
    t0 = _now_ms(gcs) + 100
    gcs.run(5.5)
    assert _count_between(gcs, "ATTITUDE", t0, t0 + 5_000) == 0

    gcs.command_ack(mav.MAV_CMD_SET_MESSAGE_INTERVAL, ATTITUDE, 0)
    t0 = _now_ms(gcs) + 100
    gcs.run(10.5)
    assert _count_between(gcs, "ATTITUDE", t0, t0 + 10_000) == 40


def test_rates_above_the_physics_rate_are_capped_at_one_per_step():
    gcs = ready_gcs()
    gcs.command_ack(mav.MAV_CMD_SET_MESSAGE_INTERVAL, ATTITUDE, 1_000)  # 1 kHz asked
    t0 = _now_ms(gcs) + 100
    gcs.run(2.5)
    assert _count_between(gcs, "ATTITUDE", t0, t0 + 2_000) == round(2.0 / gcs.sim.dt)


def test_get_message_interval_reports_microseconds_or_minus_one():
    gcs = ready_gcs()
    gcs.command_ack(mav.MAV_CMD_GET_MESSAGE_INTERVAL, ATTITUDE)
    gcs.command_ack(mav.MAV_CMD_GET_MESSAGE_INTERVAL, mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION)
    gcs.run(0.1)
    replies = {m.message_id: m.interval_us for m in gcs.of_type("MESSAGE_INTERVAL")}
    assert replies == {ATTITUDE: 250_000, mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: -1}


def test_request_data_stream_sets_whole_stream_groups():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_request_data_stream_message(1, 1, mav.MAV_DATA_STREAM_ALL, 0, 0))  # stop all
    gcs.send(mav.MAVLink_request_data_stream_message(1, 1, mav.MAV_DATA_STREAM_POSITION, 10, 1))
    gcs.run(0.5)
    t = gcs.sim.time_s
    gcs.run(5.0)
    after = [m.get_type() for tt, m in gcs.log if tt > t]
    assert set(after) == {"HEARTBEAT", "GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"}
    assert 49 <= after.count("GLOBAL_POSITION_INT") <= 51


def test_request_message_sends_home_position_once_after_the_ack():
    gcs = ready_gcs()
    before = len(gcs.of_type("HOME_POSITION"))
    gcs.command_ack(mav.MAV_CMD_REQUEST_MESSAGE, mav.MAVLINK_MSG_ID_HOME_POSITION)
    gcs.run(1.0)
    homes = gcs.of_type("HOME_POSITION")
    assert len(homes) == before + 1
    home = gcs.sim.autopilot.home
    assert (homes[-1].latitude, homes[-1].longitude) == (round(home.lat_deg * 1e7), round(home.lon_deg * 1e7))
    assert homes[-1].altitude == round(home.alt_m * 1000)


def test_home_position_is_sent_when_home_is_first_set_and_again_when_arming_resets_it():
    gcs = PipeGcs(Simulator(quick_scenario(), 0))
    gcs.run(0.5)
    assert gcs.of_type("HOME_POSITION") == []  # no fix, no home
    gcs.run(3.0)
    assert len(gcs.of_type("HOME_POSITION")) == 1
    gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    gcs.run(0.5)
    assert len(gcs.of_type("HOME_POSITION")) == 2


def test_system_time_is_scenario_epoch_plus_boot_time():
    gcs = PipeGcs(Simulator(quick_scenario(), 0))
    gcs.run(3.0)
    st = gcs.of_type("SYSTEM_TIME")[-1]
    assert st.time_unix_usec == 1_767_225_600_000_000 + st.time_boot_ms * 1000  # 2026-01-01T00:00Z
    assert st.time_boot_ms == pytest.approx(gcs.sim.time_s * 1000, abs=21)


def test_readiness_comes_up_in_gps_ekf_prearm_order():
    gcs = PipeGcs(Simulator(quick_scenario(), 0))

    def flags_at(t: float):
        gcs.run(t - gcs.sim.time_s)
        sys_status = gcs.of_type("SYS_STATUS")[-1]
        return (
            gcs.of_type("GPS_RAW_INT")[-1].fix_type >= 3,
            bool(gcs.of_type("EKF_STATUS_REPORT")[-1].flags & mav.EKF_POS_HORIZ_ABS),
            bool(sys_status.onboard_control_sensors_health & mav.MAV_SYS_STATUS_PREARM_CHECK),
            bool(sys_status.onboard_control_sensors_present & mav.MAV_SYS_STATUS_PREARM_CHECK),
        )

    assert flags_at(0.5) == (False, False, False, True)
    assert flags_at(1.6) == (True, False, False, True)
    assert flags_at(2.6) == (True, True, False, True)
    assert flags_at(3.6) == (True, True, True, True)
    assert gcs.of_type("EKF_STATUS_REPORT")[0].flags & mav.EKF_ATTITUDE  # attitude from the start


# 42.5 deg N on WGS84: metres per degree of latitude 111132.954 - 559.822 cos 2phi + 1.175 cos 4phi,
# of longitude 111412.84 cos phi - 93.5 cos 3phi + 0.118 cos 5phi.
_M_PER_DEG_LAT = 111_083.0
_M_PER_DEG_LON = 82_197.4


def test_global_and_local_position_report_a_hand_computed_point():
    gcs = airborne_gcs(15.0)
    # fly to 30 m east, 40 m north, 15 m above home and hold
    gcs.send(mav.MAVLink_set_position_target_local_ned_message(
        0, 1, 1, mav.MAV_FRAME_LOCAL_NED, 0b110111111000, 40.0, 30.0, -15.0, 0, 0, 0, 0, 0, 0, 0, 0))
    gcs.run(25.0)
    gpi = gcs.of_type("GLOBAL_POSITION_INT")[-1]
    assert gpi.lat == pytest.approx(FIELD["lat_deg"] * 1e7 + 40.0 / _M_PER_DEG_LAT * 1e7, abs=15)
    assert gpi.lon == pytest.approx(FIELD["lon_deg"] * 1e7 + 30.0 / _M_PER_DEG_LON * 1e7, abs=15)
    assert gpi.relative_alt == pytest.approx(15_000, abs=300)
    assert gpi.alt == pytest.approx(95_000, abs=300)  # 80 m field + 15 m
    lpn = gcs.of_type("LOCAL_POSITION_NED")[-1]
    assert (lpn.x, lpn.y, lpn.z) == (pytest.approx(40.0, abs=1.0), pytest.approx(30.0, abs=1.0),
                                     pytest.approx(-15.0, abs=0.3))
    vfr = gcs.of_type("VFR_HUD")[-1]
    assert vfr.alt == pytest.approx(95.0, abs=0.3)


def test_velocities_are_ned_in_cm_per_s_and_m_per_s():
    gcs = airborne_gcs(10.0)
    for _ in range(40):  # 2 m/s north, 1 m/s west, resent at 10 Hz
        gcs.send(mav.MAVLink_set_position_target_local_ned_message(
            0, 1, 1, mav.MAV_FRAME_LOCAL_NED, 0b110111000111, 0, 0, 0, 2.0, -1.0, 0.0, 0, 0, 0, 0, 0))
        gcs.run(0.1)
    gpi = gcs.of_type("GLOBAL_POSITION_INT")[-1]
    assert (gpi.vx, gpi.vy, gpi.vz) == (pytest.approx(200, abs=20), pytest.approx(-100, abs=20),
                                        pytest.approx(0, abs=20))
    lpn = gcs.of_type("LOCAL_POSITION_NED")[-1]
    assert (lpn.vx, lpn.vy) == (pytest.approx(2.0, abs=0.2), pytest.approx(-1.0, abs=0.2))
    gps = gcs.of_type("GPS_RAW_INT")[-1]
    assert gps.vel == pytest.approx(100 * math.hypot(2.0, 1.0), abs=20)
    assert gps.cog == pytest.approx(100 * math.degrees(math.atan2(-1.0, 2.0)) % 36000, abs=300)


def test_attitude_quaternion_is_scalar_first_frd_to_ned():
    gcs = airborne_gcs(10.0)
    gcs.command_ack(mav.MAV_CMD_SET_MESSAGE_INTERVAL, mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, 100_000)
    # hold position, face east (heading 90 deg)
    gcs.send(mav.MAVLink_set_position_target_local_ned_message(
        0, 1, 1, mav.MAV_FRAME_LOCAL_OFFSET_NED, 0b100111111000, 0, 0, 0, 0, 0, 0, 0, 0, 0, math.pi / 2, 0))
    gcs.run(8.0)
    att = gcs.of_type("ATTITUDE")[-1]
    assert att.yaw == pytest.approx(math.pi / 2, abs=0.03)
    q = gcs.of_type("ATTITUDE_QUATERNION")[-1]
    # a pure 90 deg rotation about NED down: (cos 45, 0, 0, sin 45), up to the small hover tilt
    assert (q.q1, q.q4) == (pytest.approx(math.sqrt(0.5), abs=0.02), pytest.approx(math.sqrt(0.5), abs=0.02))
    assert abs(q.q2) < 0.02 and abs(q.q3) < 0.02
    assert gcs.of_type("GLOBAL_POSITION_INT")[-1].hdg == pytest.approx(9000, abs=200)
    assert gcs.of_type("VFR_HUD")[-1].heading in (89, 90, 91)


def test_landed_state_and_battery_reports():
    gcs = ready_gcs()
    assert gcs.of_type("EXTENDED_SYS_STATE")[-1].landed_state == mav.MAV_LANDED_STATE_ON_GROUND
    gcs = airborne_gcs(8.0)
    assert gcs.of_type("EXTENDED_SYS_STATE")[-1].landed_state == mav.MAV_LANDED_STATE_IN_AIR
    sys_status, batt = gcs.of_type("SYS_STATUS")[-1], gcs.of_type("BATTERY_STATUS")[-1]
    truth = gcs.sim.autopilot.battery()
    assert sys_status.voltage_battery == pytest.approx(truth.voltage_v * 1000, abs=300)
    assert batt.voltages[0] == sys_status.voltage_battery  # both sent in the same step
    assert sys_status.current_battery > 1000  # > 10 A hovering an S1000-class octocopter
    assert 0 < batt.battery_remaining < 100 and batt.current_consumed > 0


@pytest.mark.parametrize("interval_us", [-2, 2**31, 1e30])
def test_set_message_interval_rejects_intervals_outside_int32_or_below_minus_one(interval_us):
    gcs = ready_gcs()
    ack, _ = gcs.command_ack(mav.MAV_CMD_SET_MESSAGE_INTERVAL, ATTITUDE, interval_us)
    assert ack.result == mav.MAV_RESULT_FAILED
    gcs.command_ack(mav.MAV_CMD_GET_MESSAGE_INTERVAL, ATTITUDE)
    gcs.run(0.1)
    assert gcs.of_type("MESSAGE_INTERVAL")[-1].interval_us == 250_000  # unchanged


def test_a_mode_change_sends_a_heartbeat_at_once_and_arming_does_not():
    # Copter::set_mode sends MSG_HEARTBEAT on every entered mode; arming sends none. ArduCopter
    # V4.8.0-dev SITL in our world (chase seed 1) acknowledged GUIDED at 3.18 s with a HEARTBEAT
    # custom_mode 4 in the same loop, between its 1 Hz ones at 2.98 s and 3.98 s; its armed flag
    # first came with the 3.98 s one, 0.7 s after the arming ACK.
    gcs = ready_gcs()
    regular = [t for t, m in gcs.log if m.get_type() == "HEARTBEAT"]
    gcs.run((regular[-1] + 0.3 - gcs.sim.time_s) % 1.0)  # to 0.3 s after a regular heartbeat
    t_cmd = gcs.sim.time_s
    assert gcs.set_mode(4).result == mav.MAV_RESULT_ACCEPTED
    gcs.run(0.05)
    beats = [(t, m) for t, m in gcs.log if t >= t_cmd and m.get_type() == "HEARTBEAT"]
    assert len(beats) == 1 and beats[0][1].custom_mode == 4
    assert beats[0][0] - t_cmd <= 0.05  # not the next 1 Hz one, 0.7 s away
    t_arm = gcs.sim.time_s
    assert gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)[0].result == mav.MAV_RESULT_ACCEPTED
    gcs.run(1.2)
    after_arm = [t for t, m in gcs.log if t >= t_arm and m.get_type() == "HEARTBEAT"]
    assert len(after_arm) == 1  # the regular one only
    assert (after_arm[0] - regular[-1]) == pytest.approx(round(after_arm[0] - regular[-1]), abs=0.03)  # same phase
