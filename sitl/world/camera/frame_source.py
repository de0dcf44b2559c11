"""The simulator's camera as a :class:`chaser_bt.vision.frame_source.FrameSource`.

Frames are rendered from ground truth (the chaser's true pose, the targets' true poses): that is
the sensor, not a leak, and the mission only ever sees the pixels. Motion blur follows the
ownship's rotation between frames (``exposure_s`` of it smears the image).

A frame is taken in two steps: :meth:`SimulatorFrameSource.shot` notes the scene at the simulator's
time (a :class:`Shot`: poses and blur, cheap), :meth:`SimulatorFrameSource.develop` draws it. A
rehearsal may draw a shot later or in another process (:mod:`sitl.world.camera.render_process`) while the
simulator flies on; the frame is the same.

A simulator flying in :class:`~sitl.world.surroundings.Surroundings` (it has ``surroundings``) also
shows the scenario's birds: each shot carries them where the simulator has them (the radar sees the
same birds there), and they are drawn unlabelled, so the targets' labels are as without them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.frame_source import Frame, Region
from sitl.world.camera.renderer import (
    Lighting,
    Renderer,
    TargetPose,
    attitude_from_velocity,
)
from sitl.world.camera.distractors import BirdPose
from sitl.world.camera.scene import GroundScene, make_ground
from sitl.world.camera.world import CameraWorld

__all__ = ["Shot", "SimTarget", "SimulatorFrameSource"]


@dataclass(frozen=True)
class SimTarget:
    """A target the camera can see: its kind and a path with ``position_enu(t)`` and ``velocity_enu(t)``
    (a ``sitl.world.targets`` path or an intruder); attitude from ``path.attitude(t)`` if it has one, else
    from its velocity; ``variant`` picks the colour scheme of kinds that have several (a person's clothes)."""

    kind: str
    path: Any
    variant: int = 0

    def pose(self, t: float) -> TargetPose:
        att = self.path.attitude(t) if hasattr(self.path, "attitude") else attitude_from_velocity(self.path.velocity_enu(t))
        return TargetPose(self.kind, np.asarray(self.path.position_enu(t), float), att, self.variant)


@dataclass(frozen=True)
class Shot:
    """The scene at one instant, before it is drawn: what :meth:`SimulatorFrameSource.develop` needs.

    ``t`` is the frame's stamp (the mission clock's), ``sim_t`` the simulator's time (it places the
    world's birds and aircraft and the camera's drift), ``index`` the frame's number; ``birds`` the
    scenario's birds present then.
    """

    t: float
    sim_t: float
    index: int
    position_enu: np.ndarray
    attitude: Rotation
    targets: tuple[TargetPose, ...]
    blur_px: float
    birds: tuple[BirdPose, ...] = ()


class SimulatorFrameSource:
    """Renders the chaser's camera from a running simulator.

    Args:
        simulator: a ``sitl.simulator.Simulator`` (reads ``truth`` and ``time_s``).
        camera_model: the camera (its size is the frame size).
        targets: what to draw.
        seed: sensor-noise seed.
        lighting: scene lighting; ground_seed: the procedural ground's layout.
        exposure_s: shutter time for motion blur.
        ground: a ground already made (shared between runs: making one takes a second or two);
            None makes the one of ``ground_seed``.
        world: a camera world (:mod:`sitl.world.camera.world`) to render instead: its ground, sky,
            clutter, distractors, camera effects and lighting replace ``ground`` and ``lighting``;
            or a function making one, called at the first frame drawn (a source that only takes
            shots, for a renderer elsewhere, never builds it).
    """

    def __init__(self, simulator: Any, camera_model: CameraModel, targets: Sequence[SimTarget], seed: int,
                 lighting: Lighting = Lighting(), ground_seed: int = 7, exposure_s: float = 0.01,
                 ground: GroundScene | None = None, world: CameraWorld | Callable[[], CameraWorld] | None = None) -> None:
        self.simulator = simulator
        self.camera = camera_model
        self.targets = list(targets)
        self.lighting = world.lighting if isinstance(world, CameraWorld) else lighting
        self.exposure_s = exposure_s
        self._scene = (world, ground, ground_seed, seed)
        self._renderer: Renderer | None = None
        self.rng = np.random.default_rng(seed)
        self._last: tuple[float, Rotation] | None = None
        self._index = 0
        self.last_labels = ()

    reads_regions = True  # see chaser_bt.vision.frame_source

    @property
    def renderer(self) -> Renderer:
        """The renderer, made at the first frame drawn (with its world, when that is made lazily)."""
        if self._renderer is None:
            world, ground, ground_seed, seed = self._scene
            if callable(world):
                world = world()
                self.lighting = world.lighting
            if world is not None:
                self._renderer = Renderer(self.camera, world=world, noise_seed=seed)
            else:
                self._renderer = Renderer(self.camera, ground if ground is not None else make_ground(ground_seed), noise_seed=seed)
        return self._renderer

    def read(self, t: float, regions: Sequence[Region] | None = None) -> Frame | None:
        """The frame at the simulator's time, stamped ``t``; only ``regions`` drawn when given
        (:meth:`Renderer.render`)."""
        return self.develop(self.shot(t), regions)

    def shot(self, t: float) -> Shot:
        """The scene now, stamped ``t``: the chaser's and the targets' poses and the blur of the
        chaser's rotation since the last shot."""
        truth = self.simulator.truth
        sim_t = float(self.simulator.time_s)
        att = truth.attitude
        blur = 0.0
        if self._last is not None and sim_t > self._last[0]:
            rate = np.linalg.norm((att * self._last[1].inv()).as_rotvec()) / (sim_t - self._last[0])
            blur = rate * self.exposure_s * self.camera.focal_px[0]
        self._last = (sim_t, att)
        surroundings = getattr(self.simulator, "surroundings", None)  # a bare test double has none
        birds = surroundings.bird_poses(sim_t) if surroundings is not None else ()
        out = Shot(t, sim_t, self._index, np.array(truth.pos_enu, float), att, tuple(tg.pose(sim_t) for tg in self.targets), blur,
                   birds)
        self._index += 1
        return out

    def develop(self, shot: Shot, regions: Sequence[Region] | None = None) -> Frame:
        """Draw ``shot`` (only ``regions`` when given); shots must be developed in the order taken
        (the sensor noise is drawn from one stream)."""
        renderer = self.renderer  # first: a world made now brings its lighting
        frame = renderer.render(shot.position_enu, shot.attitude, list(shot.targets), self.lighting, self.rng,
                                blur_px=shot.blur_px, t=shot.sim_t, regions=regions, birds=shot.birds)
        self.last_labels = frame.labels  # for scoring only
        return Frame(shot.t, frame.image, shot.index, frame.views)

    def close(self) -> None:
        """Nothing to release: frames are rendered on demand."""
