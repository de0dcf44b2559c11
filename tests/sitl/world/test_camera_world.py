"""Camera worlds: families, reproducibility, the held-out families' separation, and each layer's effect."""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel
from sitl.world.camera.distractors import Bird, Birds
from sitl.world.camera.effects import CameraEffects, vignette_map
from sitl.world.camera.materials import MATERIALS, periodic_fractal_noise
from sitl.world.camera.renderer import Renderer, TargetPose, attitude_from_velocity
from sitl.world.camera.world import (ANY_FAMILY, FAMILIES, HELDOUT_FAMILIES, TRAINING_FAMILIES, CameraWorld, WorldSpec,
                                     build_world, family_of)
from sitl.world.scenario import Scenario, ScenarioError

CAM = CameraModel(width_px=320, height_px=240)
LOOK = Rotation.from_euler("ZY", [math.radians(60), math.radians(5)])  # toward the north-east, nose a little down
DRONE = TargetPose("s1000", np.array([6.0, 30.0, 31.0]), attitude_from_velocity(np.array([2.0, 1.0, 0.0])))


def _frame(world: CameraWorld, t: float = 3.0, targets=(DRONE,), camera: CameraModel = CAM):
    r = Renderer(camera, world=world, noise_seed=1)
    return r.render(np.array([0.0, 0.0, 30.0]), LOOK, list(targets), world.lighting, np.random.default_rng(0), t=t)


@pytest.fixture(scope="module")
def meadow() -> CameraWorld:
    return build_world(WorldSpec("meadow"), seed=11, width_px=CAM.width_px, height_px=CAM.height_px)


def test_the_plain_world_renders_exactly_as_the_plain_field():
    world = build_world(WorldSpec(), seed=7)
    old = Renderer(CAM, world.ground, noise_seed=1).render(np.array([0.0, 0.0, 30.0]), LOOK, [DRONE], world.lighting,
                                                          np.random.default_rng(0))
    assert np.array_equal(old.image, _frame(world).image) and old.labels == _frame(world).labels


def test_a_world_is_the_same_for_a_seed_and_differs_between_seeds(meadow):
    again = build_world(WorldSpec("meadow"), seed=11, width_px=CAM.width_px, height_px=CAM.height_px)
    assert np.array_equal(_frame(meadow).image, _frame(again).image)
    other = build_world(WorldSpec("meadow"), seed=12, width_px=CAM.width_px, height_px=CAM.height_px)
    assert np.abs(_frame(meadow).image.astype(int) - _frame(other).image.astype(int)).mean() > 10


def test_every_family_renders_with_the_target_labelled_where_it_is_drawn():
    for name in FAMILIES:
        world = build_world(WorldSpec(name), seed=3, width_px=CAM.width_px, height_px=CAM.height_px)
        frame = _frame(world)
        assert frame.image.shape == (CAM.height_px, CAM.width_px, 3), name
        (label,) = frame.labels
        bare = _frame(world, targets=())
        x0, y0, x1, y1 = (int(round(v)) for v in label.box)
        diff = np.abs(frame.image.astype(int) - bare.image.astype(int)).sum(axis=2)
        assert diff[y0:y1 + 1, x0:x1 + 1].max() > 60, name  # the drone is in its box
        outside = diff.copy()
        outside[max(y0 - 3, 0):y1 + 4, max(x0 - 3, 0):x1 + 4] = 0
        assert outside.max() < 60, name  # and nowhere else (JPEG ringing aside)


