"""Camera worlds: what the rendered camera looks at, chosen by family and randomised by seed.

A *family* fixes the kind of place (its ground materials and clutter, its skies, its distractors,
its camera): ``meadow``, ``farmland``, ``arid``, ``winter`` and ``suburb`` are for training;
``coast`` and ``moor`` share no ground material, sky style or distractor look with them and are kept
out of training, so a detector can be scored on a world it has never seen. ``plain`` is the
original smooth procedural field (:func:`sitl.world.camera.scene.make_ground`) for quick tests;
``any`` draws one of the seven families from the seed (:func:`family_of`), so a campaign over seeds
flies over every kind of place, the held-out ones included.

A scenario names its world with the ``camera_world`` key (``sitl/scenarios/README.md``); a seed
lays out the ground, picks the weather and places every distractor. A scenario's ``lighting`` keys
(:class:`~sitl.world.camera.lighting.LightingOverride`, carried in :attr:`WorldSpec.lighting`) then
replace the sun and the overcast the seed drew; everything else the seed draws stays as it was.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from sitl.world.camera.distractors import Aircraft, Bird, LensSpecks, make_aircraft, make_birds
from sitl.world.camera.effects import CameraEffects
from sitl.world.camera.fields import GroundStyle, make_field_ground
from sitl.world.camera.props import PowerLine, make_power_lines
from sitl.world.camera.lighting import Lighting, LightingOverride
from sitl.world.camera.scene import GroundScene, make_ground
from sitl.world.camera.sky import Sky, make_sky

__all__ = ["Family", "FAMILIES", "TRAINING_FAMILIES", "HELDOUT_FAMILIES", "ANY_FAMILY", "WorldSpec", "CameraWorld",
           "build_world", "family_of", "PLAIN_FIELD_SEED", "plain_ground"]

#: The plain field every rehearsal flew over before camera worlds (``camera_world`` without a seed).
PLAIN_FIELD_SEED = 7


@dataclass(frozen=True)
class Family:
    """A kind of place.

    Args:
        ground: its ground (:class:`GroundStyle`).
        cloud_cover: range of cloud cover; sky_zenith / sky_horizon: BGR of the clear sky.
        sun_elevation_deg: range of the sun's height; haze_m: range of the visibility distance.
        brightness: range of exposure; glare: the sun's bloom strength.
        birds, flocks, aircraft, power_lines: counts over the 1 km field.
        specks: dirt spots on the lens; effects: exposure and white-balance drift, vignetting.
    """

    ground: GroundStyle
    cloud_cover: tuple[float, float] = (0.0, 0.6)
    sky_zenith: tuple[float, float, float] = (200.0, 140.0, 90.0)
    sky_horizon: tuple[float, float, float] = (235.0, 215.0, 200.0)
    sun_elevation_deg: tuple[float, float] = (20.0, 65.0)
    haze_m: tuple[float, float] = (600.0, 1500.0)
    brightness: tuple[float, float] = (0.8, 1.15)
    glare: float = 1.0
    birds: int = 6
    flocks: int = 1
    aircraft: int = 1
    power_lines: int = 1
    specks: int = 3
    effects: CameraEffects = field(default_factory=CameraEffects)


_TREE_DARK = (30, 55, 30)
FAMILIES: dict[str, Family] = {
    "meadow": Family(GroundStyle({"grass": 5.0, "lawn": 1.0, "crop": 1.0}, dryness=(0.0, 0.4), buildings=1.0)),
    "farmland": Family(GroundStyle({"crop": 3.0, "soil": 2.0, "grass": 2.0}, dryness=(0.1, 0.8), field_m=(60, 250),
                                   tracks=4.0, trees=30.0, tree_lines=8.0), power_lines=2, flocks=2),
    "arid": Family(GroundStyle({"sand": 3.0, "gravel": 2.0, "soil": 1.0, "grass": 0.5}, dryness=(0.7, 1.0),
                               trees=5.0, tree_lines=0.0, bushes=300.0, buildings=1.0, roads=2.0),
                   cloud_cover=(0.0, 0.2), sky_zenith=(210.0, 160.0, 110.0), haze_m=(400.0, 900.0),
                   brightness=(0.95, 1.25), birds=3, flocks=0),
    "winter": Family(GroundStyle({"snow": 5.0, "soil": 0.5, "grass": 0.5}, dryness=(0.3, 0.7), trees=80.0,
                                 tree_colour=_TREE_DARK, cars=6.0),
                     cloud_cover=(0.3, 0.9), sky_zenith=(190.0, 170.0, 150.0), sun_elevation_deg=(8.0, 30.0),
                     brightness=(0.75, 1.0), birds=4),
    "suburb": Family(GroundStyle({"lawn": 3.0, "asphalt": 1.5, "grass": 1.0, "gravel": 0.5}, field_m=(25, 80),
                                 roads=8.0, buildings=40.0, cars=40.0, fences=30.0, trees=120.0, tree_lines=2.0),
                     power_lines=3, aircraft=2),
    # Held out of training: no ground material, sky, clutter or distractor look in common with the above.
    "coast": Family(GroundStyle({"water": 2.0, "rock": 2.0}, dryness=(0.0, 0.0), field_m=(80, 300),
                                roads=0.0, tracks=0.0, ponds=6.0, trees=0.0, tree_lines=0.0, bushes=0.0,
                                buildings=0.0, fences=0.0, cars=0.0),
                    cloud_cover=(0.85, 1.0), sky_zenith=(175.0, 170.0, 165.0), sky_horizon=(205.0, 205.0, 200.0),
                    haze_m=(300.0, 700.0), glare=0.3, birds=0, flocks=3, aircraft=0, power_lines=0,
                    effects=CameraEffects(exposure_sigma=0.2, white_balance_sigma=0.08, vignetting=0.35)),
    "moor": Family(GroundStyle({"heather": 3.0, "rock": 1.0, "water": 0.5}, dryness=(0.0, 0.0), field_m=(100, 400),
                               roads=0.0, tracks=1.0, ponds=3.0, trees=0.0, tree_lines=0.0, bushes=0.0,
                               buildings=0.0, fences=10.0, cars=0.0),
                   cloud_cover=(0.9, 1.0), sky_zenith=(160.0, 150.0, 145.0), sky_horizon=(190.0, 185.0, 185.0),
                   sun_elevation_deg=(10.0, 35.0), haze_m=(250.0, 600.0), glare=0.2, birds=0, flocks=4, aircraft=0,
                   power_lines=0, effects=CameraEffects(exposure_sigma=0.2, white_balance_sigma=0.08, vignetting=0.35)),
}
TRAINING_FAMILIES = ("meadow", "farmland", "arid", "winter", "suburb")
HELDOUT_FAMILIES = ("coast", "moor")
ANY_FAMILY = "any"  # a family drawn per seed: family_of


@dataclass(frozen=True)
class WorldSpec:
    """A scenario's ``camera_world``: a family, the seed of its layout (None: the run's seed), and
    which parts to leave out (clutter above the ground, distractors, camera effects); ``lighting``:
    the scenario's ``lighting`` keys over what the seed draws (None: the seed's lighting)."""

    family: str = "plain"
    seed: int | None = None
    clutter: bool = True
    distractors: bool = True
    effects: bool = True
    lighting: LightingOverride | None = None


@dataclass(frozen=True)
class CameraWorld:
    """Everything the renderer draws besides the targets, and the lighting it draws them in."""

    name: str
    ground: GroundScene
    lighting: Lighting
    sky: Sky | None = None
    props: tuple[PowerLine, ...] = ()
    birds: tuple[Bird, ...] = ()
    aircraft: tuple[Aircraft, ...] = ()
    specks: LensSpecks | None = None
    effects: CameraEffects | None = None


def build_world(spec: WorldSpec, seed: int, width_px: int = 640, height_px: int = 480) -> CameraWorld:
    """The world of ``spec`` laid out by ``spec.seed`` (or ``seed``); the plain world without a seed of its
    own is the one field of :data:`PLAIN_FIELD_SEED`, whatever the run's seed."""
    if spec.family == "plain":
        lighting = Lighting() if spec.lighting is None else spec.lighting.apply(Lighting())
        return CameraWorld("plain", plain_ground(PLAIN_FIELD_SEED if spec.seed is None else spec.seed), lighting)
    s = spec.seed if spec.seed is not None else seed
    if spec.family == ANY_FAMILY:
        spec = replace(spec, family=family_of(s))
    if spec.family not in FAMILIES:
        raise ValueError(f"camera world family {spec.family!r}: one of plain, {ANY_FAMILY}, {', '.join(FAMILIES)}")
    fam = FAMILIES[spec.family]
    rng = np.random.default_rng([s, 0xca3])
    sun_az = float(rng.uniform(0, 2 * math.pi))
    sun_el = math.radians(float(rng.uniform(*fam.sun_elevation_deg)))
    lighting = Lighting(sun_azimuth_rad=sun_az, sun_elevation_rad=sun_el, brightness=float(rng.uniform(*fam.brightness)),
                        haze_m=float(rng.uniform(*fam.haze_m)), sky_zenith=fam.sky_zenith, sky_horizon=fam.sky_horizon,
                        noise_sigma=float(rng.uniform(2.0, 5.0)), jpeg_quality=int(rng.integers(70, 92)))
    if spec.lighting is None:
        ground = _field_ground(spec.family, s, round(sun_az, 6))
        sky = make_sky(rng, float(rng.uniform(*fam.cloud_cover)), fam.sky_zenith, fam.sky_horizon, fam.glare)
    else:  # the seed's draws as without the keys, then the keys over them
        lighting = spec.lighting.apply(lighting)
        overcast = lighting.overcast
        ground = _field_ground(spec.family, s, round(lighting.sun_azimuth_rad, 6), 1.0 - overcast)
        sky = make_sky(rng, float(rng.uniform(*fam.cloud_cover)), fam.sky_zenith, fam.sky_horizon, fam.glare)
        if overcast > 0.0:
            sky = replace(sky, cloud_cover=max(sky.cloud_cover, overcast), glare=sky.glare * (1.0 - overcast),
                          zenith=lighting.sky_zenith, horizon=lighting.sky_horizon)
    half = ground.half_extent_m
    world = CameraWorld(spec.family, ground, lighting, sky)
    if spec.clutter:
        world = replace(world, props=tuple(make_power_lines(rng, fam.power_lines, half)))
    if spec.distractors:
        world = replace(world, birds=tuple(make_birds(rng, fam.birds, fam.flocks, 0.5 * half)),
                        aircraft=tuple(make_aircraft(rng, fam.aircraft)),
                        specks=LensSpecks.random(rng, fam.specks, width_px, height_px))
    if spec.effects:
        world = replace(world, effects=replace(fam.effects, seed=int(rng.integers(2**31))))
    return world


def family_of(seed: int) -> str:
    """The family the ``any`` world takes for ``seed``: seed modulo seven, in :data:`FAMILIES` order, so
    any seven consecutive seeds visit every family once."""
    names = tuple(FAMILIES)
    return names[seed % len(names)]


@functools.lru_cache(maxsize=4)
def plain_ground(seed: int) -> GroundScene:
    """The plain field of ``seed``, made once per process (it takes a second or two)."""
    return make_ground(seed)


@functools.lru_cache(maxsize=4)
def _field_ground(family: str, seed: int, sun_azimuth_rad: float, shadow_scale: float = 1.0) -> GroundScene:
    """Grounds take a second or two to make: campaigns in one process share them."""
    return make_field_ground(FAMILIES[family].ground, seed, sun_azimuth_rad, shadow_scale=shadow_scale)
