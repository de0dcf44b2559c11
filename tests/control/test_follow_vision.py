"""Following on the camera's own range: the line-of-sight range low-pass, the lean limit, CVFollow's
ports, and one rendered vision-range flight (slow)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chaser_bt.control.follow import FollowConfig, FollowController, LineOfSightRange
from chaser_bt.control.sticks import GRAVITY
from chaser_bt.cue import TargetCue, TargetEstimate

EAST = 0.0
OWN = np.array([0.0, 0.0, 45.0])
NORTH = np.array([0.0, 1.0, 0.0])


def estimate(t, range_m, bearing=(1.0, 0.0, -0.5), camera=OWN, track_id=1):
    b = np.asarray(bearing, float) / np.linalg.norm(bearing)
    return TargetEstimate(t=t, position_enu=camera + range_m * b, source="vision", track_id=track_id,
                          bearing_enu=b, range_m=range_m, range_std_m=5.0, confidence=0.9)


# ----------------------------------------------------------------------------- LineOfSightRange
def test_low_pass_moves_with_own_velocity_then_pulls_towards_the_measurement():
    f = LineOfSightRange(tau_s=2.0)
    assert f.update(0.0, 50.0, NORTH, np.zeros(3)) == 50.0  # the first measurement is taken as it is
    # 1 s later, having flown 4 m/s north (towards the target): predicted 46, measured 60
    r = f.update(1.0, 60.0, NORTH, np.array([0.0, 4.0, 0.0]))
    assert r == pytest.approx(46.0 + (1.0 - math.exp(-0.5)) * (60.0 - 46.0))
    assert f.update(1.0, 99.0, NORTH, np.zeros(3)) == r  # no time passed: unchanged


def test_exact_measurements_of_a_closing_chaser_are_followed_without_lag():
    f = LineOfSightRange(tau_s=3.0)
    for k in range(50):  # the chaser closes at 5 m/s on a still target, range 100 -> 75
        t = 0.1 * k
        r = f.update(t, 100.0 - 5.0 * t, NORTH, np.array([0.0, 5.0, 0.0]))
        assert r == pytest.approx(100.0 - 5.0 * t, abs=1e-9)


def test_noise_shrinks_as_the_exponential_average_predicts():
    rng = np.random.default_rng(4)
    tau, dt, sigma = 3.0, 0.1, 8.0
    f = LineOfSightRange(tau)
    out = [f.update(dt * k, 40.0 + rng.normal(0.0, sigma), NORTH, np.zeros(3)) for k in range(20000)]
    a = 1.0 - math.exp(-dt / tau)
    expected_std = sigma * math.sqrt(a / (2.0 - a))  # stationary EMA of white noise
    assert np.std(out[1000:]) == pytest.approx(expected_std, rel=0.1)
    assert np.mean(out[1000:]) == pytest.approx(40.0, abs=0.3)


def test_time_constant_must_be_positive():
    with pytest.raises(ValueError):
        LineOfSightRange(0.0)
    with pytest.raises(ValueError, match="range_smoothing_s"):
        FollowConfig(range_smoothing_s=-1.0)
    with pytest.raises(ValueError, match="max_lean_rad"):
        FollowConfig(max_lean_rad=math.radians(95.0))


# ----------------------------------------------------------------------------- the controller
def test_default_config_treats_an_estimate_as_its_position():
    a, b = FollowController(), FollowController()
    for k in range(6):
        est = estimate(0.2 * k, 40.0 + 10.0 * (k % 2))
        plain = TargetCue(t=est.t, position_enu=est.position_enu, covariance_enu=est.covariance_enu, source="vision",
                          track_id=1)
        ca = a.update(est.t, OWN, np.zeros(3), EAST, est)
        cb = b.update(est.t, OWN, np.zeros(3), EAST, plain)
        assert (ca.forward_accel, ca.climb, ca.yaw_rate) == (cb.forward_accel, cb.climb, cb.yaw_rate)


def test_smoothing_keeps_the_bearing_and_damps_a_range_jump():
    bearing = np.array([1.0, 0.3, -0.6])
    h = math.hypot(1.0, 0.3) / np.linalg.norm(bearing)  # horizontal share of the line of sight
    raw, smooth = FollowController(), FollowController(FollowConfig(range_smoothing_s=3.0))
    for k in range(10):  # a steady 40 m, then three box-size ranges of 70 m (enough to move a median of 5)
        est = estimate(0.2 * k, 70.0 if k >= 7 else 40.0, bearing)
        c_raw = raw.update(est.t, OWN, np.zeros(3), EAST, est)
        c_smooth = smooth.update(est.t, OWN, np.zeros(3), EAST, est)
    # the azimuth is the bearing's, whatever the range
    assert c_smooth.pv.azimuth_rad == pytest.approx(math.atan2(0.3, 1.0), abs=1e-9)
    assert c_raw.pv.azimuth_rad == pytest.approx(math.atan2(0.3, 1.0), abs=1e-9)
    # raw: the median of (40, 40, 70, 70, 70); smoothed: the median of (40, 40, r7, r8, r9) = r7,
    # one step of the low-pass towards 70
    assert c_raw.pv.ground_range_m == pytest.approx(70.0 * h)
    assert c_smooth.pv.ground_range_m == pytest.approx((40.0 + 30.0 * (1.0 - math.exp(-0.2 / 3.0))) * h)


def test_another_track_starts_its_range_afresh():
    fc = FollowController(FollowConfig(range_smoothing_s=3.0))
    fc.update(0.0, OWN, np.zeros(3), EAST, estimate(0.0, 40.0, track_id=1))
    fc.update(0.2, OWN, np.zeros(3), EAST, estimate(0.2, 90.0, track_id=2))
    assert fc._los_range.range_m == 90.0


def test_lean_limit_caps_the_acceleration():
    far = TargetCue(t=0.0, position_enu=np.array([300.0, 0.0, 20.0]))
    capped = FollowController(FollowConfig(max_lean_rad=math.radians(15.0)))
    free = FollowController()
    c = capped.update(0.0, OWN, np.zeros(3), EAST, far)
    assert c.forward_accel == pytest.approx(GRAVITY * math.tan(math.radians(15.0)))
    c_free = free.update(0.0, OWN, np.zeros(3), EAST, far)  # the vehicle's ANGLE_MAX, 30 deg
    assert c_free.forward_accel == pytest.approx(GRAVITY * math.tan(math.radians(30.0)))


def test_cvfollow_declares_the_new_ports_with_backward_compatible_defaults():
    from behaviours.follow import CVFollow, FollowGlobal

    ports = CVFollow.INPUT_PORTS
    assert ports["range_smoothing_s"].default_value == 0.0
    assert ports["measured_rates"].default_value is True and ports["max_lean_deg"].default_value == 0.0
    assert "range_smoothing_s" not in FollowGlobal.INPUT_PORTS and "max_lean_deg" in FollowGlobal.INPUT_PORTS


# ----------------------------------------------------------------------------- flown, rendered
@pytest.mark.slow
def test_vision_range_follow_keeps_the_rectangle_target_in_view():
    """No telemetry: rendered camera, shipped detector, CVFollow with the benchmark's vision ports."""
    from sitl.bench.follow_eval import (
        VISION_FOLLOW_PORTS,
        fly_follow,
        intruder_scenario,
    )

    score, _, runner = fly_follow(intruder_scenario("rectangle"), 0, range_source="vision", duration_s=30.0,
                                  follow_ports=VISION_FOLLOW_PORTS)
    assert score.in_fov_frac >= 0.9, runner.tip_message()
    assert score.tracking_frac >= 0.5 and score.vision_range_abs_err_p50 < 20.0
