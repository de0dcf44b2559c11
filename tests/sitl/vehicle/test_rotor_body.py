"""The motor-level multirotor against answers worked out by hand: ArduPilot's motor layouts turned into
torques, the hover throttle from mass and thrust curve, free fall, wind drift, the ground, a crash."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sitl.vehicle.airframe import GRAVITY
from sitl.vehicle.json_backend import ServoPacket
from sitl.vehicle.rotor_body import AIRFRAMES, FRAMES, RotorBody, rotor_airframe, rotor_frame

DT = 1.0 / 400
FULL, OFF = 2000, 1000

# ArduPilot's motor diagrams (ardupilot.org "Connect ESCs and motors"), written out by hand: motor n's
# place as (forward, right) in arm lengths, its prop's turn seen from above.
S = math.sqrt(0.5)
C22, S22 = math.cos(math.radians(22.5)), math.sin(math.radians(22.5))
LAYOUTS = {
    "quad-plus": [((0, 1), "ccw"), ((0, -1), "ccw"), ((1, 0), "cw"), ((-1, 0), "cw")],
    "quad-x": [((S, S), "ccw"), ((-S, -S), "ccw"), ((S, -S), "cw"), ((-S, S), "cw")],
    "octa-plus": [((1, 0), "cw"), ((-1, 0), "cw"), ((S, S), "ccw"), ((-S, S), "ccw"), ((S, -S), "ccw"),
                  ((-S, -S), "ccw"), ((0, -1), "cw"), ((0, 1), "cw")],
    "octa-x": [((C22, S22), "cw"), ((-C22, -S22), "cw"), ((S22, C22), "ccw"), ((-C22, S22), "ccw"),
               ((C22, -S22), "ccw"), ((-S22, -C22), "ccw"), ((S22, -C22), "cw"), ((-S22, C22), "cw")],
}


def _aloft(params=AIRFRAMES["quad"], **state) -> RotorBody:
    return RotorBody(params, position_ned=(0.0, 0.0, -100.0), **state)


def _run(body: RotorBody, pwm, seconds: float) -> np.ndarray:
    accel = None
    for _ in range(round(seconds / DT)):
        accel = body.step(pwm, DT)
    return accel


def test_frames_are_ardupilots_motor_layouts_and_factors():
    for name, layout in LAYOUTS.items():
        f = rotor_frame(name)
        assert f.motors == len(layout)
        for i, ((fwd, right), turn) in enumerate(layout):
            # AP_MotorsMatrix: roll factor cos(angle + 90) = -right, pitch factor cos(angle) = forward.
            assert f.roll_factors[i] == pytest.approx(-right, abs=1e-12), (name, i + 1)
            assert f.pitch_factors[i] == pytest.approx(fwd, abs=1e-12), (name, i + 1)
            assert f.yaw_factors[i] == {"ccw": 1.0, "cw": -1.0}[turn], (name, i + 1)
    assert (FRAMES["octa-x"].frame_class, FRAMES["octa-x"].frame_type) == (3, 1)
    assert (FRAMES["quad-plus"].frame_class, FRAMES["quad-plus"].frame_type) == (1, 0)
    with pytest.raises(KeyError, match="octa-x"):
        rotor_frame("hexa-x")


@pytest.mark.parametrize("frame", list(LAYOUTS))
def test_one_motor_at_full_thrust_turns_the_body_as_its_arm_says(frame):
    params = dataclasses.replace(AIRFRAMES["quad"], frame=FRAMES[frame], motor_tau_s=1e-9)  # thrust at once
    ix, iy, iz = params.inertia_kgm2
    for i, ((fwd, right), turn) in enumerate(LAYOUTS[frame]):
        body = _aloft(params)
        pwm = [OFF] * params.frame.motors
        pwm[i] = FULL
        body.step(pwm, DT)  # from rest: rate after one step = torque / inertia * dt
        # Hand-worked: 9.43 N on a 0.25 m arm; thrust is up, so a motor on the right rolls the body
        # left (negative roll), one on the nose pitches it up; its prop's drag, 0.02 m x 9.43 N,
        # turns the body against the prop: a counter-clockwise prop yaws it clockwise (positive).
        roll_nm, pitch_nm = -right * 0.25 * 9.43, fwd * 0.25 * 9.43
        yaw_nm = (0.1886 if turn == "ccw" else -0.1886)
        np.testing.assert_allclose(body.rates_frd, (roll_nm / ix * DT, pitch_nm / iy * DT, yaw_nm / iz * DT),
                                   rtol=1e-9, atol=1e-12, err_msg=f"{frame} motor {i + 1}")
        assert body.thrust_n[i] == pytest.approx(9.43) and body.thrust_n.sum() == pytest.approx(9.43)


@pytest.mark.parametrize("frame", list(LAYOUTS))
def test_speeding_up_the_counter_clockwise_props_yaws_the_body_clockwise(frame):
    params = dataclasses.replace(AIRFRAMES["quad"], frame=FRAMES[frame])
    pwm = [1560 if turn == "ccw" else 1400 for _, turn in LAYOUTS[frame]]
    body = _aloft(params)
    _run(body, pwm, 0.2)
    p, q, r = body.rates_frd
    assert r > 0.1 and abs(p) < 1e-9 and abs(q) < 1e-9  # balanced layouts: no roll or pitch from yaw
    assert body.euler_ned()[2] > 0.0


def test_the_hover_throttle_follows_from_mass_and_thrust_curve():
    quad, s1000 = rotor_airframe("quad"), rotor_airframe("s1000")
    # Hand-worked: quad 1.5 kg x 9.80665 / (4 x 9.43 N) = 0.3900 of full thrust (ArduPilot's SITL quad's
    # MOT_THST_HOVER); 0.35 x + 0.65 x² = 0.3900 gives x = 0.5508 of the spin range 0.15..0.95, PWM
    # 1150 + 800 x = 1591 us.
    assert quad.hover_thrust_fraction == pytest.approx(0.38998, abs=1e-5)
    assert quad.hover_pwm_us == pytest.approx(1590.64, abs=0.01)
    assert quad.ardupilot_params()["MOT_THST_HOVER"] == 0.39
    # S1000 7.5 kg x 9.80665 / (8 x 22 N) = 0.4179; x = 0.5766; PWM 1611 us.
    assert s1000.hover_thrust_fraction == pytest.approx(0.41790, abs=1e-5)
    assert s1000.hover_pwm_us == pytest.approx(1611.27, abs=0.01)
    assert s1000.ardupilot_params()["MOT_THST_HOVER"] == 0.418
    for params in (quad, s1000):
        n = params.frame.motors
        for pwm, sign in ((params.hover_pwm_us, 0), (params.hover_pwm_us - 20, 1), (params.hover_pwm_us + 20, -1)):
            body = _aloft(params)
            _run(body, [pwm] * n, 1.0)  # the motors spin up (16 time constants of the S1000's)...
            body.velocity_ned = (0.0, 0.0, 0.0)  # ...while it sinks; then from still
            _run(body, [pwm] * n, 2.0)
            vz = body.velocity_ned[2]
            if sign == 0:
                assert abs(vz) < 1e-3 and body.thrust_n.sum() == pytest.approx(params.mass_kg * GRAVITY, rel=1e-6)
            else:
                assert np.sign(vz) == sign and abs(vz) > 0.5, (params.name, pwm)
            np.testing.assert_allclose(body.rates_frd, 0.0, atol=1e-9)  # equal motors: no torque


def test_with_the_motors_off_it_falls_and_the_accelerometer_reads_nothing():
    body = _aloft(dataclasses.replace(AIRFRAMES["s1000"], drag_lin=0.0, drag_quad=0.0))
    accel = _run(body, [OFF] * 8, 1.0)
    assert body.velocity_ned[2] == pytest.approx(GRAVITY * 1.0, rel=1e-9)  # v = g t
    assert body.position_ned[2] == pytest.approx(-100.0 + GRAVITY / 2, abs=GRAVITY * DT)  # z = g t² / 2
    np.testing.assert_allclose(accel, 0.0, atol=1e-12)
    assert not body.on_ground and not body.crashed


def test_in_wind_it_drifts_with_the_air_and_the_drag_it_feels_is_hand_worked():
    quad = dataclasses.replace(rotor_airframe("quad"), drag_lin=0.25, drag_quad=0.0)
    body = _aloft(quad, wind_ned=(3.0, -4.0, 0.0))
    hover = [quad.hover_pwm_us] * 4
    body.step(hover, DT)  # still air-relative speed 5 m/s: drag 0.25 N/(m/s) x (3, -4) / 1.5 kg
    accel = body.step(hover, DT)
    assert accel[0] == pytest.approx(0.5, rel=1e-3) and accel[1] == pytest.approx(-2 / 3, rel=1e-3)
    _run(body, hover, 60.0)  # ten drag time constants (1.5 kg / 0.25 N s/m = 6 s)
    np.testing.assert_allclose(body.velocity_ned[:2], (3.0, -4.0), atol=1e-3)  # terminal drift = the wind
    np.testing.assert_allclose(body.euler_ned()[:2], 0.0, atol=1e-9)
    body.wind_ned = (0.0, 0.0, 0.0)
    _run(body, hover, 60.0)
    np.testing.assert_allclose(body.velocity_ned[:2], 0.0, atol=1e-3)


def test_resting_on_the_ground_with_idling_motors_nothing_moves():
    body = RotorBody.named("s1000", attitude=Rotation.from_euler("z", 1.0))
    assert body.on_ground
    accel = _run(body, [1100] * 8, 60.0)  # MOT_SPIN_ARM's idle, for a minute
    np.testing.assert_array_equal(accel, (0.0, 0.0, -GRAVITY))
    np.testing.assert_array_equal(body.position_ned, 0.0)
    np.testing.assert_array_equal(body.velocity_ned, 0.0)
    np.testing.assert_array_equal(body.rates_frd, 0.0)
    assert body.euler_ned() == pytest.approx((0.0, 0.0, 1.0), abs=1e-12)
    assert body.on_ground and not body.crashed


def test_above_the_hover_throttle_it_lifts_off_and_below_it_settles_back_gently():
    body = RotorBody.named("quad")
    _run(body, [1700] * 4, 0.5)
    assert not body.on_ground and body.position_ned[2] < -0.1
    _run(body, [body.params.hover_pwm_us - 40] * 4, 10.0)
    assert body.on_ground and not body.crashed and body.position_ned[2] == 0.0


@pytest.mark.parametrize("height_m, crash", [(10.0, True), (0.3, False)])
def test_a_touchdown_faster_than_the_crash_speed_is_a_crash(height_m, crash):
    # Hand-worked: a fall from h hits at sqrt(2 g h): 14.0 m/s from 10 m, 2.4 m/s from 0.3 m (crash speed 3).
    params = dataclasses.replace(AIRFRAMES["s1000"], drag_lin=0.0, drag_quad=0.0)
    body = RotorBody(params, position_ned=(0.0, 0.0, -height_m))
    _run(body, [OFF] * 8, 2.0)
    assert body.on_ground and body.crashed is crash


def test_the_accelerometer_feels_the_ground_stop_the_touchdown():
    # Level, nose 1 rad east of north, motors off, no drag, 1 mm up and moving (1, 0.5, 0.8) m/s NED. In the
    # step gravity adds g dt to the sink, the body reaches the ground and the ground takes the velocity out:
    # the specific force is that push, (-1, -0.5, -(0.8 + g dt)) / dt in NED, turned into the body by the
    # yaw: x = -(cos 1 + 0.5 sin 1) 400, y = -(-sin 1 + 0.5 cos 1) 400, z = -320 - g. Over the step it
    # and gravity add up to the velocity it had: an estimator integrating the IMU sees the aircraft stop.
    params = dataclasses.replace(AIRFRAMES["s1000"], drag_lin=0.0, drag_quad=0.0)
    body = RotorBody(params, position_ned=(0.0, 0.0, -0.001), velocity_ned=(1.0, 0.5, 0.8),
                     attitude=Rotation.from_euler("z", 1.0))
    accel = body.step([OFF] * 8, DT)
    assert body.on_ground and not body.crashed
    c, s = math.cos(1.0), math.sin(1.0)
    np.testing.assert_allclose(accel, (-(c + 0.5 * s) * 400.0, -(-s + 0.5 * c) * 400.0, -320.0 - GRAVITY), rtol=1e-12)
    np.testing.assert_array_equal(body.velocity_ned, 0.0)
    np.testing.assert_array_equal(body.step([OFF] * 8, DT), (0.0, 0.0, -GRAVITY))  # then at rest: 1 g


def test_a_body_that_lands_tilted_tips_back_level_and_the_gyro_sees_it():
    # Touching down rolled 0.3 rad (leaning into a wind), motors off: the ground stops it, then tips it level
    # at SETTLE_RATE_RPS, 2 rad/s: 0.3 / (2 / 400) = 60 steps of p = -2 rad/s, the gyro's integral the roll
    # undone, and meanwhile the accelerometer reads the ground holding it up, gravity's reaction turned into
    # the rolled body: (0, -g sin roll, -g cos roll). Levelled unseen, ArduCopter's EKF kept the lean.
    params = dataclasses.replace(AIRFRAMES["s1000"], drag_lin=0.0, drag_quad=0.0)
    body = RotorBody(params, position_ned=(0.0, 0.0, -0.0005), velocity_ned=(0.0, 0.0, 0.5),
                     attitude=Rotation.from_euler("ZYX", (1.0, 0.0, 0.3)))
    body.step([OFF] * 8, DT)
    assert body.on_ground and body.euler_ned() == pytest.approx((0.3, 0.0, 1.0), abs=1e-12)
    accel = body.step([OFF] * 8, DT)
    np.testing.assert_allclose(accel, (0.0, -GRAVITY * math.sin(0.295), -GRAVITY * math.cos(0.295)), atol=1e-9)
    turned = body.rates_frd[0] * DT
    for _ in range(59):
        body.step([OFF] * 8, DT)
        assert body.rates_frd[0] == pytest.approx(-2.0) and body.rates_frd[1:] == pytest.approx((0.0, 0.0), abs=1e-9)
        turned += body.rates_frd[0] * DT
    assert turned == pytest.approx(-0.3, abs=1e-9)
    assert body.euler_ned() == pytest.approx((0.0, 0.0, 1.0), abs=1e-9)
    np.testing.assert_allclose(body.step([OFF] * 8, DT), (0.0, 0.0, -GRAVITY), atol=1e-9)
    np.testing.assert_allclose(body.rates_frd, 0.0, atol=1e-9)


def test_a_steady_spin_about_the_vertical_integrates_to_its_angle():
    params = dataclasses.replace(AIRFRAMES["quad"], angular_damping=0.0)
    body = _aloft(params, rates_frd=(0.0, 0.0, 0.5))
    _run(body, [OFF] * 4, 1.0)
    assert body.euler_ned() == pytest.approx((0.0, 0.0, 0.5), abs=1e-9)
    assert np.linalg.norm(body.attitude.as_quat()) == pytest.approx(1.0, abs=1e-12)


def test_a_spinning_body_wobbles_the_way_eulers_equations_say():
    # Hand-worked, torque-free, I_x = I_y: the body z rate stays, the (p, q) rate turns from x to y at
    # (I_z - I_x) / I_x * r = (0.60 - 0.35) / 0.35 * 2 = 1.4286 rad/s; after 1 s, 0.5 (cos, sin)(1.4286).
    params = dataclasses.replace(AIRFRAMES["s1000"], angular_damping=0.0)
    body = _aloft(params, rates_frd=(0.5, 0.0, 2.0))
    _run(body, [OFF] * 8, 1.0)
    np.testing.assert_allclose(body.rates_frd, (0.0710, 0.4949, 2.0), atol=2e-3)


def test_euler_angles_are_scipys_zyx():
    r = Rotation.from_euler("ZYX", (2.5, -0.4, 0.3))  # yaw, pitch, roll
    body = _aloft(attitude=r)
    assert body.euler_ned() == pytest.approx((0.3, -0.4, 2.5), abs=1e-12)


def test_the_json_callable_reports_the_state_after_the_step():
    body = _aloft(AIRFRAMES["s1000"], velocity_ned=(1.0, 0.0, 0.0))
    frame = body.physics(ServoPacket(400, 0, (1611,) * 16), 0.0025)
    assert frame.timestamp_s == 0.0025
    assert frame.position_ned == pytest.approx(tuple(body.position_ned)) and frame.position_ned[0] > 0.0
    assert frame.velocity_ned == pytest.approx(tuple(body.velocity_ned))
    assert frame.attitude_rpy == pytest.approx((0.0, 0.0, 0.0))


def test_the_truth_is_read_only_and_set_whole():
    body = RotorBody.named("quad")
    with pytest.raises(ValueError):
        body.position_ned[2] = -5.0
    body.position_ned = (1.0, 2.0, -5.0)
    assert tuple(body.position_ned) == (1.0, 2.0, -5.0)
    with pytest.raises(ValueError, match="4 motors, 3 PWMs"):
        body.step((1500,) * 3, DT)
    with pytest.raises(KeyError, match="quad, s1000"):
        RotorBody.named("s900")


def test_each_airframe_names_its_ardupilot_frame():
    assert rotor_airframe("s1000").ardupilot_params()["FRAME_CLASS"] == 3
    assert rotor_airframe("s1000").ardupilot_params()["FRAME_TYPE"] == 1
    assert rotor_airframe("quad").ardupilot_params()["FRAME_CLASS"] == 1