def test_held_out_families_share_no_ground_material_sky_or_look_with_training():
    def materials(name: str) -> set[str]:
        style = FAMILIES[name].ground
        return set(style.materials) | ({"water"} if style.ponds > 0 else set())

    train = set().union(*(materials(f) for f in TRAINING_FAMILIES))
    for name in HELDOUT_FAMILIES:
        assert not materials(name) & train, name
        fam = FAMILIES[name]
        assert all((fam.sky_zenith, fam.sky_horizon) != (FAMILIES[f].sky_zenith, FAMILIES[f].sky_horizon) for f in TRAINING_FAMILIES)
        assert fam.cloud_cover[0] > max(FAMILIES[f].cloud_cover[1] for f in TRAINING_FAMILIES if f != "winter") - 0.1
        assert fam.birds == 0 and fam.aircraft == 0 and fam.power_lines == 0  # only flocks; no lone birds, planes, lines
    assert set(TRAINING_FAMILIES) | set(HELDOUT_FAMILIES) == set(FAMILIES)
    assert set(MATERIALS) >= train | set().union(*(materials(f) for f in HELDOUT_FAMILIES))


def test_distractors_are_drawn_but_never_labelled(meadow):
    quiet = dataclasses.replace(meadow, birds=(), aircraft=(), specks=None)
    bird = Bird(centre_enu=(0.0, 0.0, 31.0), radius_m=20.0, speed_mps=0.0, phase=math.radians(60), span_m=1.2,
                flap_hz=3.0, colour=(30, 30, 30))
    with_bird = dataclasses.replace(quiet, birds=(bird,))
    a, b = _frame(quiet), _frame(with_bird)
    assert a.labels == b.labels
    px, _ = Renderer(CAM, world=quiet)._project(CAM.camera_to_enu(LOOK).as_matrix(),
                                                 CAM.position_enu(np.array([0.0, 0.0, 30.0]), LOOK), bird.position(3.0)[None])
    x, y = (int(round(v)) for v in px[0])
    assert 0 <= x < CAM.width_px and 0 <= y < CAM.height_px
    diff = np.abs(a.image.astype(int) - b.image.astype(int)).sum(axis=2)
    assert diff[max(y - 3, 0):y + 4, max(x - 3, 0):x + 4].max() > 60  # the bird is where its path puts it


def test_a_bird_flaps():
    bird = Bird((-20.0, 0.0, 30.0), 20.0, 0.0, 0.0, 1.0, 2.0, (0, 0, 0))  # phase 0: at the centre + 20 m east
    # Static in place (speed 0): between flaps only the wings move; the body stays.
    assert np.allclose(bird.position(0.0), bird.position(0.37))
    img_a, img_b = np.full((240, 320, 3), 200, np.uint8), np.full((240, 320, 3), 200, np.uint8)
    def project(p):
        c = np.asarray(p, float) - [0.0, -15.0, 30.0]  # a camera 15 m south looking north (x right, z up)
        return np.stack([160 + 400 * c[:, 0] / c[:, 1], 120 - 400 * c[:, 2] / c[:, 1]], axis=1), c[:, 1]
    bird.draw(img_a, project, 400.0, 0.0)
    bird.draw(img_b, project, 400.0, 0.125)  # a quarter flap later (2 Hz)
    assert (img_a < 100).any() and not np.array_equal(img_a, img_b)



