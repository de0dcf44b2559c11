"""The multicopter physics against hand-computed answers: lags, hover, drag balance, battery."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl.vehicle.airframe import GRAVITY, AirframeParams, lipo_cell_ocv
from sitl.vehicle.physics import MulticopterPhysics, NormalStream, Wind, WindParams

DT = 0.02


def _airborne(airframe: AirframeParams | None = None, wind: WindParams | None = None,
              seed: int = 0) -> MulticopterPhysics:
    a = airframe or AirframeParams()
    ph = MulticopterPhysics(a, Wind(wind or WindParams(), NormalStream(np.random.default_rng(seed))))
    ph.pz = 100.0
    ph.on_ground = False
    ph.motors_on = True
    ph.thrust = ph.thrust_cmd = a.hover_thrust_n
    return ph


def test_hover_thrust_is_the_weight_of_the_s1000_default():
    a = AirframeParams()
    assert a.hover_thrust_n == pytest.approx(8.0 * 9.80665)  # 78.45 N
    assert a.max_thrust_n == pytest.approx(2.0 * 78.4532)
    assert a.hover_throttle == pytest.approx(0.5)


def test_hover_thrust_holds_altitude_exactly():
    ph = _airborne()
    for _ in range(500):
        ph.step(DT)
    assert ph.pz == pytest.approx(100.0, abs=1e-9)
    assert ph.vz == pytest.approx(0.0, abs=1e-9)


def test_pitch_step_follows_the_first_order_lag():
    a = AirframeParams(attitude_tau_s=0.15)
    ph = _airborne(a)
    step = math.radians(-10.0)
    ph.pitch_cmd = step
    for k in range(1, 40):
        ph.step(DT)
        expected = step * (1.0 - math.exp(-k * DT / 0.15))
        assert ph.pitch == pytest.approx(expected, rel=1e-9)
    # one time constant after the step: 63.2 % of the way
    ph2 = _airborne(a)
    ph2.pitch_cmd = step
    for _ in range(round(0.15 / 0.01)):
        ph2.step(0.01)
    assert ph2.pitch == pytest.approx(step * 0.6321, rel=1e-3)


def test_thrust_above_weight_accelerates_up_at_the_hand_computed_rate():
    ph = _airborne()
    ph.thrust = ph.thrust_cmd = 1.5 * ph.airframe.hover_thrust_n
    ph.step(DT)
    # a = 0.5 g, no drag at rest: v = a dt after one semi-implicit Euler step
    assert ph.vz == pytest.approx(0.5 * GRAVITY * DT, rel=1e-9)


def test_terminal_speed_at_fixed_lean_matches_the_drag_balance():
    a = AirframeParams()
    ph = _airborne(a)
    lean = math.radians(20.0)
    ph.pitch = ph.pitch_cmd = -lean  # nose down, heading north
    ph.thrust = ph.thrust_cmd = a.hover_thrust_n / math.cos(lean)
    for _ in range(int(60 / DT)):
        ph.step(DT)
    # m g tan(20) = 28.555 N = 0.3 v + 0.12 v^2  ->  v = 14.227 m/s
    assert ph.vy == pytest.approx(14.227, abs=0.01)
    assert ph.vx == pytest.approx(0.0, abs=1e-9)
    assert ph.vz == pytest.approx(0.0, abs=1e-6)


def test_a_drifting_copter_takes_up_the_mean_wind():
    wind = WindParams(speed_mps=3.0, direction_deg=270.0)  # from the west: blows east
    assert wind.mean_enu() == pytest.approx((3.0, 0.0), abs=1e-12)
    ph = _airborne(wind=wind)
    # near zero air speed the linear term rules: time constant m / 0.3 = 27 s
    for _ in range(int(400 / DT)):
        ph.step(DT)
    assert ph.vx == pytest.approx(3.0, abs=0.01)
    assert ph.vy == pytest.approx(0.0, abs=1e-6)


def test_gusts_have_the_configured_spread_and_are_seeded():
    params = WindParams(gust_std_mps=1.0, gust_tau_s=1.0)
    samples = []
    w = Wind(params, NormalStream(np.random.default_rng(3)))
    for _ in range(50_000):
        samples.append(w.step(DT)[0])
    assert np.std(samples) == pytest.approx(1.0, rel=0.1)
    w2 = Wind(params, NormalStream(np.random.default_rng(3)))
    assert [w2.step(DT)[0] for _ in range(100)] == samples[:100]


def test_battery_drains_at_the_hover_current():
    ph = _airborne()
    for _ in range(int(60 / DT)):
        ph.step(DT)
    # (38 A hover + 1 A avionics) * 60 s = 2340 As = 650 mAh
    assert ph.battery.consumed_mah == pytest.approx(650.0, rel=1e-6)
    assert ph.battery.current_a == pytest.approx(39.0, rel=1e-9)
    # full hover endurance about 15 minutes
    assert AirframeParams().battery_capacity_mah / 39.0 * 3.6 / 60 == pytest.approx(15.4, abs=0.1)


def test_battery_voltage_sags_with_load_and_charge():
    ph = _airborne()
    ph.step(DT)
    b = ph.battery
    soc = 1.0 - b.consumed_mah / 10000.0
    assert b.voltage_v == pytest.approx(6 * lipo_cell_ocv(soc) - 39.0 * 0.04, rel=1e-9)
    assert b.voltage_v == pytest.approx(25.2 - 1.56, abs=0.01)
    assert lipo_cell_ocv(0.5) == pytest.approx(3.84)
    assert lipo_cell_ocv(0.15) == pytest.approx((3.65 + 3.72) / 2)


def test_ground_stops_the_fall_and_a_hard_impact_is_a_crash():
    ph = _airborne()
    ph.pz = 10.0
    ph.motors_on = False
    for _ in range(int(5 / DT)):
        ph.step(DT)
    assert ph.pz == 0.0 and ph.on_ground and ph.crashed


def test_idle_rotors_rest_on_the_ground_without_drifting_in_wind():
    a = AirframeParams()
    ph = MulticopterPhysics(a, Wind(WindParams(speed_mps=8.0), NormalStream(np.random.default_rng(0))))
    ph.motors_on = True
    ph.thrust_cmd = 0.0  # clipped to idle
    for _ in range(int(10 / DT)):
        ph.step(DT)
    assert ph.on_ground and not ph.crashed
    assert (ph.px, ph.py, ph.pz) == (0.0, 0.0, 0.0)
    assert ph.thrust == pytest.approx(a.idle_thrust_n, rel=1e-6)


def test_airframe_rejects_an_impossible_thrust_ratio():
    with pytest.raises(ValueError, match="max_thrust_ratio"):
        AirframeParams(max_thrust_ratio=0.9)
