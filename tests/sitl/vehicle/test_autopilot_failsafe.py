"""Failsafes, RC overrides and scripted faults of the simulated ArduCopter."""

from __future__ import annotations

import numpy as np
import pytest

from sitl.vehicle.autopilot import MAV_LANDED_STATE_ON_GROUND
from sitl.world.scenario import Fault

GUIDED, RTL, LAND, ALT_HOLD, LOITER = 4, 6, 9, 2, 5
KEEP = 65535


def _heartbeat_every_second(ap) -> None:
    if round(ap.time_s * 50) % 50 == 0:
        ap.gcs_heartbeat()


def test_gcs_failsafe_switches_to_rtl_after_fs_gcs_timeout(airborne, run_for):
    ap = airborne()
    ap.gcs_heartbeat()
    t0 = ap.time_s
    switched = []
    run_for(ap, 5.5, each=lambda a: switched.append(a.time_s) if a.mode == "RTL" else None)
    assert ap.mode == "RTL" and ap.fs_gcs
    # first step on which more than FS_GCS_TIMEOUT (5 s) of silence has passed
    assert switched[0] - t0 == pytest.approx(5.0, abs=0.03)
    assert (4, "GCS Failsafe") in ap.pop_statustexts()
    run_for(ap, 90.0)
    assert not ap.armed and ap.landed_state == MAV_LANDED_STATE_ON_GROUND


def test_no_gcs_failsafe_before_any_gcs_heartbeat(airborne, run_for):
    ap = airborne()
    run_for(ap, 20.0)
    assert ap.mode == "GUIDED" and not ap.fs_gcs


def test_regular_heartbeats_keep_the_gcs_failsafe_away_and_recovery_clears_it(airborne, run_for):
    ap = airborne()
    run_for(ap, 20.0, each=_heartbeat_every_second)
    assert ap.mode == "GUIDED"
    run_for(ap, 6.0)
    assert ap.fs_gcs
    ap.gcs_heartbeat()
    assert not ap.fs_gcs
    assert (4, "GCS Failsafe Cleared") in ap.pop_statustexts()
    assert ap.mode == "RTL"  # the failsafe's mode stays, as in ArduCopter


def test_gcs_failsafe_land_option(airborne, run_for):
    ap = airborne(params={"FS_GCS_ENABLE": 5})
    ap.gcs_heartbeat()
    run_for(ap, 6.0)
    assert ap.mode == "LAND"


def test_gcs_failsafe_disabled_does_nothing(airborne, run_for):
    ap = airborne(params={"FS_GCS_ENABLE": 0})
    ap.gcs_heartbeat()
    run_for(ap, 10.0)
    assert ap.mode == "GUIDED"


def test_gcs_failsafe_on_the_ground_disarms(make_ap, run_for):
    ap = make_ap(params={"DISARM_DELAY": 0})
    run_for(ap, 4.0)
    ap.gcs_heartbeat()
    ap.request_mode(GUIDED)
    ap.request_arm(True)
    run_for(ap, 5.5)
    assert not ap.armed


def test_rc_override_expires_after_rc_override_time(airborne, run_for):
    ap = airborne()
    ap.rc_override([1400, 1600, 1500, 1550, KEEP, KEEP, KEEP, KEEP])
    assert ap.rc_channels()[:4] == (1400, 1600, 1500, 1550)
    run_for(ap, 2.9)
    assert ap.rc_channels()[:4] == (1400, 1600, 1500, 1550)
    run_for(ap, 0.2)
    assert ap.rc_channels()[:4] == (1500, 1500, 1000, 1500)  # back to the idle transmitter


def test_rc_override_zero_releases_and_65535_leaves_a_channel_alone(make_ap):
    ap = make_ap()
    ap.rc_override([1400, 1600, 1700, 1800, 1900, KEEP, KEEP, KEEP])
    ap.rc_override([0, KEEP, KEEP, KEEP, KEEP, KEEP, KEEP, KEEP])
    rc = ap.rc_channels()
    assert rc[0] == 1500 and rc[1:5] == (1600, 1700, 1800, 1900)
    assert len(rc) == 16
    # channels 9-18: 0 and 65535 leave alone, 65534 releases
    ap.rc_override([KEEP] * 8 + [1234, 0, KEEP])
    assert ap.rc_channels()[8:11] == (1234, 1500, 1500)
    ap.rc_override([KEEP] * 8 + [0])
    assert ap.rc_channels()[8] == 1234
    ap.rc_override([KEEP] * 8 + [65534])
    assert ap.rc_channels()[8] == 1500


