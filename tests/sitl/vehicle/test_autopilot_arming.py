"""Arming, pre-arm checks, boot readiness, auto-disarm and mode-change rules of the simulated ArduCopter."""

from __future__ import annotations

import pytest

from sitl.vehicle.autopilot import MAV_LANDED_STATE_ON_GROUND
from sitl.world.scenario import BootParams

GUIDED, RTL, LAND, BRAKE, LOITER, ALT_HOLD, STABILIZE = 4, 6, 9, 17, 5, 2, 0


def test_boot_brings_up_gps_then_ekf_then_prearm(make_ap, run_for):
    ap = make_ap(boot=BootParams())  # 5 / 25 / 40 s, as ArduCopter SITL
    seen = []

    def record(a):
        seen.append((a.time_s, a.gps_ok, a.ekf_ok, a.prearm_ok))

    run_for(ap, 45.0, each=record)
    first = {k: next(t for t, *flags in seen if flags[k]) for k in range(3)}
    assert first[0] == pytest.approx(5.0, abs=0.03)
    assert first[1] == pytest.approx(25.0, abs=0.03)
    assert first[2] == pytest.approx(40.0, abs=0.03)
    assert ap.gps().fix_type == 3


def test_arming_is_refused_without_a_3d_fix(make_ap):
    ap = make_ap(boot=BootParams())
    r = ap.request_arm(True)
    assert not r.accepted and r.text == "PreArm: Need 3D Fix"
    assert (2, "PreArm: Need 3D Fix") in ap.pop_statustexts()
    assert not ap.armed
    assert ap.gps().fix_type == 1


def test_arming_is_refused_until_the_ekf_has_a_position(make_ap, run_for):
    ap = make_ap(boot=BootParams())
    run_for(ap, 10.0)
    r = ap.request_arm(True)
    assert not r.accepted and r.text == "PreArm: Need Position Estimate"
    run_for(ap, 20.0)
    r = ap.request_arm(True)
    assert not r.accepted and r.text.startswith("PreArm:")
    run_for(ap, 11.0)
    assert ap.request_arm(True).accepted


def test_arming_is_refused_in_rtl_because_the_mode_is_not_armable(make_ap, run_for):
    ap = make_ap()
    run_for(ap, 4.0)
    assert ap.request_mode(RTL).accepted
    r = ap.request_arm(True)
    assert r == type(r)(False, "Arm: Mode not armable")
    for mode in (LAND, BRAKE):
        assert ap.request_mode(mode).accepted
        assert ap.request_arm(True).text == "Arm: Mode not armable"


@pytest.mark.parametrize("mode", [STABILIZE, ALT_HOLD, GUIDED, LOITER])
def test_arming_is_accepted_in_armable_modes_when_ready(make_ap, run_for, mode):
    ap = make_ap()
    run_for(ap, 4.0)
    assert ap.request_mode(mode).accepted
    r = ap.request_arm(True)
    assert r.accepted and ap.armed
    assert (6, "Arming motors") in ap.pop_statustexts()


def test_arming_resets_home_to_the_current_position(make_ap, run_for):
    ap = make_ap()
    run_for(ap, 4.0)
    assert ap.home is not None  # set at the first 3-D fix
    ap.phys.px, ap.phys.py = 30.0, -40.0  # the vehicle was carried elsewhere
    run_for(ap, 0.1)
    ap.request_mode(GUIDED)
    ap.request_arm(True)
    assert ap.home_enu[0] == pytest.approx(30.0, abs=0.5)
    assert ap.home_enu[1] == pytest.approx(-40.0, abs=0.5)


def test_force_arm_skips_the_prearm_checks(make_ap):
    ap = make_ap(boot=BootParams())
    assert ap.request_arm(True, force=True).accepted
    assert ap.armed


def test_arming_check_zero_skips_the_prearm_checks_but_not_the_mode_check(make_ap):
    ap = make_ap(params={"ARMING_CHECK": 0}, boot=BootParams())
    assert ap.request_mode(LAND).accepted
    assert ap.request_arm(True).text == "Arm: Mode not armable"
    assert ap.request_mode(STABILIZE).accepted
    assert ap.request_arm(True).accepted  # no fix, no EKF: nothing else is checked


