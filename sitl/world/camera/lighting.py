"""Scene lighting and sensor settings of a rendered frame."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Lighting"]


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
    """

    sun_azimuth_rad: float = 0.8
    sun_elevation_rad: float = 0.8
    brightness: float = 1.0
    haze_m: float = 900.0
    sky_zenith: tuple[float, float, float] = (200.0, 140.0, 90.0)
    sky_horizon: tuple[float, float, float] = (235.0, 215.0, 200.0)
    noise_sigma: float = 3.0
    jpeg_quality: int = 85

    def sun_enu(self) -> np.ndarray:
        ce = math.cos(self.sun_elevation_rad)
        return np.array([ce * math.cos(self.sun_azimuth_rad), ce * math.sin(self.sun_azimuth_rad), math.sin(self.sun_elevation_rad)])
