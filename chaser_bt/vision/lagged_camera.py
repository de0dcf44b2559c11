"""A camera one frame behind the tick, in lock-step: frame k is drawn while frame k-1 is processed.

A :class:`~chaser_bt.vision.pipeline.CameraSensor` reads a frame and processes it inside the tick
that asked for it: the estimate is as fresh as the frame, and the drawing, the detector and the
tick run one after another. On an aircraft the camera pipeline runs beside the control loop and the
tick reads its latest estimate, a frame's processing old (:mod:`chaser_bt.vision.perception`). A
:class:`LaggedCamera` is that, in lock-step so a seed still flies one flight:

- at tick k it plans frame k (where the detector looks, which regions are drawn) from the tracks as
  frame k-2 left them, takes frame k's shot and hands it to the renderer;
- then it processes frame k-1 (drawn since the last tick) and returns that frame's estimate,
  stamped with frame k-1's time: 0.1 s old at a 10 Hz tick.

A rehearsal's camera is one (``sitl.bench.sensors``). The source takes a shot at the tick and
develops it at the next: with a :class:`~sitl.world.camera.render_process.RenderProcess` behind the
source, frame k is drawn in the child while this process runs the detector on frame k-1, the tree
and the simulator; without one it is drawn here when it is needed. The frames, and so the flight,
are the same either way. A source that does not read out regions (the flight recorder's, which
keeps whole frames) gets whole shots. Replaying a rehearsal's log
(:func:`chaser_bt.log.replay.recorded_camera_factory`) puts one over the recorded frames, so each
frame is processed in the tick after its own with its own tick's inputs, as it was flown.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, Sequence

from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.vision.frame_source import Frame, Region, reads_regions
from chaser_bt.vision.pipeline import CameraSensor, FramePlan, OwnshipPose

__all__ = ["LaggedCamera", "ShotSource"]


class ShotSource(Protocol):
    """A frame source that takes a shot now and develops it later (:class:`~sitl.bench.sensors.ScenarioFrameSource`)."""

    def shot(self, t: float, regions: Sequence[Region] | None = None) -> Any: ...

    def develop(self, shot: Any, regions: Sequence[Region] | None = None) -> Frame | None: ...


@dataclass(frozen=True)
class _Taken:
    """A frame shot, not processed yet, with the tick's inputs."""

    shot: Any
    plan: FramePlan | None  # None: a whole shot, planned when processed
    ownship: OwnshipPose
    target_range_m: float | None
    cue: TargetCue | None


@dataclass
class LaggedCamera(CameraSensor):
    """A camera sensor over a :class:`ShotSource`, one frame behind the tick.

    Args:
        stale_after_s: the frame processed at a tick older than this (the node was not ticked for a
            while) gives no estimate; the pipeline still takes it, so its tracks go on.
    """

    stale_after_s: float = 0.5
    lag_frames: ClassVar[int] = 1
    _taken: _Taken | None = field(default=None, init=False, repr=False)

    def step(self, t: float, ownship: OwnshipPose, target_range_m: float | None = None,
             cue: TargetCue | None = None) -> TargetEstimate | None:
        """Shoot frame ``t`` and process the one shot at the last call; that one's estimate, or None
        (also when the source has no frame for that shot: a replayed log keeps only some)."""
        source: ShotSource = self.source  # type: ignore[assignment]
        plan = None
        if not self.whole_frames and reads_regions(source):
            plan = self.pipeline.plan(t, ownship, cue)
        shot = source.shot(t, None if plan is None else plan.regions)
        done, self._taken = self._taken, _Taken(shot, plan, ownship, target_range_m, cue)
        if done is None:
            return None
        frame = source.develop(done.shot, None if done.plan is None else done.plan.regions)
        if frame is None:
            return None
        self.last_frame = frame
        est = self.pipeline.process(frame, done.ownship, done.target_range_m, done.cue, done.plan)
        return est if t - frame.t <= self.stale_after_s else None
