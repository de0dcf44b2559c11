"""The motor-level quad: torque signs from ArduPilot's QUAD "+" motor matrix, thrust curve, ground, fall."""

from __future__ import annotations

import numpy as np
import pytest

from sitl.vehicle.airframe import GRAVITY
from sitl.vehicle.json_backend import ServoPacket
from sitl.vehicle.rotor_body import QuadParams, QuadRotorBody

DT = 1.0 / 800


def _aloft() -> QuadRotorBody:
    return QuadRotorBody(position_ned=np.array([0.0, 0.0, -20.0]))


def _run(body: QuadRotorBody, pwm, seconds: float) -> np.ndarray:
    accel = None
    for _ in range(round(seconds / DT)):
        accel = body.step(pwm, DT)
    return accel


def test_the_thrust_curve_is_mot_thst_expo_at_half_throttle():
    body = _aloft()
    _run(body, (1500,) * 4, 0.3)  # 15 motor time constants: settled
    # Hand-worked: 15 N * (0.35 * 0.5 + 0.65 * 0.25) = 5.0625 N per motor.
    np.testing.assert_allclose(body.thrust_n, 5.0625, rtol=1e-4)


@pytest.mark.parametrize("pwm, axis, sign", [
    ((1600, 1400, 1500, 1500), 0, -1),  # motor 1 (right) up: right side rises, negative roll
    ((1400, 1600, 1500, 1500), 0, +1),  # motor 2 (left) up: positive roll
    ((1500, 1500, 1600, 1400), 1, +1),  # motor 3 (front) up: nose up, positive pitch
    ((1600, 1600, 1400, 1400), 2, +1),  # counter-clockwise props (1, 2) up: the body yaws clockwise, positive
])
def test_motor_differences_turn_the_body_as_arducopters_motor_matrix_says(pwm, axis, sign):
    body = _aloft()
    _run(body, pwm, 0.1)
    rates = body.rates_frd
    assert np.sign(rates[axis]) == sign and abs(rates[axis]) > 0.1
    # The other axes barely move (the thrust curve's bend makes a little yaw from a roll pair).
    assert np.all(np.abs(np.delete(rates, axis)) < 0.01 * abs(rates[axis]))


def test_resting_on_the_ground_with_idle_motors_it_feels_one_g_up():
    body = QuadRotorBody()
    accel = _run(body, (1100,) * 4, 1.0)
    np.testing.assert_allclose(accel, (0.0, 0.0, -GRAVITY))
    assert np.all(body.position_ned == 0.0) and np.all(body.velocity_ned == 0.0)


def test_with_the_motors_off_it_falls_and_the_accelerometer_reads_almost_nothing():
    body = QuadRotorBody(params=QuadParams(drag_per_mps=0.0))
    body.position_ned[2] = -100.0
    accel = _run(body, (1000,) * 4, 1.0)
    assert body.velocity_ned[2] == pytest.approx(GRAVITY * 1.0, rel=1e-3)  # v = g t
    assert body.position_ned[2] == pytest.approx(-100.0 + GRAVITY / 2, abs=0.02)  # z = g t^2 / 2
    np.testing.assert_allclose(accel, 0.0, atol=1e-9)


def test_the_json_callable_reports_the_state_after_the_step():
    body = _aloft()
    frame = body.physics(ServoPacket(800, 0, (1500,) * 16), 0.00125)
    assert frame.timestamp_s == 0.00125 and frame.position_ned[2] < -19.99
    assert frame.attitude_rpy == pytest.approx((0.0, 0.0, 0.0))