def test_birds_are_placed_and_their_wings_drawn_where_their_paths_put_them():
    # By hand: centre (0, 0, 30), radius 20, 10 m/s, phase 0: at t = pi s the angle is 10 pi / 20 = pi / 2,
    # so the body is 20 m north of the centre and 2 sin(0.3 pi / 2) m up.
    a = Bird((0.0, 0.0, 30.0), 20.0, 10.0, 0.0, 2.0, 0.25, (0, 0, 0))
    b = Bird((5.0, -3.0, 40.0), 50.0, 0.0, math.pi, 1.0, 2.0, (0, 0, 0))  # still, due west of its centre
    flock = Birds((a, b))
    np.testing.assert_allclose(flock.positions(math.pi), [[0.0, 20.0, 30.0 + 2.0 * math.sin(0.15 * math.pi)],
                                                          [-45.0, -3.0, 40.0 + 2.0 * math.sin(0.3 * math.pi)]], atol=1e-12)
    # Wings: a flap phase of 0 at t = 0 (7 x phase 0) lays them level, across the flight along the radius:
    # bird a at angle 0 is east of its centre, so its tips are 1 m east and west of the body at 30 m.
    seen = []
    def project(p):
        seen.append(np.asarray(p, float).copy())
        c = np.asarray(p, float) - [20.0, -30.0, 30.0]  # a camera 30 m south of bird a, looking north
        return np.stack([160 + 400 * c[:, 0] / c[:, 1], 120 - 400 * c[:, 2] / c[:, 1]], axis=1), c[:, 1]
    img = np.full((240, 320, 3), 200, np.uint8)
    flock.draw(img, project, 400.0, 0.0, which=[0])
    np.testing.assert_allclose(seen[0], [[19.0, 0.0, 30.0], [20.0, 0.0, 30.0], [21.0, 0.0, 30.0]], atol=1e-12)
    dark = np.argwhere(img[..., 0] < 100)  # a level stroke 2 m wide at 30 m: 400 * 2 / 30 = 27 px across the centre
    assert abs(dark[:, 0].mean() - 120) < 1.5 and dark[:, 1].min() < 148 and dark[:, 1].max() > 172

def test_filtering_with_distance_calms_the_far_ground(meadow):
    low = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
    level = Rotation.from_euler("Z", math.radians(60))  # level flight: the horizon across the middle
    unfiltered = dataclasses.replace(meadow, ground=dataclasses.replace(meadow.ground, far_texture=None, detail=None),
                                     birds=(), aircraft=(), specks=None, effects=None, props=())
    calm = dataclasses.replace(unfiltered, ground=dataclasses.replace(meadow.ground, detail=None))
    def far_band_detail(world):
        r = Renderer(low, world=world, noise_seed=1)
        img = r.render(np.array([0.0, 0.0, 20.0]), level, [], dataclasses.replace(world.lighting, noise_sigma=0.0,
                       jpeg_quality=0), np.random.default_rng(0)).image
        # Rows 127-140 below the horizon (row 120): the ground 460 m to 150 m out, 2-6 texels a pixel.
        band = cv2.cvtColor(img[127:140], cv2.COLOR_BGR2GRAY)
        return float(np.abs(cv2.Laplacian(band.astype(np.float32), cv2.CV_32F)).mean())
    assert far_band_detail(calm) < 0.8 * far_band_detail(unfiltered)


def test_periodic_noise_tiles_without_a_seam():
    tile = periodic_fractal_noise(np.random.default_rng(0), 128, (4, 8, 16))
    across = np.abs(tile[:, 0] - tile[:, -1]).mean()  # the step from the last column back to the first
    inside = np.abs(np.diff(tile, axis=1)).mean()
    assert across < 2.0 * inside


def test_vignetting_is_one_at_the_centre_and_one_minus_strength_at_the_corners():
    v = vignette_map(101, 51, 0.3)
    assert v[25, 50] == pytest.approx(1.0, abs=1e-3)
    # corner pixel centre (0, 0): r^2 = (50.5^2 + 25.5^2) / (0.25 (101^2 + 51^2)) = 0.9997; gain 1 - 0.3 * r^3
    r2 = (50.5**2 + 25.5**2) / (0.25 * (101**2 + 51**2))
    assert v[0, 0] == pytest.approx(1.0 - 0.3 * r2**1.5, abs=1e-4)


def test_exposure_and_white_balance_drift_smoothly_around_one():
    fx = CameraEffects(exposure_sigma=0.1, white_balance_sigma=0.05, drift_period_s=20.0, seed=4)
    logs = np.log([fx.gains(t) for t in np.arange(0.0, 4000.0, 0.5)])
    assert fx.gains(12.5) == fx.gains(12.5)  # a function of time alone
    assert np.abs(logs.mean(axis=0)).max() < 0.03
    # each channel's log gain: exposure + its own balance, unit-variance waves: sigma = sqrt(0.1^2 + 0.05^2)
    assert logs.std(axis=0) == pytest.approx([math.hypot(0.1, 0.05)] * 3, rel=0.25)
    # No jumps: each log gain is a sum of 3 + 3 sinusoids at <= 2 cycles a period, so it moves at most
    # (0.1 + 0.05) * 3 * (2 * 2 pi / 20 s) / sqrt(1.5) = 0.23 a second: 0.115 in half a second.
    bound = (0.1 + 0.05) * 3 * (2 * 2 * math.pi / 20.0) / math.sqrt(1.5) * 0.5
    assert np.abs(np.diff(logs, axis=0)).max() <= bound


