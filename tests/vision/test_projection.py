"""Pixel <-> ENU through quaternions, and the alpha-beta attitude smoother."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import MOUNTS, CameraModel
from chaser_bt.vision.projection import AttitudeSmoother, Projector, quat_multiply, quat_rotate

angles = st.floats(-math.pi, math.pi)
small = st.floats(-0.5, 0.5)
CAM = CameraModel(width_px=640, height_px=480, tilt_rad=math.radians(12), offset_body_m=(0.15, -0.03, -0.08))


@given(st.lists(st.floats(-1, 1), min_size=4, max_size=4), st.lists(st.floats(-1, 1), min_size=4, max_size=4),
       st.lists(st.floats(-10, 10), min_size=3, max_size=3))
def test_quaternion_product_and_rotation_match_scipy(p, q, v):
    p, q = np.array(p), np.array(q)
    if np.linalg.norm(p) < 0.1 or np.linalg.norm(q) < 0.1:
        return
    p, q = p / np.linalg.norm(p), q / np.linalg.norm(q)
    expected = (Rotation.from_quat(p) * Rotation.from_quat(q)).apply(v)
    assert np.allclose(quat_rotate(quat_multiply(p, q), np.array(v)), expected, atol=1e-9)


@settings(max_examples=200)
@given(angles, small, small, st.floats(5, 200), st.floats(-1, 1), st.floats(-0.7, 0.7))
def test_enu_to_pixel_to_enu_is_exact(yaw, pitch, roll, dist, du, dv):
    att = Rotation.from_euler("ZYX", [yaw, pitch, roll])
    proj = Projector(CAM)
    pos = np.array([12.0, -7.0, 30.0])
    # A point inside the view: along the ray through a pixel, at some distance.
    px = np.array([[320 + 300 * du, 240 + 220 * dv]])
    point = proj.point_enu(px, np.array([dist]), pos, att)
    back, front = proj.pixel_of(point, pos, att)
    assert front.all()
    assert np.allclose(back, px, atol=1e-9)
    r = np.linalg.norm(point - CAM.position_enu(pos, att), axis=1)
    assert np.allclose(proj.point_enu(back, r, pos, att), point, atol=1e-9)


@given(angles, small, small, st.sampled_from(MOUNTS))
def test_quaternion_bearing_agrees_with_the_camera_model(yaw, pitch, roll, mount):
    att = Rotation.from_euler("ZYX", [yaw, pitch, roll])
    cam = dataclasses.replace(CAM, mount=mount)
    px = np.array([[0.0, 0.0], [639.0, 479.0], [320.0, 240.0], [100.0, 400.0]])
    assert np.allclose(Projector(cam).bearing_enu(px, att), cam.ray_enu(px, att), atol=1e-12)


def test_image_centre_of_a_level_untilted_camera_looks_along_the_heading():
    cam = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
    b = Projector(cam).bearing_enu(np.array([[320.0, 240.0]]), Rotation.from_euler("z", math.pi / 2))[0]
    assert np.allclose(b, [0.0, 1.0, 0.0], atol=1e-12)  # yaw 90 deg ENU = north
    # Right edge of the image is hfov/2 to the right (clockwise seen from above, i.e. towards east).
    r = Projector(cam).bearing_enu(np.array([[640.0, 240.0]]), Rotation.from_euler("z", math.pi / 2))[0]
    assert math.isclose(math.atan2(r[0], r[1]), math.radians(47.5), abs_tol=1e-9)


def test_smoother_passes_a_constant_attitude_and_tracks_a_constant_rate_without_lag():
    s = AttitudeSmoother(alpha=0.5, beta=0.1)
    fixed = Rotation.from_euler("ZYX", [0.3, 0.1, -0.2])
    for k in range(20):
        out = s.update(0.1 * k, fixed)
    assert (out * fixed.inv()).magnitude() < 1e-12
    s = AttitudeSmoother(alpha=0.5, beta=0.1)
    for k in range(200):
        out = s.update(0.02 * k, Rotation.from_euler("z", 0.4 * 0.02 * k))
    assert abs(out.as_euler("ZYX")[0] - 0.4 * 0.02 * 199) < 1e-6


def test_smoother_reduces_attitude_noise():
    rng = np.random.default_rng(0)
    s = AttitudeSmoother(alpha=0.3, beta=0.02)
    raw, smooth = [], []
    for k in range(400):
        truth = Rotation.from_euler("z", 0.2 * 0.02 * k)
        meas = Rotation.from_rotvec(rng.normal(0, 0.01, 3)) * truth
        out = s.update(0.02 * k, meas)
        if k > 50:
            raw.append((meas * truth.inv()).magnitude())
            smooth.append((out * truth.inv()).magnitude())
    assert np.mean(smooth) < 0.7 * np.mean(raw)


@settings(max_examples=60, deadline=None)
@given(angles, small, small, st.floats(-math.pi, math.pi), st.floats(-1.4, 1.4), st.floats(5, 300))
def test_angle_outside_the_image_is_zero_inside_and_never_more_than_the_angle_to_any_pixel(yaw, pitch, roll, az, el, dist):
    """Hand case: level camera yawed to north, a point at azimuth a east of north in the horizontal plane
    lies a - 47.5 deg outside the right edge's plane; property: the bound is at most the angle to the
    nearest of a dense grid of pixels (brute force), and 0 for points seen."""
    cam = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
    proj, north = Projector(cam), Rotation.from_euler("z", math.pi / 2)
    for a_deg, want in ((10.0, 0.0), (47.5, 0.0), (60.0, 12.5), (90.0, 42.5)):
        a = math.radians(a_deg)
        p = cam.position_enu(np.zeros(3), north) + 50.0 * np.array([math.sin(a), math.cos(a), 0.0])
        assert math.isclose(math.degrees(proj.angle_outside_rad(p, np.zeros(3), north)), want, abs_tol=1e-9)
    att = Rotation.from_euler("ZYX", [yaw, pitch, roll])
    ray = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    point = CAM.position_enu(np.zeros(3), att) + dist * ray
    bound = Projector(CAM).angle_outside_rad(point, np.zeros(3), att)
    grid = np.stack(np.meshgrid(np.linspace(0, 640, 65), np.linspace(0, 480, 49)), -1).reshape(-1, 2)
    nearest = math.acos(min(1.0, float(np.max(Projector(CAM).bearing_enu(grid, att) @ ray))))
    assert bound <= nearest + 1e-9
    px, front = Projector(CAM).pixel_of(point[None], np.zeros(3), att)
    if front[0] and 0 <= px[0, 0] <= 640 and 0 <= px[0, 1] <= 480:
        assert bound == 0.0
