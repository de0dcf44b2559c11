"""Scene lighting and sensor settings of a rendered frame, and a scenario's ``lighting`` keys over them."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["Lighting", "LightingOverride", "OVERCAST_GREY", "sun_share"]

#: BGR of a fully overcast sky, which clear-sky colours blend into with ``overcast``.
OVERCAST_GREY = (185.0, 185.0, 185.0)


def sun_share(cos_sun: float, overcast: float) -> float:
    """The light a surface whose normal makes cosine ``cos_sun`` with the sun gets, as a share of
    full sun on it: the direct sun ``max(cos_sun, 0)`` dimmed by ``1 - overcast``, plus the cloud's
    diffuse light, ``0.5 * overcast`` on every surface alike (so at overcast 1 every surface is lit
    the same: no highlights, no sun side)."""
    direct = max(cos_sun, 0.0)
    if overcast <= 0.0:
        return direct
    return (1.0 - overcast) * direct + 0.5 * overcast


@dataclass(frozen=True)
class Lighting:
    """Scene lighting and sensor settings.

    Args:
        sun_azimuth_rad, sun_elevation_rad: ENU azimuth (from east, counter-clockwise) and elevation.
        brightness: overall gain (1 = nominal exposure).
        haze_m: visibility distance of the ground haze (m).
        sky_zenith, sky_horizon: BGR sky colours.
        noise_sigma: additive sensor noise (grey levels, 1-sigma).
        jpeg_quality: 1..100, or 0 for no compression.
        overcast: 0 clear .. 1 fully overcast: how much of the sun's direct light the cloud takes
            (:func:`sun_share`).
    """

    sun_azimuth_rad: float = 0.8
    sun_elevation_rad: float = 0.8
    brightness: float = 1.0
    haze_m: float = 900.0
    sky_zenith: tuple[float, float, float] = (200.0, 140.0, 90.0)
    sky_horizon: tuple[float, float, float] = (235.0, 215.0, 200.0)
    noise_sigma: float = 3.0
    jpeg_quality: int = 85
    overcast: float = 0.0

    def sun_enu(self) -> np.ndarray:
        ce = math.cos(self.sun_elevation_rad)
        return np.array([ce * math.cos(self.sun_azimuth_rad), ce * math.sin(self.sun_azimuth_rad), math.sin(self.sun_elevation_rad)])


@dataclass(frozen=True)
class LightingOverride:
    """A scenario's ``lighting`` keys: each given one replaces what the camera world drew.

    Args:
        sun_elevation_deg: the sun's height above the horizon.
        sun_azimuth_deg: the sun's compass bearing (from north, clockwise).
        overcast: 0..1 (:attr:`Lighting.overcast`); it also blends the clear-sky colours toward
            :data:`OVERCAST_GREY`, and the camera world takes it for its cloud cover (at least),
            its sun glare (times ``1 - overcast``) and its ground's shadows (``1 - overcast`` of
            their length).
    """

    sun_elevation_deg: float | None = None
    sun_azimuth_deg: float | None = None
    overcast: float | None = None

    def apply(self, lighting: Lighting) -> Lighting:
        """``lighting`` with these keys in force."""
        out = lighting
        if self.sun_azimuth_deg is not None:
            out = replace(out, sun_azimuth_rad=math.radians((90.0 - self.sun_azimuth_deg) % 360.0))
        if self.sun_elevation_deg is not None:
            out = replace(out, sun_elevation_rad=math.radians(self.sun_elevation_deg))
        if self.overcast is not None:
            o = self.overcast
            out = replace(out, overcast=o, sky_zenith=_blend(out.sky_zenith, OVERCAST_GREY, o),
                          sky_horizon=_blend(out.sky_horizon, OVERCAST_GREY, o))
        return out


def _blend(a: tuple[float, float, float], b: tuple[float, float, float], w: float) -> tuple[float, float, float]:
    return tuple(float(x + w * (y - x)) for x, y in zip(a, b))