def test_scenario_chooses_the_camera_world_and_names_bad_keys():
    base = {"name": "w", "home": {"lat_deg": 42.0, "lon_deg": -71.0}}
    assert Scenario.from_dict(base).camera_world == WorldSpec()
    sc = Scenario.from_dict({**base, "camera_world": {"family": "coast", "seed": 5, "distractors": False}})
    assert sc.camera_world == WorldSpec("coast", 5, distractors=False)
    for bad, where in (({"family": "forest"}, "camera_world.family"), ({"seed": -1}, "camera_world.seed"),
                       ({"effects": "yes"}, "camera_world.effects"), ({"sky": 1}, "camera_world")):
        with pytest.raises(ScenarioError, match=where.replace(".", r"\.")):
            Scenario.from_dict({**base, "camera_world": bad})


def test_the_any_world_visits_every_family_and_is_that_familys_world():
    assert sorted(family_of(s) for s in range(10, 17)) == sorted(FAMILIES)  # any seven consecutive seeds
    for seed in (5, 9):
        drawn = build_world(WorldSpec(ANY_FAMILY), seed=seed, width_px=CAM.width_px, height_px=CAM.height_px)
        named = build_world(WorldSpec(family_of(seed)), seed=seed, width_px=CAM.width_px, height_px=CAM.height_px)
        assert drawn.name == family_of(seed)
        assert np.array_equal(_frame(drawn).image, _frame(named).image)
    base = {"name": "w", "home": {"lat_deg": 42.0, "lon_deg": -71.0}}
    assert Scenario.from_dict({**base, "camera_world": {"family": "any"}}).camera_world == WorldSpec(ANY_FAMILY)


def test_parts_of_a_world_can_be_left_out():
    spec = WorldSpec("farmland", clutter=False, distractors=False, effects=False)
    world = build_world(spec, seed=2)
    assert world.props == () and world.birds == () and world.aircraft == () and world.specks is None and world.effects is None
    full = build_world(WorldSpec("farmland"), seed=2)
    assert full.props and full.effects is not None and full.ground is world.ground  # the same ground, made once


@pytest.mark.parametrize("family", ["farmland", "suburb", "coast"])
def test_fields_painted_by_bounding_box_equal_the_field_by_field_brute_force(family):
    # The painter finds each field's bounding box in one pass; the brute force masks the whole image for
    # every field. The same layout and the same rng draws in the same order must give the same image.
    from sitl.world.camera.fields import _field_layout, _paint_fields

    style = dataclasses.replace(FAMILIES[family].ground, field_m=(10.0, 30.0))  # many fields on a small image
    cell, kinds = _field_layout(style, np.random.default_rng(5), 256)
    assert len(kinds) > 20
    fast = _paint_fields(cell, kinds, style, np.random.default_rng(9))
    rng = np.random.default_rng(9)
    slow = np.zeros((256, 256, 3), np.float32)
    for k, kind in enumerate(kinds):
        mask = cell == k
        if not mask.any():
            continue
        rows, cols = np.nonzero(mask)
        r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
        patch = MATERIALS[kind](rng, int(max(r1 - r0, c1 - c0)), rng.uniform(0, math.pi), rng.uniform(*style.dryness))
        slow[mask] = patch[: r1 - r0, : c1 - c0][mask[r0:r1, c0:c1]]
    np.testing.assert_array_equal(fast, slow)
