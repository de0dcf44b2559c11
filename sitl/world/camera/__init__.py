"""The simulated camera: what the chaser's camera sees, rendered from ground truth (paper section 3.1).

:mod:`sitl.world.camera.scene` makes the ground texture, :mod:`sitl.world.camera.models` the target airframes,
:mod:`sitl.world.camera.renderer` draws a frame and :mod:`sitl.world.camera.frame_source` serves frames to a
mission like a real camera would. The labelled training sets are the bench's (:mod:`sitl.bench.camera_dataset`).
"""

from sitl.world.camera.renderer import (
    Lighting,
    RenderedFrame,
    Renderer,
    TargetLabel,
    TargetPose,
)

__all__ = ["Lighting", "RenderedFrame", "Renderer", "TargetLabel", "TargetPose"]
