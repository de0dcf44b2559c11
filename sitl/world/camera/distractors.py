"""Things in the sky that look like the target and are not: birds (alone and in flocks, flapping),
distant aircraft, and specks of dirt on the lens.

They are negatives: drawn into the frame, never labelled. Birds and aircraft move on closed-form
paths in time (a circle, a straight leg), so a frame depends only on its time and the world's seed.
A scenario's own birds (``birds:``, :class:`sitl.world.intruders.BirdFlock`) fly in the simulator,
where the radar sees them too; a shot carries them as :class:`BirdPose` and the renderer draws them
the same way (:func:`draw_bird_poses`), unlabelled too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import cv2
import numpy as np

__all__ = ["Bird", "Birds", "BirdPose", "BIRD_LOOKS", "Aircraft", "LensSpecks", "make_birds", "make_aircraft",
           "draw_bird_poses"]

Projector = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]  # ENU (N, 3) -> pixels (N, 2), depth (N,)

#: ((wing span m, flap Hz), BGR colour) of a gull, a crow and a small bird.
BIRD_LOOKS = (((1.2, 3.0), (200, 200, 205)), ((0.9, 4.0), (35, 35, 40)), ((0.3, 10.0), (50, 55, 60)))


@dataclass(frozen=True)
class BirdPose:
    """A bird where the simulator has it now: body position and velocity (ENU), wing span, flapping
    rate and phase, BGR colour."""

    position_enu: tuple[float, float, float]
    velocity_enu: tuple[float, float, float]
    span_m: float
    flap_hz: float
    phase: float
    colour: tuple[int, int, int]


def _draw_wings(img: np.ndarray, project: Projector, focal_px: float, t: float, body: np.ndarray, side: np.ndarray,
                half_span: np.ndarray, flap_hz: np.ndarray, phase: np.ndarray, spans: Sequence[float],
                colours: Sequence[tuple[int, int, int]]) -> None:
    """Draw birds at ``body`` (n, 3) as polylines wing tip - body - wing tip, the wings along ``side``
    (n, 3 unit vectors across the flight) flapping up and down."""
    flap = 0.7 * np.sin(2.0 * np.pi * flap_hz * t + 7.0 * phase)
    across = (half_span * np.cos(flap))[:, None] * side
    lift = np.column_stack([np.zeros((len(body), 2)), half_span * np.sin(flap)])  # both wings up, then down
    pts = np.stack([body - across + lift, body, body + across + lift], axis=1)  # (n, 3 points, 3)
    px, z = project(pts.reshape(-1, 3))
    px, z = px.reshape(-1, 3, 2), z.reshape(-1, 3)
    ok = (z > 1.0).all(axis=1) & np.isfinite(px).all(axis=(1, 2))
    ok[ok] &= np.abs(px[ok]).max(axis=(1, 2)) <= 1e5
    for i in np.flatnonzero(ok):
        width = max(int(round(0.12 * spans[i] * focal_px / z[i, 1])), 1)
        cv2.polylines(img, [np.round(px[i] * 16).astype(np.int32)], False, colours[i], width, cv2.LINE_AA, 4)


def draw_bird_poses(img: np.ndarray, project: Projector, focal_px: float, t: float, birds: Sequence[BirdPose]) -> None:
    """Draw the simulator's birds at time ``t``: as :meth:`Birds.draw` does, the wings across the
    horizontal velocity (east-west for a bird at rest)."""
    if not birds:
        return
    body = np.array([b.position_enu for b in birds], float)
    vel = np.array([b.velocity_enu for b in birds], float)
    side = np.column_stack([vel[:, 1], -vel[:, 0], np.zeros(len(birds))])
    norm = np.linalg.norm(side, axis=1)
    side = np.where(norm[:, None] > 1e-6, side / np.maximum(norm, 1e-6)[:, None], np.array([1.0, 0.0, 0.0]))
    _draw_wings(img, project, focal_px, t, body, side, np.array([0.5 * b.span_m for b in birds]),
                np.array([b.flap_hz for b in birds]), np.array([b.phase for b in birds]),
                [b.span_m for b in birds], [b.colour for b in birds])


@dataclass(frozen=True)
class Bird:
    """A bird circling ``centre_enu`` at ``radius_m`` and ``speed_mps``; wings of ``span_m`` flapping at
    ``flap_hz`` (a gull 1.2 m at 3 Hz, a crow 0.9 m at 4 Hz, a small bird 0.3 m at 10 Hz)."""

    centre_enu: tuple[float, float, float]
    radius_m: float
    speed_mps: float
    phase: float
    span_m: float
    flap_hz: float
    colour: tuple[int, int, int]

    def position(self, t: float) -> np.ndarray:
        """Where the body is at time ``t`` (ENU)."""
        return Birds((self,)).positions(t)[0]

    def draw(self, img: np.ndarray, project: Projector, focal_px: float, t: float) -> None:
        """Draw this bird at time ``t`` (:meth:`Birds.draw`)."""
        Birds((self,)).draw(img, project, focal_px, t)


class Birds:
    """Many birds placed and drawn at once: their paths as arrays, one projection for all of them."""

    def __init__(self, birds: Sequence[Bird]) -> None:
        self.birds = tuple(birds)
        self.centre = np.array([b.centre_enu for b in self.birds], float).reshape(-1, 3)
        self.radius = np.array([b.radius_m for b in self.birds], float)
        self.speed = np.array([b.speed_mps for b in self.birds], float)
        self.phase = np.array([b.phase for b in self.birds], float)
        self.half_span = np.array([0.5 * b.span_m for b in self.birds], float)
        self.flap_hz = np.array([b.flap_hz for b in self.birds], float)

    def __len__(self) -> int:
        return len(self.birds)

    def _angles(self, t: float) -> np.ndarray:
        return self.phase + self.speed * t / np.maximum(self.radius, 1.0)

    def positions(self, t: float) -> np.ndarray:
        """(N, 3) ENU bodies at time ``t``: each circles its centre, bobbing 2 m."""
        a = self._angles(t)
        return self.centre + np.column_stack([self.radius * np.cos(a), self.radius * np.sin(a), 2.0 * np.sin(0.3 * a)])

    def draw(self, img: np.ndarray, project: Projector, focal_px: float, t: float, which: Sequence[int] | None = None) -> None:
        """Draw the birds ``which`` (all: None) in order: a polyline wing tip - body - wing tip, the wings
        flapping up and down about the direction across the flight."""
        k = np.arange(len(self)) if which is None else np.asarray(which, int)
        if not len(k):
            return
        a = self._angles(t)[k]
        body = self.positions(t)[k]
        side = np.column_stack([np.cos(a), np.sin(a), np.zeros(len(k))])  # along the radius: across the flight
        birds = [self.birds[i] for i in k]
        _draw_wings(img, project, focal_px, t, body, side, self.half_span[k], self.flap_hz[k], self.phase[k],
                    [b.span_m for b in birds], [b.colour for b in birds])


@dataclass(frozen=True)
class Aircraft:
    """A light aircraft far off, flying a straight leg: a small cross against the sky."""

    start_enu: tuple[float, float, float]
    velocity_enu: tuple[float, float, float]
    span_m: float = 11.0
    colour: tuple[int, int, int] = (70, 70, 75)

    def draw(self, img: np.ndarray, project: Projector, focal_px: float, t: float) -> None:
        p = np.asarray(self.start_enu) + t * np.asarray(self.velocity_enu)
        v = np.asarray(self.velocity_enu, float)
        fwd = v / max(np.linalg.norm(v), 1e-6)
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        half = 0.5 * self.span_m
        pts = np.array([p - half * right, p + half * right, p + 0.45 * self.span_m * fwd, p - 0.4 * self.span_m * fwd])
        px, z = project(pts)
        if (z <= 1.0).any() or not np.isfinite(px).all() or np.abs(px).max() > 1e5:
            return
        for a, b in ((0, 1), (2, 3)):
            cv2.line(img, tuple(int(c) for c in px[a] * 16), tuple(int(c) for c in px[b] * 16), self.colour, 1, cv2.LINE_AA, 4)


@dataclass(frozen=True)
class LensSpecks:
    """Dirt on the lens: soft dark spots fixed in the image (x, y, radius px, darkening 0..1)."""

    spots: tuple[tuple[float, float, float, float], ...]

    def draw(self, img: np.ndarray) -> None:
        for x, y, r, dark in self.spots:
            x0, y0 = max(int(x - 2 * r), 0), max(int(y - 2 * r), 0)
            x1, y1 = min(int(x + 2 * r) + 1, img.shape[1]), min(int(y + 2 * r) + 1, img.shape[0])
            if x1 <= x0 or y1 <= y0:
                continue
            yy, xx = np.mgrid[y0:y1, x0:x1]
            shade = 1.0 - dark * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2.0 * r * r))
            img[y0:y1, x0:x1] = (img[y0:y1, x0:x1] * shade[..., None]).astype(np.uint8)

    @classmethod
    def random(cls, rng: np.random.Generator, count: int, width: int, height: int) -> LensSpecks:
        return cls(tuple((float(rng.uniform(0, width)), float(rng.uniform(0, height)), float(rng.uniform(1.5, 5.0)),
                          float(rng.uniform(0.15, 0.5))) for _ in range(count)))


def make_birds(rng: np.random.Generator, singles: int, flocks: int, half_extent_m: float) -> list[Bird]:
    """``singles`` birds and ``flocks`` flocks of 5-25 over a field ``half_extent_m`` each way."""
    kinds = BIRD_LOOKS
    birds = []

    def one(centre, radius, speed, phase, k):
        (span, hz), colour = kinds[k]
        birds.append(Bird(tuple(float(c) for c in centre), float(radius), float(speed), float(phase),
                          span * float(rng.uniform(0.85, 1.15)), hz * float(rng.uniform(0.8, 1.2)), colour))

    for _ in range(singles):
        centre = (*rng.uniform(-half_extent_m, half_extent_m, 2), rng.uniform(8, 90))
        one(centre, rng.uniform(15, 120), rng.uniform(6, 14), rng.uniform(0, 2 * np.pi), int(rng.integers(3)))
    for _ in range(flocks):
        centre = np.array([*rng.uniform(-half_extent_m, half_extent_m, 2), rng.uniform(15, 80)])
        radius, speed, phase, k = rng.uniform(40, 150), rng.uniform(8, 13), rng.uniform(0, 2 * np.pi), int(rng.integers(3))
        for _ in range(int(rng.integers(5, 26))):
            offset = rng.normal(0, 4.0, 3) * [1.0, 1.0, 0.4]
            one(centre + offset, radius + rng.normal(0, 3.0), speed, phase + rng.normal(0, 0.03), k)
    return birds


def make_aircraft(rng: np.random.Generator, count: int) -> list[Aircraft]:
    """``count`` aircraft 2-6 km out, 300-1500 m up, at 40-70 m/s."""
    out = []
    for _ in range(count):
        bearing, heading = rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi)
        d, speed = rng.uniform(2000, 6000), rng.uniform(40, 70)
        out.append(Aircraft((d * math.cos(bearing), d * math.sin(bearing), float(rng.uniform(300, 1500))),
                            (speed * math.cos(heading), speed * math.sin(heading), 0.0)))
    return out
