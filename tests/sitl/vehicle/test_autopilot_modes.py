"""Flight modes of the simulated ArduCopter: GUIDED, ALT_HOLD, LOITER, BRAKE, RTL, LAND, STABILIZE."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from chaser_bt.geo import body_to_enu_rotation
from sitl.vehicle.autopilot import (
    MAV_LANDED_STATE_IN_AIR,
    MAV_LANDED_STATE_LANDING,
    MAV_LANDED_STATE_ON_GROUND,
    MAV_LANDED_STATE_TAKEOFF,
)
from sitl.vehicle.physics import WindParams

GUIDED, RTL, LAND, BRAKE, LOITER, ALT_HOLD, STABILIZE = 4, 6, 9, 17, 5, 2, 0
KEEP = 65535


def _horizontal(v) -> float:
    return float(math.hypot(v[0], v[1]))


def test_guided_takeoff_climbs_to_20m_at_wpnav_speed_up_and_holds(make_ap, run_for):
    ap = make_ap()
    run_for(ap, 4.0)
    ap.request_mode(GUIDED)
    ap.request_arm(True)
    assert ap.request_takeoff(20.0).accepted
    states, climb = set(), []
    run_for(ap, 20.0, each=lambda a: (states.add(a.landed_state), climb.append(a.truth.vel_enu[2])))
    assert MAV_LANDED_STATE_TAKEOFF in states
    assert max(climb) == pytest.approx(2.5, abs=0.15)  # WPNAV_SPEED_UP 250 cm/s
    assert ap.landed_state == MAV_LANDED_STATE_IN_AIR
    heights = []
    run_for(ap, 10.0, each=lambda a: heights.append(a.truth.pos_enu[2]))
    assert min(heights) > 19.7 and max(heights) < 20.3
    assert _horizontal(ap.truth.pos_enu) < 0.5
    assert ap.position_estimate().alt_rel_m == pytest.approx(20.0, abs=0.4)


def test_takeoff_is_refused_unless_armed_in_guided_on_the_ground(make_ap, run_for, airborne):
    ap = make_ap()
    run_for(ap, 4.0)
    assert not ap.request_takeoff(10.0).accepted  # disarmed, STABILIZE
    ap.request_mode(GUIDED)
    assert not ap.request_takeoff(10.0).accepted  # disarmed
    flying = airborne(10.0)
    assert not flying.request_takeoff(30.0).accepted  # already flying


def test_a_position_target_is_reached_and_held(airborne, run_for):
    ap = airborne()
    assert ap.set_position_target(np.array([40.0, -30.0, 25.0]))
    dist = []
    run_for(ap, 25.0, each=lambda a: dist.append(np.linalg.norm(a.truth.pos_enu - [40.0, -30.0, 25.0])))
    assert dist[-1] < 1.0
    run_for(ap, 30.0, each=lambda a: dist.append(np.linalg.norm(a.truth.pos_enu - [40.0, -30.0, 25.0])))
    assert max(dist[-1500:]) < 1.0
    # WPNAV_SPEED 10 m/s is the limit on the way
    assert _horizontal(ap.truth.vel_enu) < 0.3


def test_a_distant_position_target_without_yaw_turns_the_nose_towards_it(airborne, run_for):
    ap = airborne()
    ap.set_position_target([100.0, 0.0, 20.0])  # due east
    run_for(ap, 5.0)
    assert ap.heading_deg == pytest.approx(90.0, abs=2.0)


def test_a_position_target_with_yaw_sets_the_heading(airborne, run_for):
    ap = airborne()
    ap.set_position_target([0.0, 0.0, 20.0], yaw_enu_rad=math.pi)  # ENU yaw pi = facing west
    run_for(ap, 6.0)
    assert ap.heading_deg == pytest.approx(270.0, abs=2.0)


def test_change_speed_limits_guided_navigation(airborne, run_for):
    ap = airborne()
    assert ap.set_speed(4.0).accepted
    ap.set_position_target([200.0, 0.0, 20.0])
    speeds = []
    run_for(ap, 30.0, each=lambda a: speeds.append(_horizontal(a.truth.vel_enu)))
    assert max(speeds) == pytest.approx(4.0, abs=0.5)
    assert np.median(speeds[500:1000]) == pytest.approx(4.0, abs=0.1)


def test_non_finite_guided_targets_are_dropped(airborne, run_for):
    ap = airborne()
    nan = float("nan")
    assert not ap.set_position_target([nan, 0.0, 20.0])
    assert not ap.set_velocity_target([0.0, 0.0, 0.0], yaw_rate=math.inf)
    assert not ap.set_attitude_target([0.0, 0.0, 0.0, 0.0], None, 0.5)
    assert not ap.set_attitude_target([0.0, 0.0, 0.0, 1.0], None, nan)
    assert not ap.set_speed(nan).accepted
    run_for(ap, 2.0)
    assert np.all(np.isfinite(ap.truth.pos_enu)) and ap.truth.pos_enu[2] == pytest.approx(20.0, abs=0.3)


def test_guided_targets_are_ignored_outside_guided(airborne):
    ap = airborne()
    ap.request_mode(LOITER)
    assert not ap.set_position_target([10.0, 0.0, 20.0])
    assert not ap.set_velocity_target([1.0, 0.0, 0.0])
    assert not ap.set_attitude_target([0.0, 0.0, 0.0, 1.0], None, 0.5)
    assert not ap.set_speed(3.0).accepted


def test_a_velocity_target_is_flown_then_times_out_and_the_vehicle_stops(airborne, run_for):
    ap = airborne()
    assert ap.set_velocity_target([3.0, 0.0, 0.0])
    run_for(ap, 2.5)
    assert ap.truth.vel_enu[0] == pytest.approx(3.0, abs=0.3)
    run_for(ap, 0.6)  # GUID_TIMEOUT 3 s has passed
    run_for(ap, 6.0)
    assert _horizontal(ap.truth.vel_enu) < 0.2
    x = ap.truth.pos_enu[0]
    run_for(ap, 10.0)
    assert ap.truth.pos_enu[0] == pytest.approx(x, abs=0.5)  # holds where it stopped


def test_a_resent_velocity_target_keeps_the_vehicle_moving(airborne, run_for):
    ap = airborne()
    run_for(ap, 10.0, each=lambda a: a.set_velocity_target([0.0, 2.0, 0.5]))
    v = ap.truth.vel_enu
    assert v[1] == pytest.approx(2.0, abs=0.2) and v[2] == pytest.approx(0.5, abs=0.1)


def test_an_attitude_target_tilts_and_half_thrust_holds_altitude(airborne, run_for):
    ap = airborne()
    q = body_to_enu_rotation(0.0, math.radians(-10.0), 0.0).as_quat()  # nose down, heading north
    run_for(ap, 4.0, each=lambda a: a.set_attitude_target(q, None, 0.5))
    roll, pitch, *_ = ap.attitude()
    assert pitch == pytest.approx(math.radians(-10.0), abs=math.radians(0.5))
    assert ap.truth.vel_enu[1] > 3.0
    assert ap.truth.pos_enu[2] == pytest.approx(20.0, abs=0.5)


def test_attitude_thrust_above_half_is_a_climb_rate(airborne, run_for):
    ap = airborne()
    q = Rotation.identity().as_quat()  # level, nose east
    run_for(ap, 5.0, each=lambda a: a.set_attitude_target(q, None, 1.0))
    # (1.0 - 0.5) * 2 * WPNAV_SPEED_UP
    assert ap.truth.vel_enu[2] == pytest.approx(2.5, abs=0.2)
    assert ap.heading_deg == pytest.approx(90.0, abs=1.0)


def test_an_attitude_target_times_out_to_level_and_hold(airborne, run_for):
    ap = airborne()
    q = body_to_enu_rotation(math.radians(10.0), 0.0, 0.0).as_quat()
    ap.set_attitude_target(q, None, 0.5)
    run_for(ap, 2.0)
    assert ap.attitude()[0] == pytest.approx(math.radians(10.0), abs=math.radians(0.5))
    run_for(ap, 2.0)  # past GUID_TIMEOUT
    assert abs(ap.attitude()[0]) < math.radians(0.5)


def test_guid_options_bit_3_makes_attitude_thrust_real_thrust(airborne, run_for):
    ap = airborne(params={"GUID_OPTIONS": 8})
    q = body_to_enu_rotation(0.0, 0.0, 0.0).as_quat()
    run_for(ap, 1.0, each=lambda a: a.set_attitude_target(q, None, 0.6))
    # 0.6 of 2x weight = 1.2 g up: accelerating at 0.2 g minus drag
    assert ap.phys.thrust == pytest.approx(0.6 * ap.airframe.max_thrust_n, rel=0.01)
    assert ap.truth.vel_enu[2] > 1.0


def _override(ap, roll=1500, pitch=1500, throttle=1500, yaw=1500):
    ap.rc_override([roll, pitch, throttle, yaw, KEEP, KEEP, KEEP, KEEP])


def test_alt_hold_centred_sticks_hold_altitude_and_heading(airborne, run_for):
    ap = airborne(heading_deg=30.0, wind=WindParams(speed_mps=3.0, direction_deg=270.0, gust_std_mps=0.3))
    heading0 = ap.heading_deg
    _override(ap)
    assert ap.request_mode(ALT_HOLD).accepted
    run_for(ap, 20.0, each=lambda a: _override(a))
    assert ap.truth.pos_enu[2] == pytest.approx(20.0, abs=0.5)
    assert ap.heading_deg == pytest.approx(heading0, abs=1.0)


def test_alt_hold_pitch_1300_gives_11_deg_nose_down_and_flies_north(airborne, run_for):
    ap = airborne()  # heading north
    _override(ap)
    ap.request_mode(ALT_HOLD)
    run_for(ap, 5.0, each=lambda a: _override(a, pitch=1300))
    # (1300 - 1480) / 480 * 30 deg = -11.25 deg
    assert math.degrees(ap.attitude()[1]) == pytest.approx(-11.25, abs=0.2)
    v = ap.truth.vel_enu
    assert v[1] > 3.0 and abs(v[0]) < 0.5
    assert ap.truth.pos_enu[2] == pytest.approx(20.0, abs=0.7)


def test_alt_hold_yaw_stick_turns_at_the_pilot_rate(airborne, run_for):
    ap = airborne()
    _override(ap)
    ap.request_mode(ALT_HOLD)
    run_for(ap, 1.0, each=lambda a: _override(a, yaw=1750))
    rate = math.degrees(ap.attitude()[5])
    # (1750 - 1520) / 480 * PILOT_Y_RATE 202.5 deg/s = 97 deg/s, clockwise
    assert rate == pytest.approx(97.0, abs=3.0)


def test_alt_hold_with_the_throttle_stick_down_descends(airborne, run_for):
    ap = airborne()
    ap.request_mode(ALT_HOLD)  # no override: throttle stick rests at 1000
    run_for(ap, 4.0)
    # PILOT_SPEED_DN 0 -> PILOT_SPEED_UP 2.5 m/s at full down stick
    assert ap.truth.vel_enu[2] == pytest.approx(-2.5, abs=0.2)


def test_loiter_holds_position_in_wind(airborne, run_for):
    ap = airborne(wind=WindParams(speed_mps=5.0, direction_deg=45.0, gust_std_mps=0.5))
    _override(ap)
    p0 = ap.truth.pos_enu.copy()
    assert ap.request_mode(LOITER).accepted
    run_for(ap, 30.0, each=lambda a: _override(a))
    assert np.linalg.norm(ap.truth.pos_enu - p0) < 1.0


def test_loiter_roll_stick_moves_right(airborne, run_for):
    ap = airborne()  # heading north: right is east
    _override(ap)
    ap.request_mode(LOITER)
    run_for(ap, 6.0, each=lambda a: _override(a, roll=1740))
    v = ap.truth.vel_enu
    assert v[0] > 3.0 and abs(v[1]) < 0.5


def test_brake_stops_a_fast_vehicle_and_holds(airborne, run_for):
    ap = airborne()
    run_for(ap, 4.0, each=lambda a: a.set_velocity_target([8.0, 0.0, 0.0]))
    assert ap.truth.vel_enu[0] > 7.0
    assert ap.request_mode(BRAKE).accepted
    x0 = ap.truth.pos_enu[0]
    run_for(ap, 4.5)  # under 2 m/s after 2 s; the last 1.7 m/s are closed by the position hold's sqrt controller
    assert _horizontal(ap.truth.vel_enu) < 0.3
    # stopping from 8 m/s near the 30 deg lean limit (5.7 m/s^2 at most): > 5.6 m, well under 16 m
    assert 5.0 < ap.truth.pos_enu[0] - x0 < 16.0
    x1 = ap.truth.pos_enu[0]
    run_for(ap, 5.0)
    assert ap.truth.pos_enu[0] == pytest.approx(x1, abs=0.5)


def test_rtl_climbs_to_rtl_alt_then_returns(airborne, run_for):
    ap = airborne(alt=10.0)
    ap.set_position_target([40.0, 30.0, 10.0])
    run_for(ap, 20.0)
    assert ap.request_mode(RTL).accepted
    track = []
    run_for(ap, 120.0, each=lambda a: track.append((a.truth.pos_enu.copy(), a.landed_state, a.armed)))
    pos = np.array([p for p, _, _ in track])
    reached = int(np.argmax(pos[:, 2] > 14.8))
    assert reached > 0
    # climbs (RTL_ALT 1500 cm) before heading home
    assert np.linalg.norm(pos[reached, :2] - [40.0, 30.0]) < 1.5
    assert pos[:, 2].max() == pytest.approx(15.0, abs=0.4)
    # returns, lands within a metre of home, disarms itself
    assert _horizontal(pos[-1]) < 1.0 and pos[-1, 2] == 0.0
    states = [s for _, s, _ in track]
    assert MAV_LANDED_STATE_LANDING in states
    assert states[-1] == MAV_LANDED_STATE_ON_GROUND
    assert not ap.armed
    assert not ap.truth.crashed


def test_rtl_keeps_altitude_when_already_above_rtl_alt(airborne, run_for):
    ap = airborne(alt=30.0)
    ap.set_position_target([50.0, 0.0, 30.0])
    run_for(ap, 15.0)
    ap.request_mode(RTL)
    heights = []
    run_for(ap, 15.0, each=lambda a: heights.append(a.truth.pos_enu[2]))
    assert min(heights) > 29.5 and max(heights) < 30.5
    assert ap.truth.pos_enu[0] < 40.0  # on its way home at altitude


def test_rtl_loiters_rtl_loit_time_above_home_before_landing(airborne, run_for):
    ap = airborne(alt=15.0, params={"RTL_LOIT_TIME": 8000})
    ap.request_mode(RTL)
    run_for(ap, 7.0)
    assert ap.landed_state == MAV_LANDED_STATE_IN_AIR
    assert ap.truth.pos_enu[2] == pytest.approx(15.0, abs=0.3)
    run_for(ap, 5.0)
    assert ap.landed_state == MAV_LANDED_STATE_LANDING


def test_rtl_alt_final_stops_the_descent_and_hovers(airborne, run_for):
    ap = airborne(alt=15.0, params={"RTL_ALT_FINAL": 500, "RTL_LOIT_TIME": 0})
    ap.request_mode(RTL)
    run_for(ap, 30.0)
    assert ap.armed and ap.truth.pos_enu[2] == pytest.approx(5.0, abs=0.3)


def test_land_descends_at_land_speed_and_disarms(airborne, run_for):
    ap = airborne(alt=8.0)
    assert ap.request_mode(LAND).accepted
    rates = []
    run_for(ap, 25.0, each=lambda a: rates.append(a.truth.vel_enu[2]))
    assert np.median(rates[100:500]) == pytest.approx(-0.5, abs=0.05)  # LAND_SPEED 50 cm/s
    assert not ap.armed and ap.truth.on_ground and not ap.truth.crashed
    assert _horizontal(ap.truth.pos_enu) < 0.5


def test_land_from_high_descends_at_wpnav_speed_dn_above_land_alt_low(airborne, run_for):
    ap = airborne(alt=30.0)
    ap.request_mode(LAND)
    run_for(ap, 5.0)
    assert ap.truth.vel_enu[2] == pytest.approx(-1.5, abs=0.1)  # WPNAV_SPEED_DN
    ap2 = airborne(alt=30.0, params={"LAND_SPEED_HIGH": 300})
    ap2.request_mode(LAND)
    run_for(ap2, 5.0)
    assert ap2.truth.vel_enu[2] == pytest.approx(-3.0, abs=0.15)


def test_stabilize_mid_throttle_is_near_hover_and_zero_throttle_falls(airborne, run_for):
    ap = airborne()
    _override(ap)
    ap.request_mode(STABILIZE)
    run_for(ap, 1.0, each=lambda a: _override(a))
    # stick 1500 above RC3_DZ 30: (1500 - 1030) / 970 = 0.4845 of the way, just under the hover
    # throttle (0.5) at mid-stick: 48.45 % of maximum thrust, divided by the tilt boost (~1)
    assert ap.throttle_pct == pytest.approx(48.45, abs=0.3)
    run_for(ap, 1.0, each=lambda a: _override(a, throttle=1000))
    assert ap.truth.vel_enu[2] < -5.0


def test_same_seed_flies_the_same_flight(airborne, run_for):
    wind = WindParams(speed_mps=4.0, direction_deg=100.0, gust_std_mps=1.0)
    runs = []
    for _ in range(2):
        ap = airborne(wind=wind, seed=7)
        ap.set_position_target([20.0, 20.0, 25.0])
        run_for(ap, 10.0)
        runs.append(ap.truth.pos_enu)
    assert np.array_equal(runs[0], runs[1])
    other = airborne(wind=wind, seed=8)
    other.set_position_target([20.0, 20.0, 25.0])
    run_for(other, 10.0)
    assert not np.array_equal(runs[0], other.truth.pos_enu)


def test_a_speed_set_before_a_change_into_position_control_is_lost_as_on_arducopter(airborne, run_for):
    """ArduCopter's GUIDED resets the horizontal speed to WPNAV_SPEED (10 m/s here) when it enters position
    control from velocity control (mode_guided.cpp: pos_control_start -> pva_control_start), so a
    DO_CHANGE_SPEED sent while flying velocity targets does not reach the next position target; sent
    after the first position target, it holds."""
    ap = airborne()
    assert ap.set_velocity_target([2.0, 0.0, 0.0])
    run_for(ap, 2.0)
    assert ap.set_speed(4.0).accepted  # while in velocity control: lost at the change
    ap.set_position_target([600.0, 0.0, 20.0])
    speeds = []
    run_for(ap, 25.0, each=lambda a: speeds.append(_horizontal(a.truth.vel_enu)))
    assert np.median(speeds[-500:]) == pytest.approx(10.0, abs=0.3)
    assert ap.set_speed(4.0).accepted  # now in position control: holds
    ap.set_position_target([0.0, 0.0, 20.0])
    speeds.clear()
    run_for(ap, 40.0, each=lambda a: speeds.append(_horizontal(a.truth.vel_enu)))
    assert np.median(speeds[-1000:]) == pytest.approx(4.0, abs=0.2)
