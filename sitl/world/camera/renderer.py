"""Render what the chaser's camera sees, from ground truth (paper section 3.1; the camera is the sensor).

A frame is: sky (a gradient over ray elevation) above the horizon; the procedural ground
(:mod:`sitl.world.camera.scene`) mapped by the ground-plane homography ``K R^T [e1 e2 -C]`` below it,
fading into haze with distance; the targets drawn to scale and attitude from
:mod:`sitl.world.camera.models` in painter's order; then the sensor: brightness, motion blur along a
direction, additive noise and JPEG compression. The camera geometry is
:class:`chaser_bt.vision.camera.CameraModel` (the one camera model), so labels, projection and
rendering agree exactly. Each label is the tight box of the drawn primitives.

Randomness comes only from the ``rng`` passed to :meth:`Renderer.render`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Sequence

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.frame_source import Region
from sitl.world.camera.lighting import Lighting, sun_share
from sitl.world.camera.models import TargetModel, model_for
from sitl.world.camera.props import boxes_reach
from sitl.world.camera.distractors import BirdPose, Birds, draw_bird_poses
from sitl.world.camera.effects import vignette_map
from sitl.world.camera.fields import DETAIL_M_PER_PX
from sitl.world.camera.scene import GroundScene
from sitl.world.camera.sky import Sky
from sitl.world.camera.world import CameraWorld

__all__ = ["Lighting", "TargetPose", "TargetLabel", "RenderedFrame", "Renderer", "Region", "attitude_from_velocity", "viewports",
           "compile_model", "draw_model"]

_DISC_SIDES = 12
_COARSE = 4  # sky and haze grid step (pixels)
_BLOCK = 16  # JPEG's block (a 4:2:0 macroblock): views start on it so their blocks are the whole frame's
#: The margin a view adds around a region asked for: the motion blur's reach (12 px) and a JPEG
#: macroblock, whose decoding blends chroma across block edges.
VIEW_MARGIN_PX = 32


@dataclass(frozen=True)
class TargetPose:
    """A target to draw: its kind ("s1000", "phantom", "person"), ENU position (m), body (FLU) -> ENU
    attitude and colour ``variant`` (:func:`sitl.world.camera.models.model_for`)."""

    kind: str
    position_enu: np.ndarray
    attitude: Rotation = field(default_factory=Rotation.identity)
    variant: int = 0


@dataclass(frozen=True)
class TargetLabel:
    """Ground truth for one drawn target: ``box`` (x0, y0, x1, y1) pixels, clipped to the image."""

    index: int
    kind: str
    box: tuple[float, float, float, float]
    centre_px: tuple[float, float]
    range_m: float
    truncated: bool


@dataclass(frozen=True)
class RenderedFrame:
    """One camera frame (BGR uint8, height x width x 3) and the labels of the targets in it; ``views``:
    the parts drawn when regions were asked for (None: the whole frame)."""

    image: np.ndarray
    labels: tuple[TargetLabel, ...]
    views: tuple[Region, ...] | None = None


def attitude_from_velocity(velocity_enu: np.ndarray, tilt_per_mps: float = math.radians(2.5)) -> Rotation:
    """A multicopter's attitude from its velocity: nose along the ground track, pitched into the motion."""
    v = np.asarray(velocity_enu, dtype=float)
    speed = float(np.hypot(v[0], v[1]))
    yaw = math.atan2(v[1], v[0]) if speed > 0.1 else 0.0
    pitch = min(speed * tilt_per_mps, math.radians(30.0))
    # FLU body: a positive rotation about body y pitches the nose down.
    return Rotation.from_euler("ZY", [yaw, pitch])


@dataclass(frozen=True)
class _CompiledModel:
    kind: str
    sphere_c: np.ndarray
    sphere_r: np.ndarray
    sphere_col: np.ndarray
    rod_a: np.ndarray
    rod_b: np.ndarray
    rod_r: np.ndarray
    rod_col: np.ndarray
    disc_pts: np.ndarray  # (D, sides, 3)
    disc_col: np.ndarray
    disc_alpha: np.ndarray


