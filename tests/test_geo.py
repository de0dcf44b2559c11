"""Frames and geodesy against independently known values."""

import math

import numpy as np
import pymap3d
import pytest
from hypothesis import given
from hypothesis import strategies as st

from chaser_bt.geo import (
    NearbyGeodetic,
    GeoPoint,
    LocalFrame,
    body_to_enu_rotation,
    enu_to_ned,
    enu_yaw_to_heading,
    euler_ned_from_rotation,
    heading_to_enu_yaw,
    ned_to_enu,
    quat_wxyz_to_xyzw,
    quat_xyzw_to_wxyz,
    wrap_pi,
)

# WGS84 reference lengths (Torge & Müller, Geodesy): one degree of latitude at the equator is
# 110 574.3 m of meridian arc; one degree of longitude on the equator is a / (180/pi) = 111 319.5 m.
METRES_PER_DEG_LAT_EQUATOR = 110_574.3
METRES_PER_DEG_LON_EQUATOR = 6_378_137.0 * math.pi / 180.0


def test_origin_maps_to_zero():
    frame = LocalFrame(GeoPoint(42.55, -71.6, 80.0))
    np.testing.assert_allclose(frame.to_enu(42.55, -71.6, 80.0), [0, 0, 0], atol=1e-9)


def test_small_latitude_step_at_equator_is_meridian_arc_north():
    frame = LocalFrame(GeoPoint(0.0, 0.0, 0.0))
    e, n, u = frame.to_enu(0.001, 0.0, 0.0)
    assert e == pytest.approx(0.0, abs=1e-6)
    assert n == pytest.approx(METRES_PER_DEG_LAT_EQUATOR * 0.001, rel=1e-4)
    # Earth curves away beneath the tangent plane: u ~ -d^2 / (2 R) ~ -1 mm for 110 m.
    assert u == pytest.approx(-(n**2) / (2 * 6_335_439.0), abs=2e-4)


def test_small_longitude_step_on_equator_is_east():
    frame = LocalFrame(GeoPoint(0.0, 0.0, 0.0))
    e, n, _ = frame.to_enu(0.0, 0.001, 0.0)
    assert e == pytest.approx(METRES_PER_DEG_LON_EQUATOR * 0.001, rel=1e-6)
    assert n == pytest.approx(0.0, abs=1e-6)


def test_longitude_step_shrinks_with_cos_latitude():
    frame = LocalFrame(GeoPoint(60.0, 10.0, 0.0))
    e, _, _ = frame.to_enu(60.0, 10.001, 0.0)
    # Prime-vertical radius N = a / sqrt(1 - e^2 sin^2 phi); parallel radius N cos phi.
    e2 = 6.69437999014e-3
    n_radius = 6_378_137.0 / math.sqrt(1 - e2 * math.sin(math.radians(60)) ** 2)
    assert e == pytest.approx(n_radius * math.cos(math.radians(60)) * math.radians(0.001), rel=1e-5)


def test_equator_prime_meridian_is_on_the_ecef_x_axis():
    x, y, z = pymap3d.geodetic2ecef(0.0, 0.0, 0.0)
    assert (x, y, z) == pytest.approx((6_378_137.0, 0.0, 0.0), abs=1e-6)


@given(
    st.floats(-80, 80), st.floats(-179, 179), st.floats(-100, 3000),
    st.floats(-2000, 2000), st.floats(-2000, 2000), st.floats(-200, 500),
)
def test_enu_geodetic_round_trip(lat, lon, alt, e, n, u):
    frame = LocalFrame(GeoPoint(lat, lon, alt))
    p = frame.to_geodetic((e, n, u))
    np.testing.assert_allclose(frame.point_to_enu(p), [e, n, u], atol=1e-5)


@given(
    st.floats(-88, 88), st.floats(-180, 179.999), st.floats(-100, 3000),
    st.lists(st.tuples(st.floats(-3000, 3000), st.floats(-3000, 3000), st.floats(-200, 500)), min_size=1, max_size=8),
    st.floats(0.0, 60.0),
)
def test_nearby_geodetic_agrees_with_pymap3d_to_a_millimetre(lat, lon, alt, anchors, jitter):
    """Each anchor and a point up to ``jitter`` m from it (on the linearisation) land within 1 mm."""
    frame = LocalFrame(GeoPoint(lat, lon, alt))
    nearby = NearbyGeodetic(frame)
    for e, n, u in anchors:
        for p in ((e, n, u), (e + jitter, n - jitter / 2, u + jitter / 3)):
            g = nearby(p)
            assert np.linalg.norm(frame.point_to_enu(g) - np.array(p)) < 1e-3


