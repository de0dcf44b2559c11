"""The camera model: frustum membership, projection and its inverse."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from chaser_bt.vision import CameraModel

LEVEL_EAST = Rotation.identity()  # FLU body x = ENU east


def test_default_is_the_papers_econ_camera():
    cam = CameraModel()
    assert math.degrees(cam.hfov_rad) == pytest.approx(95.0) and math.degrees(cam.vfov_rad) == pytest.approx(73.0)


def test_visible_respects_the_half_angles_and_the_range():
    cam = CameraModel(tilt_rad=0.0, max_range_m=100.0)
    h = math.radians(47.5)
    pts = np.array([
        [50, 0, 0],  # on axis
        [50, 50 * math.tan(h) * 0.99, 0],  # just inside the left edge
        [50, 50 * math.tan(h) * 1.01, 0],  # just outside
        [50, 0, -50 * math.tan(math.radians(36.5)) * 0.99],  # just inside the bottom edge
        [50, 0, 50 * math.tan(math.radians(36.5)) * 1.01],  # just outside the top
        [-10, 0, 0],  # behind
        [101, 0, 0],  # too far
    ])
    np.testing.assert_array_equal(cam.visible(pts, np.zeros(3), LEVEL_EAST), [1, 1, 0, 1, 0, 0, 0])


def test_mount_tilt_looks_down_and_yaw_turns_the_footprint():
    cam = CameraModel(tilt_rad=math.radians(40.0))
    below_ahead = np.array([[30.0, 0.0, -30.0]])  # 45 deg down: inside only thanks to the tilt
    assert cam.visible(below_ahead, np.zeros(3), LEVEL_EAST)[0]
    assert not CameraModel(tilt_rad=0.0).visible(below_ahead, np.zeros(3), LEVEL_EAST)[0]
    north = Rotation.from_euler("z", math.pi / 2)
    assert cam.visible(np.array([[0.0, 30.0, -30.0]]), np.zeros(3), north)[0]


def test_projection_centres_the_axis_and_inverts_through_ray_enu():
    cam = CameraModel(tilt_rad=math.radians(15.0), offset_body_m=(0.3, 0.0, -0.1))
    att = Rotation.from_euler("zyx", [0.7, 0.1, -0.05])
    pos = np.array([10.0, -5.0, 30.0])
    axis = cam.camera_to_enu(att).apply([0.0, 0.0, 1.0])
    px, front = cam.project(cam.position_enu(pos, att) + 40.0 * axis[None], pos, att)
    np.testing.assert_allclose(px[0], [960.0, 540.0], atol=1e-9)
    rng = np.random.default_rng(0)
    pts = pos + rng.uniform(-50, 50, (20, 3)) + 60.0 * axis
    px, front = cam.project(pts, pos, att)
    rays = cam.ray_enu(px[front], att)
    expected = pts[front] - cam.position_enu(pos, att)
    np.testing.assert_allclose(rays, expected / np.linalg.norm(expected, axis=1, keepdims=True), atol=1e-9)


def test_fov_edges_land_on_the_image_edges():
    cam = CameraModel(tilt_rad=0.0)
    edge = np.array([[10.0, -10.0 * math.tan(cam.hfov_rad / 2), 0.0]])  # right edge (body -y)
    px, _ = cam.project(edge, np.zeros(3), LEVEL_EAST)
    assert px[0, 0] == pytest.approx(cam.width_px)


def test_bad_camera_parameters_are_refused():
    with pytest.raises(ValueError, match="FOV"):
        CameraModel(hfov_rad=4.0)
    with pytest.raises(ValueError, match="p_detect"):
        CameraModel(p_detect=0.0)
    with pytest.raises(ValueError, match="mount must be one of fixed, stabilised"):
        CameraModel(mount="gimbal")


def test_a_fixed_camera_leans_with_the_airframe_and_a_stabilised_one_keeps_its_tilt_below_the_horizon():
    # Heading 30 deg north of east, pitched 30 deg nose down and rolled 15 deg, as in a dash.
    att = Rotation.from_euler("ZYX", [math.radians(30), math.radians(30), math.radians(15)])
    fixed = CameraModel(width_px=640, height_px=480, tilt_rad=math.radians(10))
    level = CameraModel(width_px=640, height_px=480, tilt_rad=math.radians(10), mount="stabilised")
    down, heading = math.radians(10), math.radians(30)
    expected = [math.cos(down) * math.cos(heading), math.cos(down) * math.sin(heading), -math.sin(down)]
    assert np.allclose(level.camera_to_enu(att).apply([0, 0, 1]), expected, atol=1e-12)
    pitched = Rotation.from_euler("ZYX", [math.radians(30), math.radians(30), 0.0])
    axis = fixed.camera_to_enu(pitched).apply([0, 0, 1])
    assert math.degrees(math.asin(-axis[2])) == pytest.approx(40.0, abs=1e-9)  # 10 deg mount + 30 deg pitch
    # The image's right edge stays level on the gimbal (no roll) and tilts with the roll when fixed.
    right = level.camera_to_enu(att).apply([1, 0, 0])
    assert right[2] == pytest.approx(0.0, abs=1e-12)
    assert abs(fixed.camera_to_enu(att).apply([1, 0, 0])[2]) > 0.2
    # A target level with the chaser 60 m ahead: 40 deg above the fixed camera's axis (top edge at
    # 36.5 deg: out of view), 10 deg above the stabilised one's (in view).
    target = np.array([[60 * math.cos(heading), 60 * math.sin(heading), 0.0]])
    assert not fixed.visible(target, np.zeros(3), pitched)[0] and level.visible(target, np.zeros(3), pitched)[0]


def test_a_stabilised_camera_looks_the_same_at_any_pitch_and_roll():
    cam = CameraModel(width_px=640, height_px=480, mount="stabilised")
    pts = np.array([[60.0, 5.0, -8.0], [40.0, -20.0, -30.0], [80.0, 30.0, 5.0]])
    flat = cam.project(pts, np.zeros(3), Rotation.from_euler("z", 0.2))[0]
    for pitch, roll in ((0.5, 0.0), (-0.4, 0.3), (0.2, -0.6)):
        att = Rotation.from_euler("ZYX", [0.2, pitch, roll])
        assert np.allclose(cam.project(pts, np.zeros(3), att)[0], flat, atol=1e-9)
