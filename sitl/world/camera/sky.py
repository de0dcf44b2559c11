"""The sky of the camera world: a gradient, a cloud layer at a height, the sun's disc and its glare.

Worked out per ray on the renderer's coarse grid (sky varies slowly): a ray above the horizon meets
the cloud layer at ``cloud_height_m``, where a tileable coverage map says how cloudy it is; clouds
thin into the horizon's haze. Rays near the sun brighten (disc and bloom), above and below the
horizon alike: the lens glare a camera pointed near the sun sees.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sitl.world.camera.materials import periodic_fractal_noise

__all__ = ["Sky", "make_sky"]

_CLOUD_PX = 512


@dataclass(frozen=True)
class Sky:
    """Args:
        zenith, horizon: BGR colours of the clear sky.
        cloud_cover: 0 clear .. 1 overcast; cloud_tile: (N, N) float32 coverage noise in [0, 1].
        cloud_m_per_px: size of a cloud-tile pixel on the layer; cloud_height_m: the layer above the ground.
        cloud_lit, cloud_shade: BGR of a cloud's sunlit top and its base.
        glare: strength of the sun's bloom (0 none).
    """

    zenith: tuple[float, float, float]
    horizon: tuple[float, float, float]
    cloud_cover: float
    cloud_tile: np.ndarray
    cloud_m_per_px: float = 20.0
    cloud_height_m: float = 1500.0
    cloud_lit: tuple[float, float, float] = (245.0, 245.0, 245.0)
    cloud_shade: tuple[float, float, float] = (170.0, 165.0, 165.0)
    glare: float = 1.0

    def colour(self, rays: np.ndarray, camera_enu: np.ndarray) -> np.ndarray:
        """BGR float32 (rows, cols, 3) of the sky along unit ENU ``rays`` (rows, cols, 3), without the
        sun's glare (:meth:`glare_map`, which the lens adds over the ground too)."""
        up = rays[..., 2]
        zen, hor = np.asarray(self.zenith, np.float32), np.asarray(self.horizon, np.float32)
        out = hor + (zen - hor) * np.sqrt(np.clip(up, 0.0, 1.0))[..., None]
        if self.cloud_cover > 0.0:
            s = (self.cloud_height_m - float(camera_enu[2])) / np.maximum(up, 1e-3)
            s[up <= 0.0] = 0.0  # no cloud below the horizon (alpha 0 there): read the tile where the camera is, not scattered far off
            mx = ((camera_enu[0] + s * rays[..., 0]) / self.cloud_m_per_px).astype(np.float32)
            my = ((camera_enu[1] + s * rays[..., 1]) / self.cloud_m_per_px).astype(np.float32)
            cov = cv2.remap(self.cloud_tile, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
            alpha = np.clip((cov - (1.0 - self.cloud_cover)) * 4.0, 0.0, 1.0)
            alpha *= np.clip(up * 8.0, 0.0, 1.0)  # far clouds fade into the horizon haze
            body = np.asarray(self.cloud_shade, np.float32) + (np.asarray(self.cloud_lit, np.float32)
                                                                 - np.asarray(self.cloud_shade, np.float32)) * cov[..., None]
            out = out + (body - out) * alpha[..., None]
        return out

    def glare_map(self, rays: np.ndarray, sun: np.ndarray) -> np.ndarray:
        """Grey levels added near the sun: its disc (0.5 deg) and a broad bloom."""
        if self.glare <= 0.0:
            return np.zeros(rays.shape[:2], np.float32)
        c = np.clip(rays @ np.asarray(sun, np.float32), -1.0, 1.0)
        return (self.glare * (255.0 * np.exp((c - 1.0) / 4e-5) + 90.0 * np.exp((c - 1.0) / 0.03))).astype(np.float32)


def make_sky(rng: np.random.Generator, cover: float, zenith: tuple[float, float, float],
             horizon: tuple[float, float, float], glare: float) -> Sky:
    """A sky with ``cover`` cloud (0..1) drawn from ``rng``: cumulus-like blobs from fractal noise."""
    tile = periodic_fractal_noise(rng, _CLOUD_PX, (4, 8, 16, 64))  # periodic: the layer wraps without seams
    return Sky(zenith=zenith, horizon=horizon, cloud_cover=float(cover), cloud_tile=tile, glare=float(glare))
