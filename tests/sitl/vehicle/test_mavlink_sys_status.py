"""SYS_STATUS' sensor bits as a stock ground station reads them, against the real ArduCopter.

Reference: the 4.7.0-dev SITL in ``../shared/ardupilot`` (stock copter.parm), read with pymavlink:
ready to arm, disarmed, in GUIDED it sent present 1399979055, enabled 1382153263, health
1467087919; armed it added only LOGGING to "enabled"; FENCE_ENABLE 1 added GEOFENCE to "enabled";
FENCE_TYPE 0 removed GEOFENCE from "present" and kept it healthy; a few seconds after boot in
STABILIZE the altitude and position controllers were present but neither enabled nor healthy.
The simulator leaves out the bits of what it does not have (LOGGING: no onboard log, TERRAIN: no
terrain database, PROPULSION: no ESC telemetry), so the expected masks are the real ones less those.
"""

from __future__ import annotations

from mavlink_gcs import mav, ready_gcs

REAL_GUIDED_READY = (1399979055, 1382153263, 1467087919)  # present, enabled, health
NOT_SIMULATED = mav.MAV_SYS_STATUS_LOGGING | mav.MAV_SYS_STATUS_TERRAIN | mav.MAV_SYS_STATUS_SENSOR_PROPULSION
GEOFENCE = mav.MAV_SYS_STATUS_GEOFENCE
Z_XY = mav.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL | mav.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL


def _bits(gcs, seconds: float = 0.6) -> tuple[int, int, int]:
    since = gcs.sim.time_s
    gcs.run(seconds)
    m = gcs.of_type("SYS_STATUS", since)[-1]
    return m.onboard_control_sensors_present, m.onboard_control_sensors_enabled, m.onboard_control_sensors_health


def _expected(real: tuple[int, int, int]) -> tuple[int, int, int]:
    return tuple(v & ~NOT_SIMULATED for v in real)


def test_ready_in_guided_the_bits_are_the_real_arducopters():
    gcs = ready_gcs()
    assert gcs.set_mode(4).result == mav.MAV_RESULT_ACCEPTED
    assert _bits(gcs) == _expected(REAL_GUIDED_READY)


def test_the_default_fence_is_present_not_enabled_and_healthy_so_no_breach_is_reported():
    # MAVProxy's fence module says "fence breach" when GEOFENCE is present and not healthy
    present, enabled, health = _bits(ready_gcs())
    assert present & GEOFENCE and not enabled & GEOFENCE and health & GEOFENCE


def test_motor_outputs_rc_and_battery_are_present_enabled_and_healthy_while_disarmed():
    present, enabled, health = _bits(ready_gcs())
    for bit in (mav.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS, mav.MAV_SYS_STATUS_SENSOR_RC_RECEIVER,
                mav.MAV_SYS_STATUS_SENSOR_BATTERY, mav.MAV_SYS_STATUS_PREARM_CHECK):
        assert present & bit and enabled & bit and health & bit, bit


def test_in_stabilize_the_controllers_are_present_but_not_enabled_or_healthy():
    present, enabled, health = _bits(ready_gcs())
    assert present & Z_XY == Z_XY
    assert not enabled & Z_XY and not health & Z_XY


def test_alt_hold_enables_only_the_altitude_controller():
    gcs = ready_gcs()
    assert gcs.set_mode(2).result == mav.MAV_RESULT_ACCEPTED
    _, enabled, health = _bits(gcs)
    z = mav.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    assert enabled & Z_XY == z and health & Z_XY == z


def test_fence_enable_sets_the_enabled_bit_and_fence_type_0_removes_the_fence():
    gcs = ready_gcs(params={"FENCE_ENABLE": 1})
    assert gcs.set_mode(4).result == mav.MAV_RESULT_ACCEPTED
    p, e, h = _expected(REAL_GUIDED_READY)
    assert _bits(gcs) == (p, e | GEOFENCE, h)
    gcs = ready_gcs(params={"FENCE_TYPE": 0})
    assert gcs.set_mode(4).result == mav.MAV_RESULT_ACCEPTED
    assert _bits(gcs) == (p & ~GEOFENCE, e, h)


def test_report_only_fence_is_present_but_not_enabled():
    # AC_Fence::sys_status_enabled(): false for FENCE_ACTION 0 (report only)
    present, enabled, _ = _bits(ready_gcs(params={"FENCE_ENABLE": 1, "FENCE_ACTION": 0}))
    assert present & GEOFENCE and not enabled & GEOFENCE


def test_arming_checks_off_clears_the_prearm_enabled_bit():
    # GCS::update_sensor_status_flags: PREARM_CHECK enabled only when ARMING_CHECK is non-zero
    present, enabled, _ = _bits(ready_gcs(params={"ARMING_CHECK": 0}))
    assert present & mav.MAV_SYS_STATUS_PREARM_CHECK and not enabled & mav.MAV_SYS_STATUS_PREARM_CHECK


def test_a_breached_fence_clears_the_geofence_health_bit():
    # circle fence 15 m; the vehicle flown 30 m out: the fence fails, the vehicle is sent home
    gcs = ready_gcs(params={"FENCE_ENABLE": 1, "FENCE_RADIUS": 15, "FENCE_ACTION": 0})
    assert gcs.set_mode(4).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)[0].result == mav.MAV_RESULT_ACCEPTED
    assert gcs.command_ack(mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 5.0)[0].result == mav.MAV_RESULT_ACCEPTED
    gcs.run(6.0)
    _, _, health = _bits(gcs)
    assert health & GEOFENCE
    breached = None
    for _ in range(20):  # a 6 m/s velocity north, re-sent (GUIDED refuses a position outside the fence)
        gcs.send(mav.MAVLink_set_position_target_local_ned_message(
            0, 1, 1, mav.MAV_FRAME_LOCAL_NED, 0b110111000111, 0, 0, 0, 6.0, 0.0, 0.0, 0, 0, 0, 0, 0))
        breached = gcs.wait_for("SYS_STATUS", 1.0, lambda m: not m.onboard_control_sensors_health & GEOFENCE)
        if breached is not None:
            break
    assert breached is not None
    texts = [m.text for m in gcs.of_type("STATUSTEXT")]
    assert "Fence Breached" in texts
