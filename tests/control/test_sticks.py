"""The ALT_HOLD stick mapping, inverted, against the simulator's forward mapping (ArduCopter's)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from chaser_bt.control.sticks import StickMap
from sitl.vehicle.modes import norm_input_dz, pilot_climb_rate

SM = StickMap()


def test_design_example_pitch_1300_is_about_minus_11_deg():
    assert SM.lean_pwm(0.0, math.radians(-11.25)) == (1500, 1300)


@given(st.floats(-30.0, 30.0))
def test_lean_round_trips_through_arducopter_mapping(deg):
    roll_pwm, pitch_pwm = SM.lean_pwm(math.radians(deg), 0.0)
    back = norm_input_dz(roll_pwm, 20) * 30.0
    assert back == pytest.approx(deg, abs=30.0 / 480 + 1e-9)  # one PWM step
    assert pitch_pwm == 1500


def test_lean_is_limited_as_a_circle():
    r, p = SM.lean_pwm(math.radians(30), math.radians(-30))
    rn, pn = norm_input_dz(r, 20), norm_input_dz(p, 20)
    assert math.hypot(rn, pn) == pytest.approx(1.0, abs=0.01)


@given(st.floats(-2.5, 2.5).filter(lambda c: abs(c) >= 0.05))
def test_climb_round_trips(climb):
    pwm = SM.throttle_pwm(climb)
    assert pilot_climb_rate(pwm, 100, 2.5, 2.5) == pytest.approx(climb, abs=2.5 / 400 + 1e-9)


def test_small_climb_centres_the_throttle_and_limits_saturate():
    assert SM.throttle_pwm(0.01) == 1500
    assert SM.throttle_pwm(10.0) == 2000 and SM.throttle_pwm(-10.0) == 1000


def test_yaw_rate_counter_clockwise_is_yaw_stick_left():
    pwm = SM.yaw_pwm(math.radians(45.0))
    assert pwm < 1500
    assert -norm_input_dz(pwm, 20) * 202.5 == pytest.approx(45.0, abs=0.5)


def test_forward_acceleration_pitches_nose_down_and_right_rolls_right():
    s = SM.sticks(forward_accel=3.0, right_accel=2.0, climb_mps=1.0, yaw_rate_enu=0.0)
    assert s.pitch < 1500 and s.roll > 1500 and s.throttle > 1600 and s.yaw == 1500
    pitch = norm_input_dz(s.pitch, 20) * math.radians(30)
    assert math.tan(-pitch) * 9.80665 == pytest.approx(3.0, rel=0.02)


def test_from_params_uses_the_vehicle_parameters():
    sm = StickMap.from_params({"ANGLE_MAX": 4500, "PILOT_SPEED_UP": 500, "PILOT_SPEED_DN": 0, "PILOT_Y_RATE": 90})
    assert sm.angle_max_rad == pytest.approx(math.radians(45))
    assert sm.climb_up_max == sm.climb_down_max == 5.0
    assert sm.yaw_rate_max == pytest.approx(math.radians(90))


def test_from_params_reads_arducopter_4_7_names_in_their_si_units():
    # ArduCopter 4.7+ (checked in the 4.8.0-dev source: AC_AttitudeControl "ANGLE_MAX" under ATC_, in
    # degrees; ParametersG2 PILOT_SPD_UP/DN in m/s) answers the new names only.
    sm = StickMap.from_params({"ATC_ANGLE_MAX": 45.0, "PILOT_SPD_UP": 5.0, "PILOT_SPD_DN": 1.5})
    assert sm.angle_max_rad == pytest.approx(math.radians(45))
    assert (sm.climb_up_max, sm.climb_down_max) == (5.0, 1.5)
