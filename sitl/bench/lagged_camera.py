"""The rehearsal's camera, one frame behind the tick: frame k is drawn while frame k-1 is processed.

A :class:`~chaser_bt.vision.pipeline.CameraSensor` reads a frame and processes it inside the tick
that asked for it: the estimate is as fresh as the frame, and the drawing, the detector and the
tick run one after another. On an aircraft the camera pipeline runs beside the control loop and the
tick reads its latest estimate, a frame's processing old (:mod:`chaser_bt.vision.perception`). A
:class:`LaggedCamera` is that, in lock-step so a seed still flies one flight:

- at tick k it plans frame k (where the detector looks, which regions are drawn) from the tracks as
  frame k-2 left them, takes frame k's shot and hands it to the renderer;
- then it processes frame k-1 (drawn since the last tick) and returns that frame's estimate,
  stamped with frame k-1's time: 0.1 s old at a 10 Hz tick.

With a :class:`~sitl.world.camera.render_process.RenderProcess` the drawing of frame k runs in the
child while this process runs the detector on frame k-1, the tree and the simulator; without one
the frame is drawn here when it is needed. The frames, and so the flight, are the same either way.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.vision.frame_source import Frame, Region
from chaser_bt.vision.pipeline import CameraSensor, FramePlan, OwnshipPose
from sitl.world.camera.frame_source import Shot

if TYPE_CHECKING:
    from sitl.bench.sensors import ScenarioFrameSource
    from sitl.world.camera.render_process import RenderProcess

__all__ = ["LaggedCamera"]


@dataclass(frozen=True)
class _Taken:
    """A frame shot and handed to the renderer, not processed yet, with the tick's inputs."""

    shot: Shot
    regions: tuple[Region, ...] | None
    plan: FramePlan | None
    ownship: OwnshipPose
    target_range_m: float | None
    cue: TargetCue | None


@dataclass
class LaggedCamera(CameraSensor):
    """A camera sensor over a :class:`~sitl.bench.sensors.ScenarioFrameSource` one frame behind the tick.

    Args:
        renderer: draws the shots in a process of its own; None: drawn here.
        stale_after_s: the frame processed at a tick older than this (the node was not ticked for a
            while) gives no estimate; the pipeline still takes it, so its tracks go on.
    """

    renderer: RenderProcess | None = None
    stale_after_s: float = 0.5
    _taken: _Taken | None = field(default=None, init=False, repr=False)

    def step(self, t: float, ownship: OwnshipPose, target_range_m: float | None = None,
             cue: TargetCue | None = None) -> TargetEstimate | None:
        """Shoot frame ``t`` and process the one shot at the last call; that one's estimate, or None."""
        source: ScenarioFrameSource = self.source  # type: ignore[assignment]
        plan = None if self.whole_frames else self.pipeline.plan(t, ownship, cue)
        regions = None if plan is None else plan.regions
        shot = source.shot(t)
        if self.renderer is not None:
            self.renderer.submit(shot, regions)
        done, self._taken = self._taken, _Taken(shot, regions, plan, ownship, target_range_m, cue)
        if done is None:
            return None
        frame = self._develop(done)
        self.last_frame = frame
        est = self.pipeline.process(frame, done.ownship, done.target_range_m, done.cue, done.plan)
        return est if t - frame.t <= self.stale_after_s else None

    def _develop(self, taken: _Taken) -> Frame:
        """The frame of ``taken``: collected from the renderer, or drawn here."""
        source: ScenarioFrameSource = self.source  # type: ignore[assignment]
        if self.renderer is None:
            return source.develop(taken.shot, taken.regions)
        image, views, labels, _ = self.renderer.collect()
        source.accept(taken.shot, labels)
        return Frame(taken.shot.t, image, taken.shot.index, views)