def compile_model(model: TargetModel) -> _CompiledModel:
    """``model``'s primitives as arrays, ready for :func:`draw_model` (compile once, draw many times)."""
    def pick(shape: str):
        return [p for p in model.parts if p.shape == shape]

    ring = np.stack([np.cos(np.linspace(0, 2 * np.pi, _DISC_SIDES, endpoint=False)),
                     np.sin(np.linspace(0, 2 * np.pi, _DISC_SIDES, endpoint=False)),
                     np.zeros(_DISC_SIDES)], axis=1)
    s, r, d = pick("sphere"), pick("rod"), pick("disc")
    return _CompiledModel(
        kind=model.kind,
        sphere_c=np.array([p.a for p in s], float).reshape(-1, 3),
        sphere_r=np.array([p.radius for p in s], float),
        sphere_col=np.array([p.colour for p in s], float).reshape(-1, 3),
        rod_a=np.array([p.a for p in r], float).reshape(-1, 3),
        rod_b=np.array([p.b for p in r], float).reshape(-1, 3),
        rod_r=np.array([p.radius for p in r], float),
        rod_col=np.array([p.colour for p in r], float).reshape(-1, 3),
        disc_pts=np.array([np.asarray(p.a) + p.radius * ring for p in d], float).reshape(-1, _DISC_SIDES, 3),
        disc_col=np.array([p.colour for p in d], float).reshape(-1, 3),
        disc_alpha=np.array([p.alpha for p in d], float),
    )


