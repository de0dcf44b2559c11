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

__all__ = ["Part", "TargetModel", "TARGET_MODELS", "PERSON_VARIANTS", "PERSON_HEIGHT_M", "model_for", "variant_count"]


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