def test_rc_override_time_minus_one_never_expires(make_ap, run_for):
    ap = make_ap(params={"RC_OVERRIDE_TIME": -1})
    ap.rc_override([1400])
    run_for(ap, 30.0)
    assert ap.rc_channels()[0] == 1400


def test_alt_hold_throttle_override_lapse_makes_the_copter_sink(airborne, run_for):
    ap = airborne()
    ap.rc_override([1500, 1500, 1500, 1500])
    ap.request_mode(ALT_HOLD)
    run_for(ap, 2.0)
    assert abs(ap.truth.vel_enu[2]) < 0.2
    run_for(ap, 3.0)  # override expired: throttle stick back at 1000
    assert ap.truth.vel_enu[2] < -1.5


def test_gps_loss_in_guided_triggers_the_ekf_failsafe_and_lands(make_ap, run_for):
    ap = make_ap(faults=(Fault(at_s=30.0, kind="gps_loss"),))
    run_for(ap, 4.0)
    ap.request_mode(GUIDED)
    ap.request_arm(True)
    ap.request_takeoff(15.0)
    run_for(ap, 25.5)
    assert ap.gps().fix_type == 3 and ap.mode == "GUIDED"
    run_for(ap, 0.6)  # t = 30.1: no fix; the EKF dead-reckons for a second
    assert ap.gps().fix_type == 1 and not ap.gps_ok
    assert ap.ekf_ok and ap.mode == "GUIDED"
    frozen = ap.position_estimate().pos_enu[:2]
    run_for(ap, 1.0)
    assert not ap.ekf_ok and ap.fs_ekf and ap.mode == "LAND"
    assert ap.pop_statustexts()[-2:] == [(2, "EKF variance: position lost"), (2, "EKF Failsafe: changed to Land Mode")]
    assert np.array_equal(ap.position_estimate().pos_enu[:2], frozen)
    assert not ap.request_mode(LOITER).accepted
    run_for(ap, 60.0)
    assert not ap.armed and not ap.truth.crashed


def test_gps_loss_in_alt_hold_keeps_flying(airborne, run_for):
    ap = airborne(faults=(Fault(at_s=30.0, kind="gps_loss", duration_s=10.0),))
    ap.rc_override([1500, 1500, 1500, 1500])
    ap.request_mode(ALT_HOLD)
    run_for(ap, 12.0, each=lambda a: a.rc_override([1500, 1500, 1500, 1500]))
    assert ap.mode == "ALT_HOLD" and ap.fs_ekf
    run_for(ap, 10.0, each=lambda a: a.rc_override([1500, 1500, 1500, 1500]))
    assert ap.ekf_ok and not ap.fs_ekf and ap.gps().fix_type == 3
    assert (2, "EKF Failsafe Cleared") in ap.pop_statustexts()


def test_battery_drop_triggers_the_low_voltage_failsafe_rtl(airborne, run_for):
    ap = airborne(faults=(Fault(at_s=30.0, kind="battery_drop"),))
    run_for(ap, 29.9 - ap.time_s)
    v_before = ap.battery().voltage_v
    run_for(ap, 9.5)  # t ~ 39.4: below BATT_LOW_VOLT (21 V) for 9.4 s
    assert ap.mode == "GUIDED"
    assert ap.battery().voltage_v == pytest.approx(v_before * 5 / 6, rel=0.02)
    run_for(ap, 1.0)  # BATT_LOW_TIMER 10 s passed
    assert ap.fs_battery and ap.mode == "RTL"
    texts = [t for _, t in ap.pop_statustexts()]
    assert any(t.startswith("Battery 1 is low") for t in texts)


def test_battery_remaining_follows_batt_capacity(airborne, run_for):
    ap = airborne(params={"BATT_CAPACITY": 5000})
    b = ap.battery()
    assert b.remaining_pct == pytest.approx(100.0 * (1.0 - b.consumed_mah / 5000.0))
    assert b.current_a == pytest.approx(39.0, abs=2.0)
