"""The scenario's ``lighting`` keys: the sun and the overcast reach the renderer's Lighting, and nothing else moves."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel
from sitl.world.camera.fields import make_field_ground
from sitl.world.camera.lighting import OVERCAST_GREY, Lighting, LightingOverride, sun_share
from sitl.world.camera.models import model_for
from sitl.world.camera.renderer import compile_model, draw_model
from sitl.world.camera.world import FAMILIES, WorldSpec, build_world
from sitl.world.scenario import Scenario, ScenarioError

HOME = {"lat_deg": 42.5, "lon_deg": -71.6, "alt_m": 80.0}


def test_lighting_keys_parse_into_the_camera_world():
    s = Scenario.from_dict({"home": HOME, "lighting": {"sun_elevation_deg": 30, "sun_azimuth_deg": 630, "overcast": 0.5},
                            "camera_world": {"family": "plain", "seed": 3}})
    assert s.lighting == LightingOverride(30.0, 270.0, 0.5) and s.camera_world.lighting is s.lighting
    assert s.camera_world.seed == 3
    assert Scenario.from_dict({"home": HOME}).camera_world == WorldSpec()  # absent: as before
    assert Scenario.from_dict({"home": HOME, "lighting": {}}).camera_world == WorldSpec()


def test_compass_azimuth_becomes_the_renderer_s_enu_azimuth():
    for compass, east_ccw in ((0.0, 90.0), (90.0, 0.0), (180.0, 270.0), (270.0, 180.0)):
        world = build_world(WorldSpec(lighting=LightingOverride(sun_elevation_deg=30.0, sun_azimuth_deg=compass)), 0)
        lit = world.lighting
        assert math.degrees(lit.sun_azimuth_rad) == pytest.approx(east_ccw)
        assert math.degrees(lit.sun_elevation_rad) == pytest.approx(30.0)
        bearing = math.degrees(math.atan2(lit.sun_enu()[0], lit.sun_enu()[1])) % 360.0  # where the sun is, compass
        assert bearing == pytest.approx(compass, abs=1e-9) or bearing == pytest.approx(compass + 360.0, abs=1e-9)
        assert lit.sun_enu()[2] == pytest.approx(0.5)
    assert build_world(WorldSpec(), 0).lighting == Lighting()  # the plain world without keys: unchanged


def test_a_key_left_out_keeps_what_the_seed_drew():
    spec = WorldSpec("arid", seed=5, distractors=False, effects=False, clutter=False)
    drawn = build_world(spec, 0).lighting
    keyed = build_world(dataclasses.replace(spec, lighting=LightingOverride(sun_elevation_deg=12.0)), 0).lighting
    assert keyed == dataclasses.replace(drawn, sun_elevation_rad=math.radians(12.0))


def test_overcast_takes_the_direct_sun_away():
    # a surface facing the sun gets all of it in clear sky, half of it fully overcast; one facing away none, and half
    assert (sun_share(1.0, 0.0), sun_share(-0.5, 0.0)) == (1.0, 0.0)
    assert (sun_share(1.0, 1.0), sun_share(-1.0, 1.0)) == (0.5, 0.5)
    assert sun_share(0.8, 0.5) == pytest.approx(0.5 * 0.8 + 0.25)
    lit = LightingOverride(overcast=1.0).apply(Lighting())
    assert lit.overcast == 1.0 and lit.sky_zenith == OVERCAST_GREY and lit.sky_horizon == OVERCAST_GREY
    half = LightingOverride(overcast=0.5).apply(Lighting())
    assert half.sky_zenith == pytest.approx(tuple(0.5 * (a + b) for a, b in zip(Lighting().sky_zenith, OVERCAST_GREY)))


def test_overcast_evens_the_light_on_a_rendered_target():
    cam = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)
    model = compile_model(model_for("s1000"))
    sun = Lighting(sun_elevation_rad=math.radians(60.0)).sun_enu()
    r_ce = cam.camera_to_enu(Rotation.identity()).as_matrix()
    c_enu = cam.position_enu(np.array([0.0, 0.0, 30.0]), Rotation.identity())

    def drawn(overcast: float) -> float:
        img = np.zeros((240, 320, 3), np.uint8)  # on black every pixel, edges and discs too, scales with the shade
        draw_model(img, model, np.eye(3), np.array([12.0, 0.0, 30.0]), r_ce, c_enu, cam.focal_px, sun, 1.0, overcast)
        return float(img.astype(int).sum())

    # level, so its top faces the sun at sin 60 deg = 0.866: shade 0.55 + 0.45 * 0.866 in clear sky,
    # 0.55 + 0.45 * 0.5 under full cloud
    want = (0.55 + 0.45 * 0.5) / (0.55 + 0.45 * math.sin(math.radians(60.0)))
    assert drawn(1.0) / drawn(0.0) == pytest.approx(want, rel=0.01)


def test_overcast_shortens_the_shadows_and_clouds_the_sky():
    style = FAMILIES["suburb"].ground
    shadow = np.array([25, 30, 35])  # a building's shadow

    def shadowed(scale: float) -> int:
        tex = make_field_ground(style, 3, 0.7, size_px=512, shadow_scale=scale).texture.astype(int)
        return int((np.abs(tex - shadow).sum(axis=2) <= 6).sum())

    full, half, none = shadowed(1.0), shadowed(0.5), shadowed(0.0)
    assert full > 300 and none == 0 and 0.3 * full < half < 0.8 * full
    spec = WorldSpec("meadow", seed=11, distractors=False, effects=False, clutter=False)
    clear = build_world(spec, 0)
    cloudy = build_world(dataclasses.replace(spec, lighting=LightingOverride(overcast=0.8)), 0)
    assert cloudy.sky.cloud_cover == max(clear.sky.cloud_cover, 0.8)
    assert cloudy.sky.glare == pytest.approx(0.2 * clear.sky.glare)
    assert cloudy.lighting.sun_azimuth_rad == clear.lighting.sun_azimuth_rad and cloudy.lighting.overcast == 0.8
    assert not np.array_equal(cloudy.ground.texture, clear.ground.texture)  # its shadows shortened


@pytest.mark.parametrize("lighting, path, expected", [
    ({"sun_elevation_deg": 95}, "lighting.sun_elevation_deg", "[0, 90]"),
    ({"sun_elevation_deg": "high"}, "lighting.sun_elevation_deg", "finite number"),
    ({"overcast": 1.5}, "lighting.overcast", "[0, 1]"),
    ({"overcast": -0.1}, "lighting.overcast", ">= 0.0"),
    ({"sun_az_deg": 10}, "lighting.sun_az_deg", "did you mean sun_azimuth_deg"),
    ([30, 120], "lighting", "a mapping"),
])
def test_bad_lighting_names_its_key_path(lighting, path, expected):
    with pytest.raises(ScenarioError) as e:
        Scenario.from_dict({"home": HOME, "lighting": lighting}, source="<l>")
    assert str(e.value).startswith(f"<l>: {path}") and expected in str(e.value)
