"""Radar frame geometry: range/azimuth/elevation conventions and the pose transform."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from chaser_bt.radar.geometry import RadarPose, rae_covariance_xyz, rae_to_xyz, xyz_to_rae


def test_azimuth_is_positive_to_the_right_and_elevation_up():
    assert np.allclose(rae_to_xyz(10.0, 0.0, 0.0), [10, 0, 0])
    assert np.allclose(rae_to_xyz(10.0, math.pi / 2, 0.0), [0, -10, 0])  # right = -y in FLU
    assert np.allclose(rae_to_xyz(10.0, 0.0, math.pi / 2), [0, 0, 10])


def test_a_radar_facing_east_sees_a_point_north_of_it_on_its_left():
    pose = RadarPose.from_attitude(np.array([5.0, 0.0, 2.0]), math.pi / 2, 0.0, 0.0)  # heading east
    r, az, el = xyz_to_rae(pose.from_enu(np.array([5.0, 10.0, 2.0])))
    assert np.isclose(r, 10.0) and np.isclose(az, -math.pi / 2) and np.isclose(el, 0.0)
    assert np.allclose(pose.rae_to_enu(100.0, 0.0, 0.0), [105.0, 0.0, 2.0])
    assert np.allclose(pose.yaw_pitch_roll, (math.pi / 2, 0.0, 0.0))


@given(st.floats(1, 2000), st.floats(-3.1, 3.1), st.floats(-1.5, 1.5))
def test_rae_round_trip(r, az, el):
    back = xyz_to_rae(rae_to_xyz(r, az, el))
    assert np.allclose(back, (r, az, el), atol=1e-9 * max(1.0, r))


def test_covariance_matches_a_monte_carlo_spread():
    rng = np.random.default_rng(1)
    s = (0.5, math.radians(0.4), math.radians(1.0))
    samples = rae_to_xyz(200 + rng.normal(0, s[0], 200_000), 0.3 + rng.normal(0, s[1], 200_000),
                         0.2 + rng.normal(0, s[2], 200_000))
    assert np.allclose(np.cov(samples.T), rae_covariance_xyz(200, 0.3, 0.2, *s), rtol=0.03, atol=0.01)
