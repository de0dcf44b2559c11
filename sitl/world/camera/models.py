"""Targets for the rendered camera, to scale, as spheres, rods and rotor discs in FLU body metres.

Sizes follow the real aircraft: the DJI S1000 octocopter (1045 mm motor-to-motor, 15-inch
propellers, landing gear below) that the paper chased, and a Phantom-like quadcopter (350 mm
diagonal, 9.4-inch propellers, white shell). For search and rescue, a 1.75 m person (kind
"person") with its feet at the body origin and its head up body +z, in a few clothing colours
(``variant``): standing it is drawn with a yaw-only attitude, lying with the body rolled 90 deg.
Primitives that look right from any side keep the drawing simple: a sphere is a circle, a rod a
thick line, a disc a projected 12-gon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["Part", "TargetModel", "TARGET_MODELS", "PERSON_VARIANTS", "PERSON_HEIGHT_M", "model_for", "variant_count",
           "random_multirotor", "random_person"]


@dataclass(frozen=True)
class Part:
    """One primitive: ``shape`` "sphere" (centre a, radius), "rod" (a to b, radius) or "disc" (centre a, radius, horizontal)."""

    shape: str
    a: tuple[float, float, float]
    radius: float
    colour: tuple[int, int, int]  # BGR
    b: tuple[float, float, float] = (0.0, 0.0, 0.0)
    alpha: float = 1.0


@dataclass(frozen=True)
class TargetModel:
    """A named airframe: its parts and its span (the largest horizontal extent, m) for ranging."""

    kind: str
    parts: tuple[Part, ...]
    span_m: float
    height_m: float


def _octocopter() -> TargetModel:
    parts: list[Part] = []
    arm_r = 0.5225
    for k in range(8):
        a = (k + 0.5) * math.pi / 4
        tip = (arm_r * math.cos(a), arm_r * math.sin(a), 0.0)
        parts.append(Part("rod", (0.0, 0.0, 0.0), 0.014, (30, 30, 35), b=tip))
        parts.append(Part("sphere", (tip[0], tip[1], 0.03), 0.035, (20, 20, 25)))
        parts.append(Part("disc", (tip[0], tip[1], 0.07), 0.19, (70, 70, 75), alpha=0.45))
    parts.append(Part("sphere", (0.0, 0.0, 0.0), 0.13, (35, 35, 40)))
    parts.append(Part("sphere", (0.0, 0.0, 0.07), 0.08, (40, 40, 170)))  # red top cover
    parts.append(Part("sphere", (0.05, 0.0, -0.12), 0.06, (40, 40, 45)))  # gimbal camera
    for side in (-1.0, 1.0):
        parts.append(Part("rod", (0.0, side * 0.12, -0.02), 0.012, (200, 200, 200), b=(0.0, side * 0.22, -0.38)))
        parts.append(Part("rod", (-0.22, side * 0.22, -0.38), 0.012, (200, 200, 200), b=(0.22, side * 0.22, -0.38)))
    return TargetModel("s1000", tuple(parts), span_m=1.045 + 0.38, height_m=0.45)


def _quadcopter() -> TargetModel:
    parts: list[Part] = []
    arm_r = 0.175
    white = (235, 235, 240)
    for k in range(4):
        a = (k + 0.5) * math.pi / 2
        tip = (arm_r * math.cos(a), arm_r * math.sin(a), 0.0)
        parts.append(Part("rod", (0.0, 0.0, 0.0), 0.018, white, b=tip))
        parts.append(Part("sphere", (tip[0], tip[1], 0.015), 0.022, (60, 60, 60)))
        parts.append(Part("disc", (tip[0], tip[1], 0.04), 0.12, (170, 170, 175), alpha=0.4))
        parts.append(Part("rod", (tip[0], tip[1], -0.01), 0.008, white, b=(tip[0] * 0.9, tip[1] * 0.9, -0.12)))
    parts.append(Part("sphere", (0.03, 0.0, 0.0), 0.07, white))
    parts.append(Part("sphere", (-0.04, 0.0, 0.0), 0.07, white))
    parts.append(Part("sphere", (0.09, 0.0, -0.06), 0.03, (50, 50, 50)))  # camera
    return TargetModel("phantom", tuple(parts), span_m=0.35 + 0.24, height_m=0.2)


PERSON_HEIGHT_M = 1.75


def _person(shirt: tuple[int, int, int], trousers: tuple[int, int, int], skin: tuple[int, int, int],
            hair: tuple[int, int, int]) -> TargetModel:
    """A 1.75 m adult standing up body +z, feet at the origin, facing body +x (BGR colours)."""
    shoe = (30, 30, 35)
    parts: list[Part] = []
    for side in (-1.0, 1.0):
        parts.append(Part("sphere", (0.05, side * 0.1, 0.05), 0.055, shoe))
        parts.append(Part("rod", (0.0, side * 0.1, 0.08), 0.075, trousers, b=(0.0, side * 0.09, 0.9)))
        parts.append(Part("rod", (0.0, side * 0.21, 1.42), 0.05, shirt, b=(0.04, side * 0.26, 0.9)))  # arm
        parts.append(Part("sphere", (0.05, side * 0.26, 0.84), 0.045, skin))  # hand
    parts.append(Part("rod", (0.0, 0.0, 0.95), 0.17, shirt, b=(0.0, 0.0, 1.38)))  # torso
    parts.append(Part("rod", (0.0, -0.2, 1.42), 0.07, shirt, b=(0.0, 0.2, 1.42)))  # shoulders
    parts.append(Part("sphere", (0.01, 0.0, 1.63), 0.105, skin))  # head
    parts.append(Part("sphere", (-0.02, 0.0, 1.67), 0.095, hair))
    return TargetModel("person", tuple(parts), span_m=0.52, height_m=PERSON_HEIGHT_M)


# Clothing seen in searches: bright jackets, dark outdoor wear, hi-vis, white; BGR.
PERSON_VARIANTS: tuple[TargetModel, ...] = (
    _person((40, 40, 200), (110, 70, 40), (140, 170, 215), (30, 40, 60)),      # red jacket, jeans
    _person((180, 90, 30), (50, 50, 55), (110, 140, 190), (25, 25, 30)),       # blue jacket, dark trousers
    _person((20, 140, 250), (60, 60, 60), (150, 180, 225), (60, 90, 140)),     # orange hi-vis
    _person((50, 90, 50), (90, 120, 140), (90, 110, 150), (20, 20, 25)),       # olive green, khaki
    _person((225, 225, 230), (120, 80, 50), (140, 170, 215), (40, 60, 90)),    # white top, jeans
    _person((40, 220, 230), (40, 40, 45), (70, 90, 120), (20, 20, 20)),        # yellow, black
    _person((45, 45, 50), (45, 45, 50), (140, 170, 215), (120, 160, 200)),     # black clothes
)

TARGET_MODELS: dict[str, TargetModel] = {m.kind: m for m in (_octocopter(), _quadcopter(), PERSON_VARIANTS[0])}
_VARIANTS: dict[str, tuple[TargetModel, ...]] = {"person": PERSON_VARIANTS}


def model_for(kind: str, variant: int = 0) -> TargetModel:
    """The model for ``kind`` (``variant`` picks a colour scheme where a kind has several, modulo their
    number), or a ValueError listing the known kinds."""
    if kind in _VARIANTS:
        options = _VARIANTS[kind]
        return options[variant % len(options)]
    try:
        return TARGET_MODELS[kind]
    except KeyError:
        raise ValueError(f"unknown target kind {kind!r}; known: {sorted(TARGET_MODELS)}") from None


def variant_count(kind: str) -> int:
    """How many colour variants ``kind`` has (1 for the airframes)."""
    model_for(kind)
    return len(_VARIANTS.get(kind, (None,)))


# Finishes of small multirotors (BGR): white and grey shells, black carbon, bright plastics.
_SHELLS = ((235, 235, 240), (200, 200, 205), (150, 150, 155), (90, 90, 95), (35, 35, 40), (40, 40, 190),
           (30, 120, 240), (40, 200, 220), (170, 90, 30), (60, 140, 60))


def random_multirotor(rng: np.random.Generator) -> TargetModel:
    """A multirotor of a random design (kind "multirotor"), for training data that is not two airframes:
    3 (Y6, coaxial), 4, 6 or 8 arms in an X or + layout, 12-75 cm from the centre to a motor, coaxial
    rotor pairs, propeller discs translucent as spinning blades are, a shell of one finish, arms of it
    or of carbon, with or without landing gear (legs or skids) and a payload (gimbal or box) below."""
    arms = int(rng.choice([3, 4, 4, 4, 6, 6, 8]))
    coaxial = arms == 3 or bool(rng.random() < 0.15)
    arm_r = float(np.exp(rng.uniform(np.log(0.12), np.log(0.75))))
    shell = _SHELLS[int(rng.integers(len(_SHELLS)))]
    arm_col = shell if rng.random() < 0.4 else (30, 30, 35)
    motor = (25, 25, 30) if rng.random() < 0.7 else (170, 170, 175)
    prop_r = arm_r * float(rng.uniform(0.35, 0.6)) * (1.0 if arms <= 4 else 0.8)
    prop_col = (60, 60, 65) if rng.random() < 0.6 else (190, 190, 195)
    prop_alpha = float(rng.uniform(0.25, 0.6))
    offset = 0.5 if rng.random() < 0.75 else 0.0  # X or + layout
    parts: list[Part] = []
    for k in range(arms):
        a = (k + offset) * 2.0 * math.pi / arms
        tip = (arm_r * math.cos(a), arm_r * math.sin(a), 0.0)
        parts.append(Part("rod", (0.0, 0.0, 0.0), arm_r * 0.05, arm_col, b=tip))
        parts.append(Part("sphere", (tip[0], tip[1], arm_r * 0.05), arm_r * 0.08, motor))
        for z in ((arm_r * 0.15, -arm_r * 0.1) if coaxial else (arm_r * 0.15,)):
            parts.append(Part("disc", (tip[0], tip[1], z), prop_r, prop_col, alpha=prop_alpha))
    body = arm_r * float(rng.uniform(0.22, 0.4))
    parts.append(Part("sphere", (body * 0.3, 0.0, 0.0), body, shell))
    parts.append(Part("sphere", (-body * 0.3, 0.0, 0.0), body * 0.9, shell))
    height = body * 2
    if rng.random() < 0.5:  # landing gear: four legs or two skids
        drop = arm_r * float(rng.uniform(0.3, 0.6))
        gear = (200, 200, 200) if rng.random() < 0.4 else (30, 30, 35)
        if rng.random() < 0.5:
            for sx in (-1.0, 1.0):
                for sy in (-1.0, 1.0):
                    parts.append(Part("rod", (sx * body * 0.6, sy * body * 0.6, 0.0), arm_r * 0.02, gear,
                                      b=(sx * body * 1.1, sy * body * 1.1, -drop)))
        else:
            for sy in (-1.0, 1.0):
                parts.append(Part("rod", (0.0, sy * body * 0.5, 0.0), arm_r * 0.02, gear, b=(0.0, sy * body, -drop)))
                parts.append(Part("rod", (-body * 1.2, sy * body, -drop), arm_r * 0.02, gear, b=(body * 1.2, sy * body, -drop)))
        height = body + drop
    if rng.random() < 0.5:  # payload: a gimbal camera or a box
        size = body * float(rng.uniform(0.4, 0.8))
        parts.append(Part("sphere", (body * 0.4, 0.0, -body - size * 0.5), size, (40, 40, 45) if rng.random() < 0.6 else shell))
        height = max(height, body + 1.5 * size)
    return TargetModel("multirotor", tuple(parts), span_m=2 * (arm_r + prop_r), height_m=height)


def _random_colour(rng: np.random.Generator) -> tuple[int, int, int]:
    """A clothing colour (BGR): any hue, from washed-out to saturated, dark to light."""
    hsv = np.uint8([[[rng.integers(0, 180), rng.integers(0, 256), rng.integers(30, 250)]]])
    return tuple(int(c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0])


def random_person(rng: np.random.Generator) -> TargetModel:
    """A person of a random build and dress (kind "person"), standing up body +z, feet at the origin, for
    training data beyond the seven fixed ones: 1.55-1.95 m, slim to broad, clothes of any colour
    (trousers or shorts), arms down, out or one raised (waving), sometimes a backpack or a hat."""
    k = float(rng.uniform(1.55, 1.95)) / PERSON_HEIGHT_M
    torso_r = float(rng.uniform(0.13, 0.2))
    shirt, trousers = _random_colour(rng), _random_colour(rng)
    skin = ((140, 170, 215), (110, 140, 190), (70, 90, 120), (50, 65, 95))[int(rng.integers(4))]
    hair = ((25, 25, 30), (30, 50, 80), (60, 100, 150), (170, 170, 175))[int(rng.integers(4))]
    shorts = bool(rng.random() < 0.2)
    spread = float(rng.uniform(0.0, 0.15))
    pose = rng.choice(["down", "down", "out", "wave"])
    parts: list[Part] = []
    for side in (-1.0, 1.0):
        foot = (0.05, side * (0.1 + spread), 0.0)
        parts.append(Part("sphere", (foot[0], foot[1], 0.055), 0.055, (30, 30, 35)))
        if shorts:
            parts.append(Part("rod", (0.0, foot[1], 0.08), 0.06, skin, b=(0.0, side * 0.09, 0.55 * k)))
            parts.append(Part("rod", (0.0, side * 0.09, 0.55 * k), 0.08, trousers, b=(0.0, side * 0.09, 0.9 * k)))
        else:
            parts.append(Part("rod", (0.0, foot[1], 0.08), 0.075, trousers, b=(0.0, side * 0.09, 0.9 * k)))
        shoulder = (0.0, side * (torso_r + 0.04), 1.42 * k)
        if pose == "out" or (pose == "wave" and side > 0):
            hand = (0.05, side * (torso_r + 0.6 * k), (1.45 if pose == "out" else 2.0) * k)
        else:
            hand = (0.04, side * (torso_r + 0.09), 0.9 * k)
        parts.append(Part("rod", shoulder, 0.05, shirt, b=hand))
        parts.append(Part("sphere", hand, 0.045, skin))
    parts.append(Part("rod", (0.0, 0.0, 0.95 * k), torso_r, shirt, b=(0.0, 0.0, 1.38 * k)))
    parts.append(Part("rod", (0.0, -torso_r - 0.03, 1.42 * k), 0.07, shirt, b=(0.0, torso_r + 0.03, 1.42 * k)))
    if rng.random() < 0.3:  # a backpack
        parts.append(Part("sphere", (-torso_r - 0.05, 0.0, 1.2 * k), torso_r * 0.9, _random_colour(rng)))
    parts.append(Part("sphere", (0.01, 0.0, 1.63 * k), 0.105, skin))
    hat = rng.random() < 0.25
    parts.append(Part("sphere", (-0.02, 0.0, 1.67 * k), 0.1 if hat else 0.095, _random_colour(rng) if hat else hair))
    return TargetModel("person", tuple(parts), span_m=0.52, height_m=PERSON_HEIGHT_M * k)
