"""FollowController: geometry, signs, rate, staleness, and a closed loop on a point-mass model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chaser_bt.control.follow import FollowConfig, FollowController, MedianWindow, process_variables
from chaser_bt.cue import TargetCue

EAST = 0.0  # ENU yaw facing east


def cue(t, pos, vel=None):
    return TargetCue(t=t, position_enu=np.asarray(pos, float), velocity_enu=None if vel is None else np.asarray(vel, float))


def test_paper_set_points():
    c = FollowConfig()
    assert c.ground_range_sp == pytest.approx(30.64, abs=0.01)
    assert c.height_sp == pytest.approx(25.71, abs=0.01)
    assert (c.rate_hz, c.median_window, c.stale_after_s) == (5.0, 5, 2.0)
    assert (c.yaw.kp, c.pitch.kp, c.climb.kp) == (0.25, 0.4, 0.6)


def test_process_variables_hand_computed():
    pv = process_variables(np.array([10.0, 0.0, 40.0]), math.radians(90.0), np.array([40.0, 30.0, 20.0]))
    # target 30 m east and 30 m north of a chaser facing north: 45 deg to the right (negative), 42.43 m
    assert pv.azimuth_rad == pytest.approx(math.radians(-45.0))
    assert pv.ground_range_m == pytest.approx(math.hypot(30, 30))
    assert pv.rel_height_m == pytest.approx(20.0)
    assert pv.elevation_rad == pytest.approx(math.atan2(20.0, math.hypot(30, 30)))


def test_median_window_of_five():
    w = MedianWindow(5)
    outs = [w.push(x) for x in (1.0, 100.0, 2.0, 3.0, -50.0, 4.0)]
    assert outs == [1.0, 50.5, 2.0, 2.5, 2.0, 3.0]


def test_target_far_ahead_pitches_forward_and_holds_heading():
    fc = FollowController()
    cmd = fc.update(0.0, np.array([0, 0, 45.0]), np.zeros(3), EAST, cue(0.0, [80, 0, 19.3]))
    assert not cmd.hover and cmd.forward_accel > 0 and cmd.sticks.pitch < 1500
    assert cmd.sticks.yaw == 1500 and cmd.sticks.roll == 1500 and cmd.sticks.throttle == 1500


def test_target_left_yaws_counter_clockwise_and_low_chaser_climbs():
    fc = FollowController()
    cmd = fc.update(0.0, np.array([0, 0, 30.0]), np.zeros(3), EAST, cue(0.0, [25, 18, 20]))
    assert cmd.yaw_rate > 0 and cmd.sticks.yaw < 1500
    assert cmd.climb > 0 and cmd.sticks.throttle > 1500


def test_heading_is_the_bearing_to_the_target():
    """A target 25 m east and 25 m north of a chaser facing east: 45 deg left, so ENU yaw pi/4."""
    fc = FollowController()
    cmd = fc.update(0.0, np.array([0, 0, 30.0]), np.zeros(3), EAST, cue(0.0, [25, 25, 20]))
    assert cmd.heading_enu == pytest.approx(math.pi / 4)
    cmd = FollowController().update(0.0, np.array([0, 0, 30.0]), np.zeros(3), math.radians(170.0), cue(0.0, [-25, -25, 20]))
    assert cmd.heading_enu == pytest.approx(-3 * math.pi / 4)  # across the +-180 deg seam, wrapped


def test_at_the_set_point_everything_centres():
    c = FollowConfig()
    fc = FollowController(c)
    target = [c.ground_range_sp, 0.0, 10.0]
    for k in range(6):
        cmd = fc.update(0.2 * k, np.array([0, 0, 10.0 + c.height_sp]), np.zeros(3), EAST, cue(0.2 * k, target, [0, 0, 0]))
    assert cmd.sticks.as_tuple() == (1500, 1500, 1500, 1500)


def test_commands_at_5_hz_and_hover_at_once_when_stale():
    fc = FollowController()
    own = np.array([0, 0, 45.0])
    first = fc.update(10.0, own, np.zeros(3), EAST, cue(10.0, [60, 0, 20]))
    assert fc.update(10.1, own, np.zeros(3), EAST, cue(10.1, [61, 0, 20])) is first  # within one period
    assert fc.update(10.2, own, np.zeros(3), EAST, cue(10.2, [62, 0, 20])).t == 10.2
    # 2 s after the last data: hover in the same call, whatever the rate
    stale = fc.update(12.25, own, np.zeros(3), EAST, cue(10.2, [62, 0, 20]))
    assert stale.hover and "old" in stale.reason
    assert fc.update(12.3, own, np.zeros(3), EAST, None).hover


def test_feed_forward_turns_with_the_line_of_sight():
    # target 30 m east moving north at 6 m/s: the line of sight turns counter-clockwise at 0.2 rad/s
    base = FollowController(FollowConfig())
    ff = FollowController(FollowConfig(feed_forward=True))
    args = (0.0, np.array([0, 0, 45.7]), np.zeros(3), EAST, cue(0.0, [30.64, 0, 20], [0, 6, 0]))
    assert base.update(*args).yaw_rate == pytest.approx(0.0, abs=1e-9)
    assert ff.update(*args).yaw_rate == pytest.approx(0.2 * 30.64 ** 2 / 30.64 ** 2, abs=0.01)


def test_roll_matches_sideways_target_motion():
    fc = FollowController(FollowConfig(use_roll=True))
    cmd = fc.update(0.0, np.array([0, 0, 45.7]), np.zeros(3), EAST, cue(0.0, [30.64, 0, 20], [0, -5, 0]))
    assert cmd.right_accel > 0 and cmd.sticks.roll > 1500  # target drifting to the chaser's right


def test_guided_velocity_points_at_the_set_point():
    fc = FollowController()
    cmd = fc.update(0.0, np.zeros(3) + [0, 0, 45.7], np.zeros(3), EAST, cue(0.0, [0, 80, 20]))
    assert cmd.velocity_enu[1] > 10.0 and abs(cmd.velocity_enu[0]) < 1e-9


def test_inside_the_minimum_range_guided_backs_off_and_climbs():
    """Set-point 24 m at 20 deg (ground 22.55 m); a hovering target 6 m north and 2 m below. The range
    term alone backs off at 0.5 x (6 - 22.55) = -8.27 m/s north; with min_range 12 m the back-off adds
    1 x (12 - 6.32) m/s more, and the climb is at least 5.68 x sin(20 deg) = 1.94 m/s."""
    target, own = [0.0, 6.0, 28.0], np.array([0.0, 0.0, 30.0])
    c = dict(slant_range_m=24.0, elevation_rad=math.radians(20.0))
    plain = FollowController(FollowConfig(**c)).update(0.0, own, np.zeros(3), math.radians(90), cue(0.0, target))
    floor = FollowController(FollowConfig(**c, min_range_m=12.0)).update(0.0, own, np.zeros(3), math.radians(90),
                                                                         cue(0.0, target))
    slant = math.hypot(6.0, 2.0)
    ground_sp = 24.0 * math.cos(math.radians(20.0))
    assert plain.velocity_enu[1] == pytest.approx(0.5 * (6.0 - ground_sp), abs=1e-6)
    assert floor.velocity_enu[1] == pytest.approx(plain.velocity_enu[1] - (12.0 - slant), abs=1e-6)
    assert floor.velocity_enu[2] >= (12.0 - slant) * math.sin(math.radians(20.0)) - 1e-9
    with pytest.raises(ValueError, match="min_range_m"):
        FollowConfig(slant_range_m=24.0, min_range_m=30.0)


@pytest.mark.parametrize("use_roll, az_tol_deg", [(False, 5.0), (True, 0.5)])
def test_closed_loop_on_a_point_mass_reaches_the_set_point(use_roll, az_tol_deg):
    """Independent plant: ALT_HOLD as ideal lean -> acceleration, climb rate and yaw rate (no autopilot).

    Without roll a sideways drift only dies with drag (the chaser circles in slowly: the paper's
    three loops cannot stop it); the roll loop stops it.
    """
    c = FollowConfig(use_roll=use_roll)
    fc = FollowController(c)
    pos, vel, yaw = np.array([-20.0, -70.0, 30.0]), np.zeros(3), 0.3
    target = np.array([0.0, 0.0, 20.0])
    dt = 0.02
    for k in range(int(90 / dt)):
        t = k * dt
        cmd = fc.update(t, pos, vel, yaw, cue(t, target, [0, 0, 0]))
        fwd = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
        acc = cmd.forward_accel * fwd + cmd.right_accel * right - 0.05 * vel  # light drag
        vel = vel + acc * dt
        vel[2] = cmd.climb
        pos = pos + vel * dt
        yaw += cmd.yaw_rate * dt
    pv = process_variables(pos, yaw, target)
    assert abs(pv.azimuth_rad) < math.radians(az_tol_deg)
    assert pv.ground_range_m == pytest.approx(c.ground_range_sp, abs=0.5)
    assert pv.rel_height_m == pytest.approx(c.height_sp, abs=0.3)


def test_a_closing_limit_caps_the_range_correction_not_the_targets_own_velocity():
    """Set-point ground range 22.55 m (24 m at 20 deg); a target 100 m north. The range term asks for
    0.5 x (100 - 22.55) = 38.7 m/s north, cut to the 20 m/s speed limit; with a closing limit of 8 m/s
    the chaser flies 8 m/s north at a hovering target, and 10 + 8 = 18 m/s at one flying north at 10."""
    own = np.array([0.0, 0.0, 30.0])
    c = dict(slant_range_m=24.0, elevation_rad=math.radians(20.0), feed_forward=True)
    still = cue(0.0, [0.0, 100.0, 22.0], [0.0, 0.0, 0.0])
    fleeing = cue(0.0, [0.0, 100.0, 22.0], [0.0, 10.0, 0.0])
    free = FollowController(FollowConfig(**c)).update(0.0, own, np.zeros(3), math.radians(90), still)
    assert math.hypot(*free.velocity_enu[:2]) == pytest.approx(20.0, abs=1e-6)
    capped = FollowController(FollowConfig(**c, max_closing_mps=8.0)).update(0.0, own, np.zeros(3), math.radians(90), still)
    assert capped.velocity_enu[1] == pytest.approx(8.0, abs=1e-6) and abs(capped.velocity_enu[0]) < 1e-9
    after = FollowController(FollowConfig(**c, max_closing_mps=8.0)).update(0.0, own, np.zeros(3), math.radians(90), fleeing)
    assert after.velocity_enu[1] == pytest.approx(18.0, abs=1e-6)
    near = cue(0.0, [0.0, 30.0, 22.0], [0.0, 0.0, 0.0])  # 7.45 m beyond the set-point: 3.7 m/s, under the cap
    assert FollowController(FollowConfig(**c, max_closing_mps=8.0)).update(0.0, own, np.zeros(3), math.radians(90), near
                                                                          ).velocity_enu[1] == pytest.approx(
        0.5 * (30.0 - 24.0 * math.cos(math.radians(20.0))), abs=1e-6)
    with pytest.raises(ValueError, match="max_closing_mps"):
        FollowConfig(max_closing_mps=-1.0)
