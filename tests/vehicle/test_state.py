"""Telemetry -> VehicleState conversions, checked against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from chaser_bt.geo import GeoPoint, LocalFrame
from chaser_bt.vehicle.state import LandedState, VehicleState, update_state

from vehicle_fakes import READY_EKF, roundtrip

HOME = GeoPoint(42.5, -71.6, 80.0)
FRAME = LocalFrame(HOME)
# WGS84 radii of curvature at the home latitude, by hand (no pymap3d): meridian M and prime vertical N.
_A, _F = 6378137.0, 1 / 298.257223563
_E2 = _F * (2 - _F)
_S2 = math.sin(math.radians(HOME.lat_deg)) ** 2
M = _A * (1 - _E2) / (1 - _E2 * _S2) ** 1.5
N = _A / math.sqrt(1 - _E2 * _S2)


def _gpi(lat_e7: int, lon_e7: int, alt_mm: int, rel_mm: int = 0, vx=0, vy=0, vz=0, t_ms=1234):
    return roundtrip(mavlink2.MAVLink_global_position_int_message(t_ms, lat_e7, lon_e7, alt_mm, rel_mm, vx, vy, vz, 0))


def test_global_position_100m_north_20m_up_maps_to_enu():
    lat_e7 = round((HOME.lat_deg + math.degrees(100.0 / M)) * 1e7)
    s = VehicleState()
    update_state(s, _gpi(lat_e7, round(HOME.lon_deg * 1e7), 100_000, 20_000), FRAME)
    north = M * math.radians(lat_e7 * 1e-7 - HOME.lat_deg)  # the quantised latitude, by hand
    assert north == pytest.approx(100.0, abs=0.01)
    assert s.position_enu == pytest.approx([0.0, north, 20.0], abs=0.003)
    assert s.alt_amsl_m == pytest.approx(100.0) and s.alt_rel_m == pytest.approx(20.0)
    assert s.t_boot_s == pytest.approx(1.234)


def test_global_position_50m_east_maps_to_enu():
    lon_e7 = round((HOME.lon_deg + math.degrees(50.0 / (N * math.cos(math.radians(HOME.lat_deg))))) * 1e7)
    s = VehicleState()
    update_state(s, _gpi(round(HOME.lat_deg * 1e7), lon_e7, 80_000), FRAME)
    east = N * math.cos(math.radians(HOME.lat_deg)) * math.radians(lon_e7 * 1e-7 - HOME.lon_deg)
    assert s.position_enu == pytest.approx([east, 0.0, 0.0], abs=0.003)


def test_position_stays_unknown_without_a_frame():
    s = VehicleState()
    update_state(s, _gpi(425000000, -716000000, 80_000), None)
    assert np.isnan(s.position_enu).all()
    assert s.lat_deg == pytest.approx(42.5)


def test_ned_velocity_in_cm_per_s_becomes_enu_m_per_s():
    s = VehicleState()
    # 1 m/s north, 2 m/s west, climbing at 0.5 m/s (NED down negative)
    update_state(s, _gpi(425000000, -716000000, 80_000, vx=100, vy=-200, vz=-50), FRAME)
    assert s.velocity_enu == pytest.approx([-2.0, 1.0, 0.5])


def test_attitude_yaw_east_is_enu_yaw_zero():
    s = VehicleState()
    update_state(s, roundtrip(mavlink2.MAVLink_attitude_message(10, 0.0, 0.0, math.pi / 2, 0, 0, 0)), None)
    assert s.yaw_enu_rad == pytest.approx(0.0, abs=1e-6)
    assert s.heading_deg == pytest.approx(90.0, abs=1e-4)
    assert s.attitude.apply([1.0, 0.0, 0.0]) == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)  # nose points east


def _left_wing_after_right_roll_heading_north() -> list[float]:
    # Heading north, rolled 30 deg right wing down: the left wing (FLU +y) points west and up.
    return [-math.cos(math.radians(30)), 0.0, math.sin(math.radians(30))]


def test_attitude_roll_right_lifts_left_wing():
    s = VehicleState()
    update_state(s, roundtrip(mavlink2.MAVLink_attitude_message(10, math.radians(30), 0.0, 0.0, 0, 0, 0)), None)
    assert s.attitude.apply([0.0, 1.0, 0.0]) == pytest.approx(_left_wing_after_right_roll_heading_north(), abs=1e-6)
    assert s.yaw_enu_rad == pytest.approx(math.pi / 2)


def test_attitude_quaternion_is_read_scalar_first():
    s = VehicleState()
    c, h = math.cos(math.pi / 4), math.sin(math.pi / 4)  # 90 deg about NED down: heading east
    update_state(s, roundtrip(mavlink2.MAVLink_attitude_quaternion_message(10, c, 0, 0, h, 0, 0, 0, [0, 0, 0, 0])), None)
    assert s.yaw_enu_rad == pytest.approx(0.0, abs=1e-6)
    c, h = math.cos(math.radians(15)), math.sin(math.radians(15))  # 30 deg roll about FRD x
    update_state(s, roundtrip(mavlink2.MAVLink_attitude_quaternion_message(10, c, h, 0, 0, 0, 0, 0, [0, 0, 0, 0])), None)
    assert s.attitude.apply([0.0, 1.0, 0.0]) == pytest.approx(_left_wing_after_right_roll_heading_north(), abs=1e-6)


def test_sys_status_gives_prearm_flag_and_battery_in_si():
    s = VehicleState()
    msg = mavlink2.MAVLink_sys_status_message(0, 0, mavlink2.MAV_SYS_STATUS_PREARM_CHECK, 0, 22150, 0, 64, 0, 0, 0, 0, 0, 0)
    update_state(s, roundtrip(msg), None)
    assert s.prearm_ok and s.battery_voltage_v == pytest.approx(22.15) and s.battery_remaining_pct == 64
    msg = mavlink2.MAVLink_sys_status_message(0, 0, 0, 0, 65535, 0, -1, 0, 0, 0, 0, 0, 0)
    update_state(s, roundtrip(msg), None)
    assert not s.prearm_ok and math.isnan(s.battery_voltage_v) and math.isnan(s.battery_remaining_pct)


@pytest.mark.parametrize(("enabled", "health", "on", "breached"), [
    (0, 0, False, False),  # FENCE_ENABLE 0: not enabled, nothing breached
    (1, 1, True, False),  # on and healthy
    (1, 0, True, True),  # on and breached (AC_Fence clears the health bit)
])
def test_sys_status_geofence_bits_give_the_fence_state(enabled, health, on, breached):
    fence = mavlink2.MAV_SYS_STATUS_GEOFENCE
    s = VehicleState()
    update_state(s, roundtrip(mavlink2.MAVLink_sys_status_message(fence, enabled * fence, health * fence, 0, 22150, 0, 64,
                                                                  0, 0, 0, 0, 0, 0)), None)
    assert (s.fence_enabled, s.fence_breached) == (on, breached)


def test_the_autopilots_battery_failsafe_from_charge_state_and_from_its_text():
    s = VehicleState()
    msg = mavlink2.MAVLink_battery_status_message(0, 0, 0, 0, [22150] + [65535] * 9, 100, 0, 0, 80)
    update_state(s, roundtrip(msg), None)
    assert not s.battery_failsafe and s.battery_remaining_pct == 80  # no charge state: OK
    msg.charge_state = mavlink2.MAV_BATTERY_CHARGE_STATE_LOW
    update_state(s, roundtrip(msg), None)
    assert s.battery_failsafe
    t = VehicleState()
    update_state(t, roundtrip(mavlink2.MAVLink_statustext_message(2, b"Battery 1 is low 19.48V used 337 mAh")), None)
    assert t.battery_failsafe
    update_state(t := VehicleState(), roundtrip(mavlink2.MAVLink_statustext_message(6, b"Battery 1 is fine")), None)
    assert not t.battery_failsafe


@pytest.mark.parametrize(
    ("flags", "ok"),
    [
        (READY_EKF, True),
        (mavlink2.EKF_ATTITUDE | mavlink2.EKF_VELOCITY_HORIZ, False),  # no absolute position
        (mavlink2.EKF_ATTITUDE | mavlink2.EKF_POS_HORIZ_ABS, False),  # no velocity
        (READY_EKF | mavlink2.EKF_CONST_POS_MODE, False),  # position is a constant placeholder
    ],
)
def test_ekf_ok_needs_attitude_velocity_and_absolute_position(flags, ok):
    s = VehicleState()
    update_state(s, roundtrip(mavlink2.MAVLink_ekf_status_report_message(flags, 0, 0, 0, 0, 0)), None)
    assert s.ekf_ok is ok


def test_ready_to_arm_needs_prearm_3d_fix_and_ekf():
    s = VehicleState(prearm_ok=True, gps_fix_type=3, ekf_ok=True)
    assert s.ready_to_arm
    for change in ({"prearm_ok": False}, {"gps_fix_type": 2}, {"ekf_ok": False}):
        assert not VehicleState(**{"prearm_ok": True, "gps_fix_type": 3, "ekf_ok": True, **change}).ready_to_arm


def test_airborne_uses_landed_state_and_falls_back_to_altitude():
    assert VehicleState(armed=True, landed_state=LandedState.IN_AIR).airborne
    assert VehicleState(armed=True, landed_state=LandedState.TAKEOFF, alt_rel_m=0.0).airborne
    assert not VehicleState(armed=True, landed_state=LandedState.ON_GROUND, alt_rel_m=3.0).airborne
    assert not VehicleState(armed=False, landed_state=LandedState.IN_AIR).airborne
    assert VehicleState(armed=True, alt_rel_m=0.8).airborne
    assert not VehicleState(armed=True, alt_rel_m=0.2).airborne


def test_extended_sys_state_sets_landed_state():
    s = VehicleState()
    update_state(s, roundtrip(mavlink2.MAVLink_extended_sys_state_message(0, mavlink2.MAV_LANDED_STATE_LANDING)), None)
    assert s.landed_state is LandedState.LANDING


def test_heartbeat_gives_mode_name_and_armed_flag():
    s = VehicleState()
    base = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
    update_state(s, roundtrip(mavlink2.MAVLink_heartbeat_message(2, 3, base, 4, 4, 3)), None)
    assert (s.mode, s.armed) == ("GUIDED", True)
    update_state(s, roundtrip(mavlink2.MAVLink_heartbeat_message(2, 3, 1, 17, 3, 3)), None)
    assert (s.mode, s.armed) == ("BRAKE", False)


def test_rc_channels_keeps_the_reported_channel_count():
    s = VehicleState()
    chans = [1000 + i for i in range(18)]
    update_state(s, roundtrip(mavlink2.MAVLink_rc_channels_message(5, 8, *chans, 255)), None)
    assert s.rc_channels == tuple(chans[:8])


def test_home_position_in_e7_and_mm():
    s = VehicleState()
    msg = mavlink2.MAVLink_home_position_message(425000123, -716000456, 81234, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0)
    update_state(s, roundtrip(msg), None)
    assert (s.home.lat_deg, s.home.lon_deg, s.home.alt_m) == pytest.approx((42.5000123, -71.6000456, 81.234), abs=1e-9)


def test_statustext_is_kept_with_vehicle_time_and_bounded():
    s = VehicleState(t_boot_s=12.5)
    for i in range(60):
        update_state(s, roundtrip(mavlink2.MAVLink_statustext_message(2, f"PreArm: check {i}".encode(), 0, 0)), None)
    assert len(s.statustexts) == 50
    assert s.statustexts[-1] == (12.5, 2, "PreArm: check 59")
