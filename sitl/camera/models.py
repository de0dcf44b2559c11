"""Target airframes for the rendered camera, to scale, as spheres, rods and rotor discs in FLU body metres.

Sizes follow the real aircraft: the DJI S1000 octocopter (1045 mm motor-to-motor, 15-inch
propellers, landing gear below) that the paper chased, and a Phantom-like quadcopter (350 mm
diagonal, 9.4-inch propellers, white shell). Primitives that look right from any side keep the
drawing simple: a sphere is a circle, a rod a thick line, a disc a projected 12-gon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


__all__ = ["Part", "TargetModel", "TARGET_MODELS", "model_for"]


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


TARGET_MODELS: dict[str, TargetModel] = {m.kind: m for m in (_octocopter(), _quadcopter())}


def model_for(kind: str) -> TargetModel:
    """The model for ``kind``, or a ValueError listing the known kinds."""
    try:
        return TARGET_MODELS[kind]
    except KeyError:
        raise ValueError(f"unknown target kind {kind!r}; known: {sorted(TARGET_MODELS)}") from None
