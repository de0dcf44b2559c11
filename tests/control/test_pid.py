"""PID loop: hand-computed steps, saturation and anti-windup."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, strategies as st

from chaser_bt.control.pid import Pid, PidGains


def test_proportional_only_is_kp_times_error():
    assert Pid(PidGains(0.4)).update(2.5, 0.2) == pytest.approx(1.0)


def test_integral_accumulates_ki_error_dt():
    pid = Pid(PidGains(0.0, ki=0.5))
    for _ in range(4):
        out = pid.update(2.0, 0.25)
    assert out == pytest.approx(0.5 * 2.0 * 0.25 * 4)  # 1.0


def test_derivative_of_the_error_change_and_none_on_the_first_step():
    pid = Pid(PidGains(0.0, kd=0.2))
    assert pid.update(1.0, 0.5) == 0.0
    assert pid.update(3.0, 0.5) == pytest.approx(0.2 * (3.0 - 1.0) / 0.5)


def test_measured_error_rate_replaces_the_difference():
    pid = Pid(PidGains(0.0, kd=2.0))
    pid.update(1.0, 0.2)
    assert pid.update(5.0, 0.2, error_rate=-0.5) == pytest.approx(-1.0)


def test_varying_kd_and_feed_forward():
    pid = Pid(PidGains(1.0, kd=100.0))
    pid.update(0.0, 1.0)
    assert pid.update(1.0, 1.0, kd=0.5, feed_forward=0.25) == pytest.approx(1.0 + 0.5 + 0.25)


def test_saturated_output_does_not_wind_up_the_integral():
    gains = PidGains(1.0, ki=1.0, out_min=-1.0, out_max=1.0)
    pid = Pid(gains)
    for _ in range(100):
        assert pid.update(10.0, 0.1) == 1.0
    assert pid.integral == pytest.approx(0.0)  # never integrated while pushing into the limit
    # The moment the error reverses, the output follows it (a wound-up integral would hold it at +1).
    assert pid.update(-0.5, 0.1) == pytest.approx(-0.5 - 0.05)


def test_integral_clamped_to_i_limit():
    pid = Pid(PidGains(0.0, ki=1.0, i_limit=0.3))
    for _ in range(50):
        out = pid.update(1.0, 0.1)
    assert out == pytest.approx(0.3)


def test_reset_forgets_integral_and_derivative_history():
    pid = Pid(PidGains(0.0, ki=1.0, kd=1.0))
    pid.update(1.0, 1.0)
    pid.reset()
    assert pid.update(0.0, 1.0) == 0.0


@pytest.mark.parametrize("bad", [dict(kp=-1.0), dict(kp=1.0, ki=math.nan), dict(kp=1.0, out_min=1.0, out_max=1.0)])
def test_invalid_gains_are_rejected(bad):
    with pytest.raises(ValueError):
        PidGains(**bad)


def test_non_positive_dt_is_rejected():
    with pytest.raises(ValueError, match="dt"):
        Pid(PidGains(1.0)).update(1.0, 0.0)


@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=40), st.floats(0.01, 1.0))
def test_output_always_within_limits(errors, dt):
    pid = Pid(PidGains(0.7, 0.3, 0.1, out_min=-2.0, out_max=3.0, i_limit=1.0))
    for e in errors:
        out = pid.update(e, dt)
        assert -2.0 <= out <= 3.0
        assert abs(pid.integral) <= 1.0 + 1e-12
