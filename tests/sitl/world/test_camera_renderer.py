"""The rendered camera: geometry agrees with the CameraModel, labels fit the drawn target, speed is fine."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel
from sitl.world.camera.models import TARGET_MODELS, model_for
from sitl.world.camera.renderer import (
    Lighting,
    Renderer,
    TargetPose,
    attitude_from_velocity,
)
from sitl.world.camera.scene import make_ground

CAM = CameraModel(width_px=640, height_px=480, tilt_rad=0.0)
CLEAN = Lighting(noise_sigma=0.0, jpeg_quality=0)


@pytest.fixture(scope="module")
def renderer():
    return Renderer(CAM, make_ground(3, size_px=512))


def test_target_straight_ahead_is_boxed_at_the_centre_with_its_size_from_the_pinhole(renderer):
    d = 20.0
    target = TargetPose("s1000", np.array([d, 0.0, 30.0]))  # vehicle at 30 m looking east, level
    frame = renderer.render(np.array([0.0, 0.0, 30.0]), Rotation.identity(), [target], CLEAN, np.random.default_rng(0))
    (lab,) = frame.labels
    fx = CAM.focal_px[0]
    assert lab.centre_px == pytest.approx((320.0, 240.0), abs=1e-9)
    x0, y0, x1, y1 = lab.box
    # Seen from behind the octocopter's width is its rotor-tip span, at range d minus the disc offsets.
    assert 0.5 * (x0 + x1) == pytest.approx(320.0, abs=0.5)
    assert (x1 - x0) == pytest.approx(2 * (0.5225 * math.sin(3 * math.pi / 8) + 0.19) * fx / d, rel=0.08)
    assert lab.range_m == pytest.approx(d) and not lab.truncated
    # The drawn pixels are darker than the sky around them inside the box, and the box is tight.
    img = frame.image.astype(int).sum(axis=2)
    inside = img[int(y0):int(y1), int(x0):int(x1)]
    assert inside.min() < 300 and img[int(y0) - 4, int(x0):int(x1)].min() > 400


def test_sky_above_the_horizon_and_ground_below(renderer):
    frame = renderer.render(np.array([0.0, 0.0, 30.0]), Rotation.identity(), [], CLEAN, np.random.default_rng(0))
    top, bottom = frame.image[5, 320].astype(int), frame.image[475, 320].astype(int)
    assert top[0] > top[2]  # sky: blue over red (BGR)
    assert bottom[1] > bottom[0]  # grass: green over blue
    assert frame.labels == ()


def test_targets_behind_the_camera_or_outside_the_view_get_no_label(renderer):
    behind = TargetPose("phantom", np.array([-10.0, 0.0, 30.0]))
    aside = TargetPose("phantom", np.array([0.0, 50.0, 30.0]))
    frame = renderer.render(np.array([0.0, 0.0, 30.0]), Rotation.identity(), [behind, aside], CLEAN, np.random.default_rng(0))
    assert frame.labels == ()


def test_same_seed_gives_the_same_frame_and_noise_changes_with_the_seed(renderer):
    args = (np.array([0.0, 0.0, 20.0]), Rotation.from_euler("z", 0.4), [TargetPose("phantom", np.array([8.0, 4.0, 21.0]))], Lighting())
    a = renderer.render(*args, np.random.default_rng(5)).image
    b = renderer.render(*args, np.random.default_rng(5)).image
    c = renderer.render(*args, np.random.default_rng(6)).image
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_attitude_from_velocity_points_the_nose_along_the_track_and_pitches_into_it():
    att = attitude_from_velocity(np.array([0.0, 4.0, 0.0]))
    nose = att.apply([1.0, 0.0, 0.0])
    assert abs(nose[0]) < 1e-12 and nose[1] > 0  # north
    assert math.asin(-nose[2]) == pytest.approx(math.radians(10.0))  # 2.5 deg per m/s, nose down
    assert model_for("s1000") is TARGET_MODELS["s1000"]
    with pytest.raises(ValueError, match="known"):
        model_for("zeppelin")


def test_motion_blur_and_jpeg_change_the_image_but_not_the_labels(renderer):
    tg = [TargetPose("s1000", np.array([15.0, 0.0, 30.0]))]
    pos, att = np.array([0.0, 0.0, 30.0]), Rotation.identity()
    sharp = renderer.render(pos, att, tg, CLEAN, np.random.default_rng(0))
    blurred = renderer.render(pos, att, tg, Lighting(noise_sigma=0, jpeg_quality=50), np.random.default_rng(0), blur_px=9)
    assert sharp.labels == blurred.labels
    assert np.abs(sharp.image.astype(int) - blurred.image.astype(int)).mean() > 0.5


def test_a_standing_person_is_boxed_to_its_height_and_shoulder_width(renderer):
    from sitl.world.camera.models import PERSON_HEIGHT_M

    d = 20.0
    feet = np.array([d, 0.0, 30.0 - 0.88])  # the body's middle at the (level) camera's height
    frame = renderer.render(np.array([0.0, 0.0, 30.0]), Rotation.identity(), [TargetPose("person", feet)], CLEAN, np.random.default_rng(0))
    (lab,) = frame.labels
    fx, fy = CAM.focal_px
    x0, y0, x1, y1 = lab.box
    # Head top 1.765 m, shoe bottom -0.005 m; arms out to +-0.31 m seen from behind.
    assert (y1 - y0) == pytest.approx(1.77 * fy / d, rel=0.05) and 1.77 == pytest.approx(PERSON_HEIGHT_M, abs=0.03)
    assert (x1 - x0) == pytest.approx(0.62 * fx / d, rel=0.1)
    assert lab.kind == "person" and 0.5 * (x0 + x1) == pytest.approx(320.0, abs=0.5)


def test_a_lying_person_seen_from_above_is_long_along_its_body_and_colour_variants_differ(renderer):
    down = Rotation.from_euler("ZY", [0.0, math.pi / 2])  # nose straight down: image right is ENU south
    lying = Rotation.from_euler("ZX", [0.0, math.pi / 2])  # head towards ENU south
    pos = np.array([0.0, 0.0, 30.0])
    frames = [renderer.render(pos, down, [TargetPose("person", np.array([0.0, 0.0, 0.16]), lying, v)], CLEAN, np.random.default_rng(0))
              for v in (0, 1)]
    fx, fy = CAM.focal_px
    (lab,) = frames[0].labels
    x0, y0, x1, y1 = lab.box
    assert (x1 - x0) == pytest.approx(1.77 * fx / 29.84, rel=0.1)  # along the body, 29.84 m below
    assert (y1 - y0) < 0.7 * fy / 29.5 and (y1 - y0) < 0.5 * (x1 - x0)
    assert frames[0].labels == frames[1].labels
    assert not np.array_equal(frames[0].image, frames[1].image)  # the clothes differ
    with pytest.raises(ValueError, match="known"):
        model_for("yeti", 3)


# -- regions of interest ------------------------------------------------------------------------------


def test_viewports_widen_each_region_to_the_jpeg_block_grid_and_merge_overlaps():
    from sitl.world.camera.renderer import viewports

    # (200 - 32) / 16 = 10.5 -> 160; (100 - 32) / 16 = 4.25 -> 64; (408 + 32) / 16 = 27.5 -> 448; (308 + 32) / 16 = 21.25 -> 352
    assert viewports([(200, 100, 408, 308)], 640, 480) == [(160, 64, 448, 352)]
    # Cut to the frame at its edges.
    assert viewports([(0, 440, 40, 480)], 640, 480) == [(0, 400, 80, 480)]
    # Two overlapping regions become their union's box; a distant one stays apart.
    assert viewports([(100, 100, 140, 140), (150, 120, 190, 160), (500, 20, 520, 40)], 640, 480) == [
        (64, 64, 224, 192), (464, 0, 560, 80)]
    # Nothing asked, too much asked (one whole frame is cheaper) or a frame off the block grid: the whole frame.
    assert viewports(None, 640, 480) is None
    assert viewports([(0, 0, 500, 400)], 640, 480) is None
    assert viewports([(10, 10, 20, 20)], 630, 480) is None


@pytest.mark.parametrize("family", ["plain", "suburb", "coast"])
def test_a_frame_read_out_in_regions_is_the_whole_frame_inside_them(family):
    from sitl.world.camera.world import WorldSpec, build_world

    world = build_world(WorldSpec(family=family), 3)
    rend = Renderer(CAM, world=world, noise_seed=1)
    regions = [(200, 100, 408, 308), (40, 380, 120, 460)]
    targets = [TargetPose("s1000", np.array([60.0, 8.0, 33.0])), TargetPose("phantom", np.array([40.0, -30.0, 28.0]))]
    pose = (np.array([0.0, 0.0, 30.0]), Rotation.from_euler("ZY", [0.1, 0.12]))
    full_rng, part_rng = np.random.default_rng(5), np.random.default_rng(5)
    full = rend.render(*pose, targets, world.lighting, full_rng, blur_px=4.0, blur_angle_rad=0.4, t=2.0)
    part = rend.render(*pose, targets, world.lighting, part_rng, blur_px=4.0, blur_angle_rad=0.4, t=2.0, regions=regions)
    assert full.views is None and part.views == ((160, 64, 448, 352), (0, 336, 160, 480))
    assert part.labels == full.labels and full.labels  # labels are geometry: the same either way
    assert part_rng.integers(1 << 30) == full_rng.integers(1 << 30)  # the same randomness drawn
    for x0, y0, x1, y1 in regions:
        diff = np.abs(full.image[y0:y1, x0:x1].astype(int) - part.image[y0:y1, x0:x1])
        # The same pixels but for OpenCV's warp rounding a texel coordinate (1/32 texel) the other way
        # now and then, which JPEG then spreads over its block: a few pixels in a thousand, by a few levels.
        assert diff.max() <= 16 and np.count_nonzero(diff) <= 0.01 * diff.size
    # Outside the views the frame is a flat fill, not the scene.
    assert len(np.unique(part.image[5:60, 600:635].reshape(-1, 3), axis=0)) == 1