def test_nearby_geodetic_calls_pymap3d_only_to_re_anchor(monkeypatch):
    """A 100-point walk inside 10 m costs the 4 exact conversions of one anchor; 200 m on, 4 more."""
    calls = []
    exact = pymap3d.enu2geodetic
    monkeypatch.setattr(pymap3d, "enu2geodetic", lambda *a, **k: calls.append(a) or exact(*a, **k))
    nearby = NearbyGeodetic(LocalFrame(GeoPoint(47.0, 8.0, 400.0)))
    for k in range(100):
        nearby((5.0 * math.cos(k), 5.0 * math.sin(k), 20.0))
    assert len(calls) == 4
    nearby((200.0, 0.0, 20.0))
    assert len(calls) == 8


def test_nearby_geodetic_wraps_the_antimeridian():
    frame = LocalFrame(GeoPoint(10.0, 179.9999, 0.0))
    nearby = NearbyGeodetic(frame)
    nearby((0.0, 0.0, 0.0))
    g = nearby((30.0, 0.0, 0.0))  # 30 m east of 179.9999 E is west of 180
    assert g.lon_deg < 0.0
    assert np.linalg.norm(frame.point_to_enu(g) - [30.0, 0.0, 0.0]) < 1e-3


def test_geopoint_rejects_out_of_range_latitude():
    with pytest.raises(ValueError, match="latitude"):
        GeoPoint(91.0, 0.0)


def test_ned_enu_swap_axes_and_flip_vertical():
    np.testing.assert_array_equal(ned_to_enu((1.0, 2.0, 3.0)), [2.0, 1.0, -3.0])
    np.testing.assert_array_equal(enu_to_ned(ned_to_enu((1.0, 2.0, 3.0))), [1.0, 2.0, 3.0])


def test_level_nose_north_body_axes():
    r = body_to_enu_rotation(0.0, 0.0, 0.0)
    np.testing.assert_allclose(r.apply([1, 0, 0]), [0, 1, 0], atol=1e-12)  # forward -> north
    np.testing.assert_allclose(r.apply([0, 1, 0]), [-1, 0, 0], atol=1e-12)  # left -> west
    np.testing.assert_allclose(r.apply([0, 0, 1]), [0, 0, 1], atol=1e-12)  # up -> up


def test_heading_east_points_forward_east():
    r = body_to_enu_rotation(0.0, 0.0, math.pi / 2)
    np.testing.assert_allclose(r.apply([1, 0, 0]), [1, 0, 0], atol=1e-12)


def test_right_wing_down_raises_left_wing():
    roll = math.radians(30)
    r = body_to_enu_rotation(roll, 0.0, 0.0)
    np.testing.assert_allclose(r.apply([0, 1, 0]), [-math.cos(roll), 0, math.sin(roll)], atol=1e-12)


def test_nose_up_pitch_raises_forward_axis():
    pitch = math.radians(10)
    r = body_to_enu_rotation(0.0, pitch, 0.0)
    np.testing.assert_allclose(r.apply([1, 0, 0]), [0, math.cos(pitch), math.sin(pitch)], atol=1e-12)


@given(st.floats(-1.4, 1.4), st.floats(-1.4, 1.4), st.floats(-3.1, 3.1))
def test_euler_round_trip(roll, pitch, yaw):
    back = euler_ned_from_rotation(body_to_enu_rotation(roll, pitch, yaw))
    np.testing.assert_allclose(back, [roll, pitch, yaw], atol=1e-9)


@pytest.mark.parametrize("heading_deg, yaw_deg", [(0, 90), (90, 0), (180, -90), (270, -180)])
def test_heading_and_enu_yaw(heading_deg, yaw_deg):
    assert math.degrees(heading_to_enu_yaw(math.radians(heading_deg))) == pytest.approx(yaw_deg)
    assert math.degrees(enu_yaw_to_heading(math.radians(yaw_deg))) == pytest.approx(heading_deg % 360)


def test_quaternion_order_conversion():
    q = quat_wxyz_to_xyzw((1.0, 2.0, 3.0, 4.0))
    np.testing.assert_array_equal(q, [2.0, 3.0, 4.0, 1.0])
    np.testing.assert_array_equal(quat_xyzw_to_wxyz(q), [1.0, 2.0, 3.0, 4.0])


@given(st.floats(-100, 100))
def test_wrap_pi_range_and_equivalence(a):
    w = wrap_pi(a)
    assert -math.pi <= w < math.pi
    assert math.isclose(math.cos(w), math.cos(a), abs_tol=1e-9) and math.isclose(math.sin(w), math.sin(a), abs_tol=1e-9)