def test_an_armed_vehicle_accepts_arm_again(make_ap, run_for):
    ap = make_ap()
    run_for(ap, 4.0)
    ap.request_mode(GUIDED)
    assert ap.request_arm(True).accepted
    assert ap.request_arm(True).accepted and ap.armed


def test_disarm_in_flight_is_refused_unless_forced(airborne):
    ap = airborne()
    assert not ap.request_arm(False).accepted
    assert ap.armed
    assert ap.request_arm(False, force=True).accepted
    assert not ap.armed


def test_auto_disarm_after_disarm_delay_on_the_ground(make_ap, run_for):
    ap = make_ap()
    run_for(ap, 4.0)
    ap.request_mode(GUIDED)
    ap.request_arm(True)
    ap.pop_statustexts()
    run_for(ap, 9.8)
    assert ap.armed
    run_for(ap, 0.4)
    assert not ap.armed
    assert ap.landed_state == MAV_LANDED_STATE_ON_GROUND
    assert (6, "Disarming motors") in ap.pop_statustexts()


def test_disarm_delay_zero_never_disarms(make_ap, run_for):
    ap = make_ap(params={"DISARM_DELAY": 0})
    run_for(ap, 4.0)
    ap.request_mode(GUIDED)
    ap.request_arm(True)
    run_for(ap, 30.0)
    assert ap.armed


def test_any_mode_is_accepted_while_disarmed_and_the_checks_come_at_arming(make_ap):
    # ArduCopter Copter::set_mode: ignore_checks = !motors->armed(), "we rely on the arming check";
    # the 4.7.0-dev SITL in ../shared/ardupilot accepted GUIDED (ACK 0) 3 s after boot, before
    # "EKF3 IMU0 is using GPS". (This test used to assert the refusal, which was the defect.)
    ap = make_ap(boot=BootParams())
    for mode, name in ((GUIDED, "GUIDED"), (LOITER, "LOITER"), (RTL, "RTL"), (BRAKE, "BRAKE")):
        r = ap.request_mode(mode)
        assert r.accepted and ap.mode == name
    assert ap.request_mode(GUIDED).accepted
    r = ap.request_arm(True)
    assert not r.accepted and r.text == "PreArm: Need 3D Fix"  # the arming checks refuse it instead
    assert not ap.armed and ap.mode == "GUIDED"


def test_without_arming_checks_a_position_mode_still_needs_a_position_to_arm(make_ap):
    # AP_Arming_Copter::mandatory_gps_checks: the mode requires GPS and there is no position estimate
    ap = make_ap(boot=BootParams(), params={"ARMING_CHECK": 0})
    assert ap.request_mode(LOITER).accepted
    r = ap.request_arm(True)
    assert not r.accepted and r.text == "PreArm: Need Position Estimate"


def test_modes_needing_a_position_are_refused_while_armed_without_one(make_ap):
    # armed (STABILIZE needs no position; ARMING_CHECK 0 skips the GPS checks), Copter::set_mode
    # refuses a position mode: "Mode change to GUIDED failed: requires position"
    ap = make_ap(boot=BootParams(), params={"ARMING_CHECK": 0})
    assert ap.request_arm(True).accepted
    for mode, name in ((GUIDED, "GUIDED"), (LOITER, "LOITER"), (RTL, "RTL"), (BRAKE, "BRAKE")):
        r = ap.request_mode(mode)
        assert not r.accepted
        assert r.text == f"Mode change to {name} failed: requires position"
    assert ap.mode == "STABILIZE"
    assert ap.request_mode(ALT_HOLD).accepted and ap.mode == "ALT_HOLD"
    assert ap.request_mode(LAND).accepted and ap.mode_number == LAND


def test_changing_to_the_current_mode_is_accepted(make_ap):
    ap = make_ap()
    assert ap.request_mode(STABILIZE).accepted


def test_an_unknown_mode_number_is_refused(make_ap):
    ap = make_ap()
    r = ap.request_mode(3)  # AUTO: not simulated
    assert not r.accepted and r.text == "No such mode 3"
    assert not ap.request_mode(99).accepted
