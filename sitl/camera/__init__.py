"""The simulated camera: what the chaser's camera sees, rendered from ground truth (paper section 3.1).

:mod:`sitl.camera.scene` makes the ground texture, :mod:`sitl.camera.models` the target airframes,
:mod:`sitl.camera.renderer` draws a frame, :mod:`sitl.camera.dataset` writes labelled training sets
and :mod:`sitl.camera.frame_source` serves frames to a mission like a real camera would.
"""

from sitl.camera.renderer import Lighting, RenderedFrame, Renderer, TargetLabel, TargetPose

__all__ = ["Lighting", "RenderedFrame", "Renderer", "TargetLabel", "TargetPose"]