class Renderer:
    """Draws camera frames of a :class:`GroundScene` and targets for a :class:`CameraModel`.

    Args:
        camera: the camera (its width/height are the frame size).
        scene: the ground.
        noise_seed: seed of the fixed noise tile the sensor noise is cut from.
        world: the rest of a camera world (:mod:`sitl.world.camera.world`): sky, poles and power lines,
            distractors, camera effects; its ground replaces ``scene``. None: the plain field.
    """

    def __init__(self, camera: CameraModel, scene: GroundScene | None = None, noise_seed: int = 0,
                 world: CameraWorld | None = None) -> None:
        if scene is None and world is None:
            raise ValueError("Renderer needs a ground scene or a camera world")
        self.camera = camera
        self.world = world
        scene = world.ground if world is not None else scene
        self.scene = scene
        w, h = camera.width_px, camera.height_px
        fx, fy = camera.focal_px
        self._k = np.array([[fx, 0.0, 0.5 * w], [0.0, fy, 0.5 * h], [0.0, 0.0, 1.0]])
        u = (np.arange(w, dtype=np.float32) + 0.5 - 0.5 * w) / fx
        v = (np.arange(h, dtype=np.float32) + 0.5 - 0.5 * h) / fy
        self._u_lo = cv2.resize(np.repeat(u[None, :], h, 0), (w // _COARSE, h // _COARSE), interpolation=cv2.INTER_AREA)
        self._v_lo = cv2.resize(np.repeat(v[:, None], w, 1), (w // _COARSE, h // _COARSE), interpolation=cv2.INTER_AREA)
        self._inv_norm_lo = 1.0 / np.sqrt(1.0 + self._u_lo**2 + self._v_lo**2)
        tile_rng = np.random.default_rng(noise_seed)
        self._noise = np.clip(tile_rng.standard_normal((h + 64, w + 64, 3)) * 20.0, -127, 127).astype(np.int8)  # sigma 20
        self._models = {}
        self._ground_mean = tuple(float(c) for c in scene.texture.reshape(-1, 3).mean(axis=0))
        # A frame of the ground's mean colour, copied where a fill is needed (a copy is a memcpy; a
        # broadcast fill of a colour is ten times slower).
        self._flat = np.empty((h, w, 3), np.uint8)
        self._flat[:] = np.round(self._ground_mean).astype(np.uint8)
        effects = world.effects if world is not None else None
        self._birds = Birds(world.birds if world is not None else ())
        self._vignette_lo = None if effects is None or effects.vignetting <= 0 else cv2.resize(
            vignette_map(w, h, effects.vignetting), (w // _COARSE, h // _COARSE), interpolation=cv2.INTER_AREA)

    def _model(self, kind: str, variant: int = 0) -> _CompiledModel:
        if (kind, variant) not in self._models:
            self._models[(kind, variant)] = compile_model(model_for(kind, variant))
        return self._models[(kind, variant)]

    def render(self, vehicle_pos_enu: np.ndarray, body_attitude: Rotation, targets: Sequence[TargetPose],
               lighting: Lighting, rng: np.random.Generator, blur_px: float = 0.0, blur_angle_rad: float = 0.0,
               t: float = 0.0, regions: Sequence[Region] | None = None, birds: Sequence[BirdPose] = ()) -> RenderedFrame:
        """The frame seen from the vehicle's pose; ``blur_px`` is the motion-blur streak length and
        ``t`` the time (s) that places a world's birds and aircraft and its camera's drift. ``birds``
        are the simulator's birds where it has them now, drawn (unlabelled) after the world's
        distractors and before the targets.

        ``regions`` (x0, y0, x1, y1 pixel rectangles) asks for those parts only, as a camera reading out
        regions of interest: each is drawn with a margin wide enough for the blur and the JPEG blocks
        (:func:`viewports`), so its pixels are the whole frame's; the rest of the frame is a flat grey.
        None: the whole frame. The labels and the randomness drawn are the same either way.
        """
        cam = self.camera
        w, h = cam.width_px, cam.height_px
        r_ce = cam.camera_to_enu(body_attitude).as_matrix()  # optical -> ENU
        c_enu = cam.position_enu(vehicle_pos_enu, body_attitude)
        sun = lighting.sun_enu()
        drawn = views = viewports(regions, w, h)
        if views is None:
            views = [(0, 0, w, h)]
            img = self._background(views[0], r_ce, c_enu, sun, lighting)
        else:
            img = self._flat.copy()
            for x0, y0, x1, y1 in views:
                img[y0:y1, x0:x1] = self._background((x0, y0, x1, y1), r_ce, c_enu, sun, lighting)
        if self.world is not None:
            self._draw_world(img, r_ce, c_enu, t, views)
        if birds:
            draw_bird_poses(img, lambda p: self._project(r_ce, c_enu, p), self.camera.focal_px[0], t, birds)
        labels = self._draw_targets(img, r_ce, c_enu, targets, sun, lighting.brightness, lighting.overcast)
        effects = self.world.effects if self.world is not None else None
        gains = _gain_table(effects.gains(t)) if effects is not None else None
        for x0, y0, x1, y1 in views:
            view = img[y0:y1, x0:x1]
            if gains is not None:
                cv2.LUT(view, gains, dst=view)
            if blur_px >= 1.5:
                view[:] = _motion_blur(view, blur_px, blur_angle_rad)
        if self.world is not None and self.world.specks is not None:
            self.world.specks.draw(img)
        if lighting.noise_sigma > 0:
            oy, ox = rng.integers(0, 64, size=2)
        for x0, y0, x1, y1 in views:
            view = img[y0:y1, x0:x1]
            if lighting.noise_sigma > 0:
                noise = self._noise[oy + y0:oy + y1, ox + x0:ox + x1]
                view[:] = cv2.addWeighted(view, 1.0, noise, lighting.noise_sigma / 20.0, 0.0, dtype=cv2.CV_8U)
            if lighting.jpeg_quality > 0:
                ok, buf = cv2.imencode(".jpg", view, [cv2.IMWRITE_JPEG_QUALITY, int(lighting.jpeg_quality)])
                view[:] = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return RenderedFrame(image=img, labels=labels, views=None if drawn is None else tuple(drawn))

    def _background(self, view: Region, r_ce: np.ndarray, c_enu: np.ndarray, sun: np.ndarray,
                    lighting: Lighting) -> np.ndarray:
        """Ground, sky and haze over ``view`` (x0, y0, x1, y1, multiples of the coarse step), before
        anything is drawn over them.

        Sky and haze vary slowly: they are worked out on the coarse grid's cells under the view and one
        cell around it (so their interpolation up to full size is the whole frame's), then blended at
        full size over that padded view, which is cut back to ``view`` at the end.
        """
        x0, y0, x1, y1 = view
        gh, gw = self._u_lo.shape
        if view == (0, 0, self.camera.width_px, self.camera.height_px):
            cx0, cy0, cx1, cy1 = 0, 0, gw, gh
            size = (x1, y1)
        else:  # viewports() gives views on the coarse grid, inside a frame the grid covers exactly
            cx0, cy0 = max(x0 // _COARSE - 1, 0), max(y0 // _COARSE - 1, 0)
            cx1, cy1 = min(x1 // _COARSE + 1, gw), min(y1 // _COARSE + 1, gh)
            size = ((cx1 - cx0) * _COARSE, (cy1 - cy0) * _COARSE)
        px0, py0 = cx0 * _COARSE, cy0 * _COARSE  # the padded view's corner, frame pixels
        u_lo, v_lo = self._u_lo[cy0:cy1, cx0:cx1], self._v_lo[cy0:cy1, cx0:cx1]
        inv_norm_lo = self._inv_norm_lo[cy0:cy1, cx0:cx1]
        # Ground through the homography K R^T [e1 e2 -C] G (G: texture pixel -> ground metres).
        rt = r_ce.T
        plane = self._k @ np.column_stack([rt[:, 0], rt[:, 1], -rt @ c_enu])
        if px0 or py0:  # into the padded view's pixels
            plane = np.array([[1.0, 0.0, -float(px0)], [0.0, 1.0, -float(py0)], [0.0, 0.0, 1.0]]) @ plane
        # Ray elevation: the ENU up-component of the optical ray, linear in (u, v).
        up = (r_ce[2, 0] * u_lo + r_ce[2, 1] * v_lo + r_ce[2, 2]) * inv_norm_lo
        ground = up < 0.0
        height = max(float(c_enu[2]), 0.05)
        dist = height / np.maximum(-up, 1e-4)
        if self.scene.far_texture is None and self.scene.detail is None:
            # Beyond the texture the ground is its mean colour (BORDER_REFLECT would loop for near-horizon rays).
            ground_img = cv2.warpPerspective(self.scene.texture, plane @ self.scene.texture_to_ground(), size,
                                             flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                                             borderValue=self._ground_mean)
        else:
            ground_img = self._filtered_ground(plane, dist, ground, size)
        ground_img = cv2.convertScaleAbs(ground_img, alpha=0.55 + 0.55 * sun_share(float(sun[2]), lighting.overcast))
        weight = np.where(ground, np.exp(-dist / lighting.haze_m), 0.0).astype(np.float32)
        hor = np.asarray(lighting.sky_horizon, np.float32)
        sky_model = self.world.sky if self.world is not None else None
        if sky_model is None:
            zen = np.asarray(lighting.sky_zenith, np.float32)
            sky = hor + (zen - hor) * np.sqrt(np.clip(up, 0.0, 1.0))[..., None]
            back = np.clip(np.where(ground[..., None], hor, sky), 0, 255).astype(np.uint8)
        else:
            rays = np.stack([u_lo, v_lo, np.ones_like(u_lo)], axis=-1) @ r_ce.T
            rays *= inv_norm_lo[..., None]
            glare = sky_model.glare_map(rays, sun)[..., None]  # the lens sees it over sky and ground alike
            sky = hor if ground.all() else _sky_rows(sky_model, rays, ground, hor, c_enu)
            back = np.clip(sky + glare, 0, 255).astype(np.uint8)
        back = cv2.resize(back, size, interpolation=cv2.INTER_LINEAR)
        if self._vignette_lo is None:
            weight = cv2.resize(weight, size, interpolation=cv2.INTER_LINEAR)
            img = cv2.blendLinear(ground_img, back, weight, 1.0 - weight)
        else:  # the lens darkens the corners: folded into the blend's weights
            v = self._vignette_lo[cy0:cy1, cx0:cx1]
            w_ground = cv2.resize(weight * v, size, interpolation=cv2.INTER_LINEAR)
            w_back = cv2.resize((1.0 - weight) * v, size, interpolation=cv2.INTER_LINEAR)
            img = cv2.blendLinear(ground_img, back, w_ground, w_back)
        if lighting.brightness != 1.0:
            img = cv2.convertScaleAbs(img, alpha=lighting.brightness)
        if size == (x1 - x0, y1 - y0):
            return img
        return img[y0 - py0:y1 - py0, x0 - px0:x1 - px0]

    def _filtered_ground(self, plane: np.ndarray, dist_lo: np.ndarray, ground_lo: np.ndarray,
                         size: tuple[int, int]) -> np.ndarray:
        """The ground filtered with distance: the pre-filtered copy where a pixel spans several texels
        (no shimmer toward the horizon), the full texture nearer, and the detail tile's fine grain
        where the ground is near. Each layer is warped only over the rows where it shows. ``plane`` maps
        ground metres to the output's pixels; ``size`` is the output's (width, height), which the coarse
        grids ``dist_lo`` and ``ground_lo`` cover."""
        w, h = size
        scene = self.scene
        out = self._flat[:h, :w].copy()
        texels_per_px = np.where(ground_lo, dist_lo / (self.camera.focal_px[0] * scene.metres_per_px), np.inf)
        far_lo = np.clip((texels_per_px - 0.75) / 0.75, 0.0, 1.0).astype(np.float32)  # all far from 1.5 texels a pixel
        to_ground = scene.texture_to_ground()
        near_rows = _rows(far_lo < 1.0, h)
        if near_rows is not None:
            _warp_into(out, scene.texture, plane @ to_ground, near_rows, cv2.BORDER_CONSTANT, self._ground_mean)
        far_rows = _rows(ground_lo & (far_lo > 0.0), h) if scene.far_texture is not None else None
        if far_rows is not None:
            r0, r1 = far_rows
            k = scene.texture.shape[1] / scene.far_texture.shape[1]
            shift = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -float(r0)], [0.0, 0.0, 1.0]])
            # Far off the ground goes on past the texture's edge, mirrored: under the haze, no one sees it repeat.
            far = cv2.warpPerspective(scene.far_texture, shift @ plane @ to_ground @ np.diag([k, k, 1.0]), (w, r1 - r0),
                                      flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101)
            far_w = cv2.resize(far_lo, (w, h), interpolation=cv2.INTER_LINEAR)[r0:r1]
            out[r0:r1] = cv2.blendLinear(far, out[r0:r1], far_w, 1.0 - far_w)
        near_w_lo = np.where(ground_lo, np.clip(1.5 - 0.02 * dist_lo, 0.0, 1.0), 0.0).astype(np.float32)
        detail_rows = _rows(near_w_lo > 0.0, h) if scene.detail is not None else None
        if detail_rows is not None:
            r0, r1 = detail_rows
            d = DETAIL_M_PER_PX
            grain = np.empty((h, w), np.uint8)
            _warp_into(grain, scene.detail, plane @ np.array([[d, 0.0, 0.0], [0.0, -d, 0.0], [0.0, 0.0, 1.0]]),
                       detail_rows, cv2.BORDER_WRAP, 0)
            near_w = cv2.resize(near_w_lo, (w, h), interpolation=cv2.INTER_LINEAR)[r0:r1]
            # The grain fades to 128 (no change) with distance, then scales the ground: out * grain / 128.
            faded = cv2.blendLinear(grain[r0:r1], np.full_like(grain[r0:r1], 128), near_w, 1.0 - near_w)
            out[r0:r1] = cv2.multiply(out[r0:r1], cv2.cvtColor(faded, cv2.COLOR_GRAY2BGR), scale=1.0 / 128.0)
        return out

    def _project(self, r_ce: np.ndarray, c_enu: np.ndarray, points_enu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ENU points (N, 3) -> pixels (N, 2) and depth along the optical axis (N,)."""
        c = (np.asarray(points_enu, float).reshape(-1, 3) - c_enu) @ r_ce
        z = c[:, 2]
        zs = np.where(np.abs(z) > 1e-6, z, 1e-6)
        fx, fy = self.camera.focal_px
        px = np.stack([0.5 * self.camera.width_px + fx * c[:, 0] / zs, 0.5 * self.camera.height_px + fy * c[:, 1] / zs], axis=1)
        return px, z

    def _draw_world(self, img: np.ndarray, r_ce: np.ndarray, c_enu: np.ndarray, t: float, views: Sequence[Region]) -> None:
        """Power lines, then birds and aircraft, drawn before the targets; what cannot reach any of
        ``views`` is not drawn (outside them the frame is a fill nobody reads)."""
        world = self.world

        def project(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return self._project(r_ce, c_enu, points)

        f = self.camera.focal_px[0]
        for prop in world.props:
            prop.draw(img, project, f, views)
        for plane in world.aircraft:
            plane.draw(img, project, f, t)
        birds = self._birds
        if len(birds):  # most birds are out of view at any moment: cull them together first
            px, z = project(birds.positions(t))
            w, h = self.camera.width_px, self.camera.height_px
            seen = (z > 1.0) & (px[:, 0] > -50) & (px[:, 0] < w + 50) & (px[:, 1] > -50) & (px[:, 1] < h + 50)
            # A bird's wings reach half its span from its body: their pixels lie within
            # f h / (z - h) (1 + |body pixel - centre| / f) of the body's (h the half span), plus the stroke.
            half = birds.half_span
            near = z - half <= 1.0
            reach = f * half / np.where(near, 1.0, z - half) * (1.0 + (np.abs(px[:, 0] - 0.5 * w) + np.abs(px[:, 1] - 0.5 * h)) / f)
            reach += 0.12 * 2.0 * half * f / np.maximum(z, 1.0) + 3.0
            seen &= near | boxes_reach(px - reach[:, None], px + reach[:, None], views)
            birds.draw(img, project, f, t, np.flatnonzero(seen))

    def _draw_targets(self, img: np.ndarray, r_ce: np.ndarray, c_enu: np.ndarray, targets: Sequence[TargetPose],
                      sun: np.ndarray, brightness: float, overcast: float = 0.0) -> tuple[TargetLabel, ...]:
        w, h = self.camera.width_px, self.camera.height_px
        fx, fy = self.camera.focal_px
        order = sorted(range(len(targets)), key=lambda i: -float(np.linalg.norm(np.asarray(targets[i].position_enu) - c_enu)))
        labels = []
        for i in order:
            t = targets[i]
            drawn = draw_model(img, self._model(t.kind, t.variant), t.attitude.as_matrix(), np.asarray(t.position_enu, float),
                               r_ce, c_enu, (fx, fy), sun, brightness, overcast)
            if drawn is None:
                continue
            lo, hi, centre_px, rng_m = drawn
            x0, y0 = max(lo[0], 0.0), max(lo[1], 0.0)
            x1, y1 = min(hi[0], float(w)), min(hi[1], float(h))
            truncated = bool(lo[0] < 0 or lo[1] < 0 or hi[0] > w or hi[1] > h)
            labels.append(TargetLabel(i, t.kind, (float(x0), float(y0), float(x1), float(y1)), centre_px, rng_m, truncated))
        return tuple(sorted(labels, key=lambda lab: lab.index))


def draw_model(img: np.ndarray, m: _CompiledModel, rot: np.ndarray, pos: np.ndarray, r_ce: np.ndarray, c_enu: np.ndarray,
               focal_px: tuple[float, float], sun: np.ndarray, brightness: float, overcast: float = 0.0
               ) -> tuple[np.ndarray, np.ndarray, tuple[float, float], float] | None:
    """Draw compiled model ``m`` (body -> world rotation ``rot``, world position ``pos``) into ``img`` for a
    pinhole camera at ``c_enu`` (optical -> world ``r_ce``, principal point at the image centre), lit by
    ``sun`` at ``brightness`` under ``overcast`` (:func:`~sitl.world.camera.lighting.sun_share`). Returns the
    unclipped pixel extent (lo, hi), the centre pixel and the range (m), or None when the target is behind
    the lens, too close or outside the image."""
    h, w = img.shape[:2]
    fx, fy = focal_px

    def to_cam(p: np.ndarray) -> np.ndarray:
        return (p.reshape(-1, 3) @ rot.T + pos - c_enu) @ r_ce

    centre_c = to_cam(np.zeros(3))[0]
    if centre_c[2] < 0.3:
        return None
    sc, rc_a, rc_b = to_cam(m.sphere_c), to_cam(m.rod_a), to_cam(m.rod_b)
    dc = to_cam(m.disc_pts).reshape(-1, _DISC_SIDES, 3)
    if np.concatenate([sc[:, 2], rc_a[:, 2], rc_b[:, 2], dc[..., 2].ravel()]).min() < 0.05:
        return None  # part of the target is behind the lens: too close to draw

    def px(c: np.ndarray) -> np.ndarray:
        return np.stack([0.5 * w + fx * c[..., 0] / c[..., 2], 0.5 * h + fy * c[..., 1] / c[..., 2]], axis=-1)

    ps, pa, pb, pd = px(sc), px(rc_a), px(rc_b), px(dc)
    rs = m.sphere_r * fx / sc[:, 2]
    rr = m.rod_r * fx / (0.5 * (rc_a[:, 2] + rc_b[:, 2]))
    lo = np.min(np.vstack([ps - rs[:, None], np.minimum(pa, pb) - rr[:, None], pd.reshape(-1, 2)]), axis=0)
    hi = np.max(np.vstack([ps + rs[:, None], np.maximum(pa, pb) + rr[:, None], pd.reshape(-1, 2)]), axis=0)
    if min(hi[0], float(w)) - max(lo[0], 0.0) < 1.0 or min(hi[1], float(h)) - max(lo[1], 0.0) < 1.0:
        return None
    # Lighting: top surfaces catch the sun, the rest sees sky light.
    shade = brightness * (0.55 + 0.45 * sun_share(float(rot[:, 2] @ sun), overcast))
    _paint_model(img, m, ps, rs, pa, pb, rr, pd, sc[:, 2], 0.5 * (rc_a[:, 2] + rc_b[:, 2]), dc[..., 2].mean(axis=1), shade)
    cpx = px(centre_c)
    return lo, hi, (float(cpx[0]), float(cpx[1])), float(np.linalg.norm(centre_c))


def _paint_model(img: np.ndarray, m: _CompiledModel, ps, rs, pa, pb, rr, pd, zs, zr, zd, shade: float) -> None:
    """Paint the projected primitives far to near (painter's order), discs blended by their alpha."""
    s = 16.0  # fixed-point sub-pixel drawing (4 fractional bits)
    items = [(z, 0, k) for k, z in enumerate(zs)] + [(z, 1, k) for k, z in enumerate(zr)] + [(z, 2, k) for k, z in enumerate(zd)]
    items.sort(key=lambda it: -it[0])
    sphere_cols, rod_cols, disc_cols = (np.clip(c * shade, 0, 255).tolist() for c in (m.sphere_col, m.rod_col, m.disc_col))
    for _, kind, k in items:
        if kind == 0:
            col = tuple(sphere_cols[k])
            cv2.circle(img, (int(ps[k, 0] * s), int(ps[k, 1] * s)), max(int(rs[k] * s), 8), col, -1, cv2.LINE_AA, 4)
        elif kind == 1:
            col = tuple(rod_cols[k])
            cv2.line(img, (int(pa[k, 0] * s), int(pa[k, 1] * s)), (int(pb[k, 0] * s), int(pb[k, 1] * s)), col,
                     max(int(round(2 * rr[k])), 1), cv2.LINE_AA, 4)
        else:
            poly = (pd[k] * s).astype(np.int32)
            bx, by, bw, bh = cv2.boundingRect(poly)
            bx0, by0 = max(bx // 16 - 1, 0), max(by // 16 - 1, 0)
            bx1, by1 = min((bx + bw) // 16 + 2, img.shape[1]), min((by + bh) // 16 + 2, img.shape[0])
            if bx1 <= bx0 or by1 <= by0:
                continue
            roi = img[by0:by1, bx0:bx1]
            layer = roi.copy()
            col = tuple(disc_cols[k])
            shifted = poly - np.array([bx0 * 16, by0 * 16], np.int32)
            cv2.fillPoly(layer, [shifted], col, cv2.LINE_AA, 4)
            a = float(m.disc_alpha[k])
            cv2.addWeighted(layer, a, roi, 1.0 - a, 0.0, dst=roi)


def viewports(regions: Sequence[Region] | None, width: int, height: int, margin_px: int = VIEW_MARGIN_PX,
              max_share: float = 0.6) -> list[Region] | None:
    """The views to draw for ``regions``: each widened by ``margin_px``, its corners moved out to the
    16-pixel grid of the JPEG blocks (and so the coarse grid's), cut to the frame, and overlapping
    ones merged. None (draw the whole frame) for no regions, when the views would cover more than
    ``max_share`` of the frame (one whole frame is cheaper) or when the frame is not a whole number of
    blocks."""
    if regions is None or width % _BLOCK or height % _BLOCK:
        return None
    views: list[list[int]] = []
    for x0, y0, x1, y1 in regions:
        v = [max(int(math.floor((x0 - margin_px) / _BLOCK)) * _BLOCK, 0), max(int(math.floor((y0 - margin_px) / _BLOCK)) * _BLOCK, 0),
             min(int(math.ceil((x1 + margin_px) / _BLOCK)) * _BLOCK, width), min(int(math.ceil((y1 + margin_px) / _BLOCK)) * _BLOCK, height)]
        if v[2] > v[0] and v[3] > v[1]:
            views.append(v)
    while pair := next(((i, j) for i, j in itertools.combinations(range(len(views)), 2) if _overlap(views[i], views[j])), None):
        i, j = pair  # the two become their union's box, until no two views overlap
        a, b = views[i], views.pop(j)
        views[i] = [min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])]
    if sum((v[2] - v[0]) * (v[3] - v[1]) for v in views) > max_share * width * height:
        return None
    return [(v[0], v[1], v[2], v[3]) for v in views]


def _overlap(a: Sequence[int], b: Sequence[int]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _rows(mask_lo: np.ndarray, height: int) -> tuple[int, int] | None:
    """The full-size row span covering the coarse grid's rows where ``mask_lo`` holds (one cell of margin)."""
    rows = np.flatnonzero(mask_lo.any(axis=1))
    if rows.size == 0:
        return None
    return max((int(rows[0]) - 1) * _COARSE, 0), min((int(rows[-1]) + 2) * _COARSE, height)


def _warp_into(out: np.ndarray, texture: np.ndarray, h_tex_to_img: np.ndarray, rows: tuple[int, int], border: int,
               border_value) -> None:
    """Warp ``texture`` by the homography into ``out``'s rows ``rows`` only."""
    r0, r1 = rows
    shift = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -float(r0)], [0.0, 0.0, 1.0]])
    roi = out[r0:r1]
    cv2.warpPerspective(texture, shift @ h_tex_to_img, (out.shape[1], r1 - r0), dst=roi, flags=cv2.INTER_LINEAR,
                        borderMode=border, borderValue=border_value)


def _sky_rows(sky: Sky, rays: np.ndarray, ground: np.ndarray, horizon: np.ndarray, camera_enu: np.ndarray) -> np.ndarray:
    """The background's colour over the coarse grid: the sky's along ``rays`` where they do not meet the
    ground, ``horizon`` where they do; the sky worked out only on the rows that hold some of it."""
    out = np.empty(ground.shape + (3,), np.float32)
    out[:] = horizon
    rows = np.flatnonzero(~ground.all(axis=1))
    r0, r1 = int(rows[0]), int(rows[-1]) + 1
    out[r0:r1] = np.where(ground[r0:r1, :, None], horizon, sky.colour(rays[r0:r1], camera_enu))
    return out


def _gain_table(gains: tuple[float, float, float]) -> np.ndarray:
    """The BGR channel gains as a lookup table (256 x 1 x 3): each grey level times its channel's gain,
    rounded and saturated as ``cv2.multiply`` does (worked out by it, on the 256 levels), applied in one
    table lookup a pixel instead of a multiplication through floats."""
    levels = np.repeat(np.arange(256, dtype=np.uint8)[:, None, None], 3, axis=2)
    return cv2.multiply(levels, tuple(gains) + (1.0,), dtype=cv2.CV_8U)


def _motion_blur(img: np.ndarray, length_px: float, angle_rad: float) -> np.ndarray:
    n = int(min(max(round(length_px), 2), 25)) | 1
    kernel = np.zeros((n, n), np.float32)
    c = n // 2
    dx, dy = math.cos(angle_rad) * c, math.sin(angle_rad) * c
    cv2.line(kernel, (int(round(c - dx)), int(round(c - dy))), (int(round(c + dx)), int(round(c + dy))), 1.0, 1, cv2.LINE_AA)
    kernel /= kernel.sum()
    return cv2.filter2D(img, -1, kernel, borderType=cv2.BORDER_REFLECT)
