"""What the camera does to the light: exposure and white balance that drift, vignetting.

(Motion blur, noise and JPEG compression are the renderer's, for every world.) The drift is a
sum of slow sinusoids with seeded frequencies and phases: smooth, reproducible, and a function of
time alone, so a frame depends on nothing but its time.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CameraEffects", "vignette_map"]


@dataclass(frozen=True)
class CameraEffects:
    """Args:
        exposure_sigma: 1-sigma of the exposure drift (log gain; 0.15 ~ +-15 %).
        white_balance_sigma: 1-sigma of each colour channel's gain drift (log).
        drift_period_s: the drift's typical period.
        vignetting: darkening of the frame's corners (0 none, 0.4 strong).
        seed: the drift's frequencies and phases.
    """

    exposure_sigma: float = 0.12
    white_balance_sigma: float = 0.05
    drift_period_s: float = 20.0
    vignetting: float = 0.25
    seed: int = 0

    @functools.cached_property
    def _drift(self) -> tuple[np.ndarray, np.ndarray]:
        """The drift's angular frequencies and phases (4 waves x 3 sinusoids), drawn once from the seed."""
        rng = np.random.default_rng([self.seed, 0xe1f])
        freqs = rng.uniform(0.5, 2.0, (4, 3)) * (2.0 * math.pi / self.drift_period_s)
        return freqs, rng.uniform(0, 2.0 * math.pi, (4, 3))

    def gains(self, t: float) -> tuple[float, float, float]:
        """BGR gains at time ``t``: exposure times each channel's white balance."""
        freqs, phases = self._drift
        wave = np.sin(freqs * t + phases).sum(axis=1) / math.sqrt(1.5)  # unit variance each
        exposure = self.exposure_sigma * wave[0]
        wb = self.white_balance_sigma * wave[1:]
        return tuple(float(math.exp(exposure + w)) for w in wb)


def vignette_map(width: int, height: int, strength: float) -> np.ndarray:
    """(height, width) float32 gain: 1 at the centre, ``1 - strength`` at the corners (cos^4-like)."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    r2 = ((x - 0.5 * width) ** 2 + (y - 0.5 * height) ** 2) / (0.25 * (width ** 2 + height ** 2))
    return (1.0 - strength * r2 ** 1.5).astype(np.float32)
