"""The built-in autopilot against ArduCopter's own behaviour, each against an answer worked by hand
from ArduPilot's formulas (RTL's return altitude, the S-curve, the take-off ramp, the land detector)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sitl.vehicle.airframe import AirframeParams
from sitl.vehicle.modes import (
    PositionController,
    StraightSCurve,
    inv_sqrt_controller,
    land_descent_rate,
    rtl_return_alt,
    sqrt_controller,
    stopping_point,
)
from sitl.vehicle.physics import WindParams

GUIDED, RTL, LAND = 4, 6, 9


# ---------------------------------------------------------------- RTL return altitude (ModeRTL::compute_return_target)
@pytest.mark.parametrize(("alt", "dist", "rtl_alt", "climb_min", "slope", "expected"), [
    (10.0, 50.0, 15.0, 0.0, 3.0, 15.0),   # far out: the cone (150 m) is above RTL_ALT, RTL_ALT governs
    (10.0, 4.0, 15.0, 0.0, 3.0, 12.0),    # 4 m out: capped at 3 * 4 = 12 m
    (10.0, 2.0, 15.0, 0.0, 3.0, 10.0),    # 2 m out: the cone (6 m) is below us, no climb, no descent
    (10.0, 2.0, 15.0, 2.0, 3.0, 12.0),    # RTL_CLIMB_MIN 2 m still climbs 2 m inside the cone
    (10.0, 4.0, 15.0, 0.0, 0.4, 15.0),    # slopes under 0.5 are ignored
    (20.0, 50.0, 15.0, 0.0, 3.0, 20.0),   # above RTL_ALT: returns at its own height
    (0.1, 0.0, 0.0, 0.0, 3.0, 0.3),       # never below RTL_ALT_MIN (30 cm)
])
def test_rtl_return_altitude_follows_arducopters_cone(alt, dist, rtl_alt, climb_min, slope, expected):
    assert rtl_return_alt(alt, dist, rtl_alt, climb_min, slope) == pytest.approx(expected)


def test_stopping_point_is_the_inverse_sqrt_controller():
    # PSC_POSXY_P 1, accel 2.5: below 2.5 m/s linear (d = v / P); above, 0.5 a / P^2 + v^2 / (2 a)
    assert stopping_point(0.0, 0.0, 2.0, 0.0, 2.5) == pytest.approx((2.0, 0.0))
    assert stopping_point(0.0, 0.0, 0.0, -5.0, 2.5) == pytest.approx((0.0, -(1.25 + 5.0)))


def test_rtl_near_home_climbs_only_to_the_cone(airborne, run_for):
    ap = airborne(alt=10.0)
    ap.set_position_target([4.0, 0.0, 10.0])
    run_for(ap, 15.0)
    assert ap.request_mode(RTL).accepted
    heights = []
    run_for(ap, 12.0, each=lambda a: heights.append(a.truth.pos_enu[2]))
    # 3 * 4 m, not RTL_ALT's 15 m (within the estimate's ~0.2 m error in height and its position error)
    assert max(heights) == pytest.approx(12.0, abs=0.5)


# ---------------------------------------------------------------- the S-curve of a waypoint leg
def test_s_curve_leg_matches_the_hand_worked_profile():
    # jerk 1, snap pi: raised-cosine rise tj = pi * 1 / (2 pi) = 0.5 s; accel 2.5 = 1 * (tj + t2): t2 = 2 s;
    # a pulse (3 s) gains 2.5 * 3 / 2 = 3.75 m/s, two give 7.5, so 1 s at 2.5 m/s^2 makes 10 m/s:
    # speeding up takes 7 s over 35 m, slowing down the same, 30 m of cruise at 10 m/s: 17 s in all
    leg = StraightSCurve.plan(100.0, 10.0, 2.5, 1.0, math.pi)
    assert leg.duration == pytest.approx(17.0)
    assert leg.at(3.5) == pytest.approx((leg.at(3.5)[0], 5.0, 2.5))  # 3.75 + 0.5 s at 2.5
    assert leg.at(7.0)[:2] == pytest.approx((35.0, 10.0))
    assert leg.at(8.5) == pytest.approx((50.0, 10.0, 0.0), abs=1e-9)
    assert leg.at(17.0) == (100.0, 0.0, 0.0)


def test_a_short_s_curve_leg_shortens_its_jerk_pulses():
    # snap pi/4: the full rise would be tj = 2 s, too long for 4 m; raised-cosine pulses only, with peak
    # jerk 2 snap tj / pi = tj / 2, so two pulses of 2 tj reach v = tj^3 over 2 v tj = 2 tj^4 m each way:
    # 4 m = 4 tj^4 gives tj = 1 s, a peak of 1 m/s at 4 s, 8 s in all
    leg = StraightSCurve.plan(4.0, 10.0, 2.5, 1.0, math.pi / 4.0)
    assert leg.duration == pytest.approx(8.0)
    assert leg.at(4.0)[:2] == pytest.approx((2.0, 1.0))


# ---------------------------------------------------------------- GUIDED position shaping (shape_pos_vel_accel_xy)
def test_position_target_speeds_up_at_the_jerk_limit_and_stops_on_the_goal():
    pc = PositionController(8.0, 157.0)
    pc.reset(0.0, 0.0, 20.0, 0.0, 0.0, 0.0, 0.0)
    pc.set_pos_xy(100.0, 0.0, 10.0, 2.5)
    dt, t = 0.02, 0.0
    prev_a, at_1s, top, furthest = 0.0, None, 0.0, 0.0
    while t < 30.0 - 1e-9:
        pc.update_xy(dt, pc.tpx, pc.tpy, pc.tvx, pc.tvy, 0.0, math.radians(30.0))  # a vehicle right on target
        t += dt
        assert abs(pc.tax - prev_a) <= 5.0 * dt + 1e-9  # PSC_JERK_XY 5 m/s^3
        assert abs(pc.tax) <= 2.5 + 1e-9  # WPNAV_ACCEL
        prev_a, top, furthest = pc.tax, max(top, pc.tvx), max(furthest, pc.tpx)
        if at_1s is None and t >= 1.0 - 1e-9:
            at_1s = (pc.tpx, pc.tvx)
    # 0.5 s of 5 m/s^3 to 2.5 m/s^2 (0.625 m/s, 5 * 0.5^3 / 6 = 0.104 m), then 0.5 s at 2.5 m/s^2:
    # 1.875 m/s and 0.104 + 0.3125 + 0.3125 = 0.729 m after 1 s, less the one 20 ms step by which the
    # target moves before its acceleration is reshaped (ArduPilot's order too): 0.05 m/s, 0.04 m
    assert at_1s == pytest.approx((0.729, 1.875), abs=0.06)
    assert top == pytest.approx(10.0, abs=0.01)
    assert furthest < 100.3  # braking at half WPNAV_ACCEL leaves room: a few tens of cm past at most
    assert pc.tpx == pytest.approx(100.0, abs=0.01) and pc.tvx == pytest.approx(0.0, abs=0.01)


def test_the_velocity_pid_low_passes_its_error_and_adds_the_derivative_as_arducopters():
    # AC_PID_2D with PSC_VELXY_P 2, _D 0.25, FLTE = FLTD = 5 Hz: a 1 m/s velocity error appearing at once,
    # one 10 ms step: alpha = 0.01 / (0.01 + 1 / (2 pi 5)) = 0.23906; the filtered error 0.23906 m/s, its
    # derivative 0.23906 * 0.23906 / 0.01 = 5.7148 m/s^2; the integrator, stepped before the output as
    # AC_PID_2D::update_all does, 1 * 0.23906 * 0.01 = 0.0023906; the demand 2 * 0.23906 + 0.25 * 5.7148
    # + 0.0023906 = 1.9092 m/s^2 east, a roll of atan(1.9092 / g) with the nose north. Unfiltered, P alone
    # gave 2.0.
    pc = PositionController(8.0, 157.0)
    pc.reset(0.0, 0.0, 20.0, 0.0, 0.0, 0.0, 0.0)
    pc.tvx, pc.xy_external = 1.0, True  # a target velocity set from outside this step, not reshaped
    roll, pitch = pc.update_xy(0.01, 0.0, 0.0, 0.0, 0.0, 0.0, math.radians(30.0))
    assert roll == pytest.approx(math.atan(1.9092 / 9.80665), abs=2e-5)
    assert pitch == pytest.approx(0.0, abs=1e-9)


def test_the_position_error_is_corrected_by_a_sqrt_controller_as_arducopters():
    # AC_P_2D with PSC_POSXY_P 1 and GUIDED's correction limits (WPNAV_SPEED 10 m/s, WPNAV_ACCEL 2.5 m/s^2):
    # a 5 m error is past the linear part (2.5 m), so the correction is sqrt(2 * 2.5 * (5 - 1.25)) = 4.3301
    # m/s, not 5. Through the velocity PID's first 10 ms step (the factor 1.90921 worked in the test above)
    # that asks 8.2671 m/s^2 east (linear: 9.5461), under the 45 deg limit.
    pc = PositionController(8.0, 157.0)
    pc.reset(0.0, 0.0, 20.0, 0.0, 0.0, 0.0, 0.0)
    pc.set_correction_xy(10.0, 2.5)
    pc.tpx, pc.xy_external = 5.0, True
    roll, _ = pc.update_xy(0.01, 0.0, 0.0, 0.0, 0.0, 0.0, math.radians(45.0))
    assert roll == pytest.approx(math.atan(8.2671 / 9.80665), abs=2e-5)


def test_a_target_beyond_the_error_limit_is_dragged_back_to_it():
    # The error that asks for the full 10 m/s: 2.5 / 2 + 10^2 / (2 * 2.5) = 21.25 m. A target 30 m ahead
    # of the vehicle is moved back to 21.25 m ahead (AC_P_2D's _error_max), along the same line.
    pc = PositionController(8.0, 157.0)
    pc.reset(0.0, 0.0, 20.0, 0.0, 0.0, 0.0, 0.0)
    pc.set_correction_xy(10.0, 2.5)
    pc.tpx, pc.tpy, pc.xy_external = 18.0, 24.0, True  # 30 m out, 3-4-5
    pc.update_xy(0.01, 0.0, 0.0, 0.0, 0.0, 0.0, math.radians(30.0))
    assert (pc.tpx, pc.tpy) == pytest.approx((21.25 * 0.6, 21.25 * 0.8))


@pytest.mark.parametrize(("output", "p", "accel", "expected"), [
    (10.0, 1.0, 2.5, 21.25),  # past the linear part: accel / (2 p^2) + v^2 / (2 accel)
    (2.0, 1.0, 2.5, 2.0),     # inside it: v / p
    (-10.0, 1.0, 2.5, -21.25),
    (3.0, 0.5, 0.0, 6.0),     # no acceleration limit: linear
])
def test_inv_sqrt_controller_by_hand(output, p, accel, expected):
    assert inv_sqrt_controller(output, p, accel) == pytest.approx(expected)


@given(st.floats(-30.0, 30.0), st.floats(0.2, 3.0), st.floats(0.5, 10.0))
def test_inv_sqrt_controller_inverts_sqrt_controller(output, p, accel):
    assert sqrt_controller(inv_sqrt_controller(output, p, accel), p, accel) == pytest.approx(output, abs=1e-9)


def test_a_guided_position_target_is_flown_on_a_straight_3d_line(airborne, run_for):
    """AC_PosControl::input_pos_xyz: 280 m north and 20 m up at WPNAV_SPEED 10 m/s and WPNAV_SPEED_UP
    2.5 m/s. The line rises 20 m in 280 m (slope 0.071, under 2.5 / 10), so the horizontal limit binds:
    10 m/s across and 10 * 20 / 280 = 0.714 m/s up, and both axes arrive together. Shaped axis by axis,
    it would climb at 2.5 m/s and be up in 9 s."""
    ap = airborne(10.0)
    ap.set_position_target([0.0, 280.0, 30.0])
    track = []
    run_for(ap, 45.0, each=lambda a: track.append((a.time_s, *a.truth.pos_enu, a.truth.vel_enu[1], a.truth.vel_enu[2])))
    t, _, north, up, vn, vz = np.array(track).T
    cruise = (north > 100.0) & (north < 180.0)
    assert np.median(vn[cruise]) == pytest.approx(10.0, abs=0.3)
    assert np.median(vz[cruise]) == pytest.approx(20.0 / 28.0, abs=0.08)
    # on the line: the height gained is the distance flown times the slope, all the way
    assert np.max(np.abs((up - 10.0) - (north / 280.0) * 20.0)) < 1.5
    assert up[-1] == pytest.approx(30.0, abs=0.3) and north[-1] == pytest.approx(280.0, abs=0.5)
    # a goal straight up is not slowed: WPNAV_SPEED_UP
    ap.set_position_target([0.0, 280.0, 50.0])
    climb = []
    run_for(ap, 6.0, each=lambda a: climb.append(a.truth.vel_enu[2]))
    assert max(climb) == pytest.approx(2.5, abs=0.15)


def test_the_target_waits_for_a_vehicle_held_back_by_its_lean_limit(make_ap, run_for):
    # ArduPilot's SITL quad's drag on 8 kg: at 30 deg, 0.234 v^2 + 1.37 v = 8 g tan 30 = 45.3 N: 11.29 m/s
    # through the air, 8.29 m/s over the ground into 3 m/s
    quad = AirframeParams(max_thrust_ratio=2.564, drag_lin_h=1.37, drag_quad_h=0.234)
    ap = make_ap(wind=WindParams(speed_mps=3.0, direction_deg=270.0), airframe=quad)
    run_for(ap, 4.0)
    ap.request_mode(GUIDED)
    ap.request_arm(True)
    ap.request_takeoff(20.0)
    run_for(ap, 16.0)
    ap.set_position_target([-100.0, 0.0, 20.0])  # west, into the wind
    lead, speed = [], []
    run_for(ap, 14.0, each=lambda a: (lead.append(math.hypot(a.pc.tpx - a.ex, a.pc.tpy - a.ey)),
                                      speed.append(-a.truth.vel_enu[0])))
    assert max(speed) == pytest.approx(8.29, abs=0.3)
    assert max(lead) < 3.0  # without the limit vector the target ran ~1.7 m/s ahead: > 10 m


@pytest.mark.parametrize(("integrator", "step", "limit", "expected"), [
    ((1.0, 0.0), (0.1, 0.0), (0.0, 0.0), (1.1, 0.0)),       # no limit: it grows
    ((1.0, 0.0), (0.1, 0.0), (5.0, 0.0), (1.0, 0.0)),       # along the limit: held at its length
    ((1.0, 0.0), (0.0, 0.1), (5.0, 0.0), (1.0, 0.1)),       # across it: free
    ((1.0, 0.0), (0.1, 0.1), (5.0, 0.0), (1.1 / math.hypot(1.1, 0.1), 0.1 / math.hypot(1.1, 0.1))),  # turned, not lengthened
    ((1.0, 0.0), (-0.1, 0.0), (5.0, 0.0), (0.9, 0.0)),      # against it: unwinds
    ((9.95, 0.0), (0.1, 0.0), (0.0, 0.0), (10.0, 0.0)),     # PSC_VELXY_IMAX
])
def test_the_velocity_integrator_may_turn_but_not_grow_along_the_last_lean_limit(integrator, step, limit, expected):
    # AC_PID_2D::update_i: the step is added, then, if it pushed along the limit vector, the integrator is
    # cut back to its length before the step
    pc = PositionController(8.0, 157.0)
    pc.ix, pc.iy = integrator
    pc._limit = limit
    pc._integrate(*step)
    assert (pc.ix, pc.iy) == pytest.approx(expected, abs=1e-12)


def test_a_lean_limited_leg_flies_at_50_hz_as_at_arducopters_400_hz(make_ap, run_for, monkeypatch):
    # The S1000 matched to our rotor body (7.5 kg, 176 N) 100 m east into 8 m/s: 17-18 m/s through the air
    # needs the whole 30 deg. ArduCopter runs its position controller at 400 Hz and, flying this body in our
    # world, held the lean at 29.95 deg and took 14.52 s (0.52 s more than in still air); the built-in at
    # 50 Hz let its target jump a step ahead of the vehicle and back (29.3 deg, 0.15 s slower than itself
    # at 400 Hz)
    import sitl.vehicle.autopilot as autopilot

    s1000 = AirframeParams(mass_kg=7.5, max_thrust_ratio=2.393, motor_tau_s=0.06, drag_lin_h=0.3, drag_quad_h=0.12,
                           drag_lin_v=0.3, drag_quad_v=0.12)

    def leg(physics_dt: float) -> tuple[float, float]:
        monkeypatch.setattr(autopilot, "PHYSICS_DT", physics_dt)
        ap = make_ap(wind=WindParams(speed_mps=8.0, direction_deg=90.0), airframe=s1000)
        run_for(ap, 4.0)
        ap.request_mode(GUIDED)
        ap.request_arm(True)
        ap.request_takeoff(20.0)
        run_for(ap, 20.0)
        t0, x0 = ap.time_s, ap.truth.pos_enu[0]
        ap.set_position_target([x0 + 100.0, ap.truth.pos_enu[1], 20.0])
        leans = []
        while ap.truth.pos_enu[0] < x0 + 98.0:
            run_for(ap, 0.02)
            if 6.0 < ap.time_s - t0 < 9.0:
                leans.append(abs(ap.phys.pitch))
        return ap.time_s - t0, math.degrees(float(np.mean(leans)))

    t50, lean50 = leg(0.02)
    t400, lean400 = leg(0.0025)
    assert t50 == pytest.approx(t400, abs=0.05)
    assert lean50 > 29.7 and lean400 > 29.7


# ---------------------------------------------------------------- take-off (_AutoTakeoff::run) and land detector
def test_takeoff_waits_out_the_arming_delay_spools_up_then_ramps_the_throttle(make_ap, run_for):
    # the rotors stay still for ArduCopter's 2 s arming delay, spool up for MOT_SPOOL_TIME 0.5 s, then
    # the throttle climbs 1 / TKOFF_SLEW_TIME = 0.5 per s from zero; the default airframe hovers at 0.5
    # throttle, so a take-off commanded on arming lifts 2 + 0.5 + 1.0 = 3.5 s after it, one commanded
    # 3 s after arming (delay over) 0.5 + 1.0 = 1.5 s after the command
    for wait, expected in ((0.0, 3.5), (3.0, 1.5)):
        ap = make_ap()
        run_for(ap, 4.0)
        ap.request_mode(GUIDED)
        ap.request_arm(True)
        run_for(ap, wait)
        assert ap.request_takeoff(20.0).accepted
        heights = []
        run_for(ap, 5.0, each=lambda a: heights.append(a.truth.pos_enu[2]))
        first_up = next(i for i, h in enumerate(heights) if h > 0.0) * 0.02
        assert first_up == pytest.approx(expected, abs=0.1)


def test_the_position_controller_takes_over_the_takeoff_throttle_without_a_drop(make_ap, run_for):
    # AC_PosControl::D_init_controller at lift-off: the acceleration target starts at the measured climb
    # acceleration and the acceleration integrator holds the throttle the ramp had reached, so the
    # thrust runs on from the ramp's last value; reset to zero instead, it fell to the hover thrust (half
    # of the default airframe's maximum) on the first step and the climb started 0.25 s late
    ap = make_ap()
    run_for(ap, 4.0)
    ap.request_mode(GUIDED)
    ap.request_arm(True)
    run_for(ap, 3.0)
    assert ap.request_takeoff(20.0).accepted
    steps = []  # (lifted off, thrust command, vertical speed)
    run_for(ap, 4.0, each=lambda a: steps.append((a._mode.lifted_off, a.phys.thrust_cmd, a.truth.vel_enu[2])))
    i = next(k for k, (lifted, _, _) in enumerate(steps) if lifted)
    ramp_thrust = steps[i - 1][1]
    assert ramp_thrust > 0.5 * ap.airframe.max_thrust_n  # lift-off needs more than hover thrust
    after = [thrust for _, thrust, _ in steps[i + 1:i + 6]]  # the controller's first 0.1 s
    assert min(after) > 0.97 * ramp_thrust
    climb = [vz for _, _, vz in steps[i:i + 50]]
    assert all(b >= a - 1e-6 for a, b in zip(climb, climb[1:]))  # accelerating up through lift-off


LAND_PARAMS = {"LAND_SPEED": 50, "LAND_SPEED_HIGH": 0, "WPNAV_SPEED_DN": 150, "LAND_ALT_LOW": 1000, "WPNAV_ACCEL_Z": 100}


@pytest.mark.parametrize(("alt", "params", "expected"), [
    (20.0, {}, 1.5),                               # far above LAND_ALT_LOW: WPNAV_SPEED_DN
    (11.5, {}, math.sqrt(2.0 * 1.0 * (1.5 - 0.5))),  # 1.5 m above: sqrt(2 a (e - a / 2p^2)), 1.414
    (11.0, {}, 1.0),                               # 1 m above: the linear part, p e
    (10.3, {}, 0.5),                               # 0.3 m above: held at LAND_SPEED
    (4.0, {}, 0.5),                                # below: LAND_SPEED
    (1.5, {"LAND_ALT_LOW": 50}, 0.5),              # LAND_ALT_LOW is taken as at least 1 m
    (30.0, {"LAND_SPEED_HIGH": 300}, 3.0),         # LAND_SPEED_HIGH over WPNAV_SPEED_DN
    (30.0, {"WPNAV_SPEED_DN": 30}, 0.5),           # never slower than LAND_SPEED
])
def test_land_eases_to_land_speed_above_land_alt_low_as_arducopter(alt, params, expected):
    # Mode::land_run_vertical_control: sqrt_controller(LAND_ALT_LOW - alt, PSC_POSZ_P 1, WPNAV_ACCEL_Z 1 m/s^2)
    # held between -LAND_SPEED and the fast rate; the linear part reaches 1 m out (a / p^2)
    host = SimpleNamespace(p=LAND_PARAMS | params, alt_rel=lambda: alt)
    assert land_descent_rate(host) == pytest.approx(expected)


def test_land_disarms_one_second_at_the_throttle_floor_and_a_spool_down_later(airborne, run_for):
    # LAND_DETECTOR_TRIGGER_SEC 1 s with the thrust at its lower limit on the ground, then the rotors
    # spool down for MOT_SPOOL_TIME 0.5 s before the disarm
    ap = airborne(alt=3.0)
    assert ap.request_mode(LAND).accepted
    floor, disarmed, t = None, None, 0.0
    while t < 30.0 and disarmed is None:
        ap.step(0.02)
        t += 0.02
        at_floor = ap.phys.on_ground and ap.phys.thrust_cmd <= ap.airframe.idle_thrust_n
        if at_floor and floor is None:
            floor = t
        elif not at_floor and ap.armed:
            floor = None
        if not ap.armed:
            disarmed = t
    assert floor is not None and disarmed is not None
    assert disarmed - floor == pytest.approx(1.5, abs=0.05)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_still_air_hover_holds_its_height_still(airborne, run_for, seed):
    # ArduCopter's SITL hovers at 0.00 m/s vertically. The EKF's error is a slow, smooth drift (a 30 s
    # Gauss-Markov process, low-passed at 3 s: its rate is 0.1 m / sqrt(30 s * 3 s) ~ 0.01 m/s RMS), which the
    # altitude hold follows; the earlier 5 s unsmoothed walk had it moving at 0.05 m/s RMS, 0.1-0.2 m/s at times
    ap = airborne(alt=20.0, seed=seed)
    run_for(ap, 10.0)
    vz = []
    run_for(ap, 30.0, each=lambda a: vz.append(a.truth.vel_enu[2]))
    vz = np.asarray(vz)
    assert np.sqrt(np.mean(vz * vz)) < 0.02
    assert np.abs(vz).max() < 0.05


def test_after_touchdown_the_thrust_reaches_its_floor_as_late_as_arducopters(airborne, run_for):
    # ArduCopter standing on the ground after a 0.5 m/s descent: the accel target grows as
    # 5 * (0.5 + 0.5 t) m/s^2 (PSC_VELZ_P 5, PSC_POSZ_P 1), and the throttle falls from hover (0.39) by
    # 0.0005 * err + 0.001 * integral(err) (PSC_ACCZ_P 0.5, _I 1, err in cm/s^2): 0.125 t^2 + 0.375 t + 0.125
    # = 0.39 at t = 0.59 s. Feeding the accel demand forward into the thrust got there in 0.4 s.
    ap = airborne(alt=3.0)
    assert ap.request_mode(LAND).accepted
    contact = floor = None
    t = 0.0
    while t < 30.0 and floor is None:
        ap.step(0.01)
        t += 0.01
        if contact is None and ap.phys.on_ground:
            contact = t
        if contact is not None and ap.phys.thrust_cmd <= ap.airframe.idle_thrust_n and t - contact > 0.05:
            floor = t
    assert contact is not None and floor is not None
    assert floor - contact == pytest.approx(0.59, abs=0.1)
