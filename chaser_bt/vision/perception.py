"""Perception beside the control loop: the camera pipeline in its own threads, the tick reading its latest result.

Inline, the VisionPipeline behaviour reads a frame and runs detector and trackers inside the tree's
tick (26-59 ms with the detector), so every command the tick sends leaves that much later, and
later still on a detector frame. On a flight the paper ran detector and trackers as processes of
their own; here a :class:`PerceptionWorker` owns the :class:`~chaser_bt.vision.pipeline.CameraSensor`
and runs two daemon threads:

* **capture** reads the source as it gives frames (at most ``max_fps`` a second, for sources that
  never block: files and replays), stamps each with the clock's time when it arrived, and keeps the
  newest; a frame replaced before it was processed is dropped and counted;
* **process** takes the newest frame with the newest inputs the tick submitted (ownship pose,
  range cue, cue, detector setup; inputs older than ``stale_after_s`` are not used: the node is not
  being ticked, and the frame is dropped), runs the pipeline and publishes a :class:`PerceptionResult`: the
  estimate with its frame's time, the frame (for streaming and the flight log) and the followed box.

The tick never waits: :meth:`PerceptionWorker.submit`, :meth:`~PerceptionWorker.configure` and
:meth:`~PerceptionWorker.latest` swap or read one reference under a lock held for no work. OpenCV,
onnxruntime and torch release the GIL while they compute, so the tick runs while a frame is being
processed. The estimate the tick reads is as old as one frame's processing plus the wait for the
next frame (its ``t`` is the frame's time, so ``TargetInView`` judges its age as before).

The ownship pose submitted at the tick is carried to the frame's time along its velocity; the
attitude is the tick's (the pipeline smooths it). An exception while reading or processing is
logged, counted and the worker goes on with the next frame; a worker that stopped or died, or whose
last result is older than ``stale_after_s``, says so in :meth:`~PerceptionWorker.health`, and the
behaviour fails with that sentence so the tree's hover-on-stale logic takes over.

Thread counts: the detector runs with one intra-op thread (``Detector(threads=1)``: torch's is
process-wide, onnxruntime's per session, inter-op 1) and a flight sets OpenCV to one thread
(``cv2.setNumThreads(1)``), so the processing thread uses one core and the tick loop and the MAVLink
link keep the other (docs/vision.md). Rehearsals do not use the worker: their camera
(``chaser_bt.vision.lagged_camera.LaggedCamera``) keeps the same one-frame lag in lock-step with the
simulator, so a seed reproduces a rehearsal exactly.
"""

from __future__ import annotations

import logging
import math
import threading
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from chaser_bt.clock import Clock
from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.vision.detection import Detection
from chaser_bt.vision.frame_source import Frame, FrameSource
from chaser_bt.vision.pipeline import CameraSensor, OwnshipPose, VisionPipeline

__all__ = ["PerceptionResult", "PerceptionStats", "PerceptionWorker", "PipelineSetup"]

log = logging.getLogger(__name__)

_LOGGED_ERRORS = 3  # the first few errors with their traceback, then one line every _ERROR_LOG_EVERY
_ERROR_LOG_EVERY = 100


@dataclass(frozen=True)
class PipelineSetup:
    """What a VisionPipeline node wants of the camera's pipeline; :meth:`apply` makes it so (idempotent).

    Args:
        detector: the detector to run; None keeps the pipeline's own (the camera's).
        detector_name: its name (a shipped model's or a weights path); a change restarts the tracks.
        classes: class names that count as the target; empty keeps the pipeline's.
        target_on_ground: range a target standing on flat ground where its bearing meets it.
        detect_every: run the detector on every k-th frame; 0 keeps the pipeline's.
    """

    detector: Callable[[np.ndarray], Sequence[Detection]] | None = None
    detector_name: str = ""
    classes: tuple[str, ...] = ()
    target_on_ground: bool = False
    detect_every: int = 0

    def apply(self, pipeline: VisionPipeline) -> None:
        """Put this setup into ``pipeline``; nothing changes (tracks live on) when it is already there."""
        classes = self.classes or pipeline.config.classes
        if self.detect_every and self.detect_every != pipeline.config.detect_every:
            pipeline.config = replace(pipeline.config, detect_every=self.detect_every)
        if self.detector is not None and pipeline.detector_name != self.detector_name:
            pipeline.use_detector(self.detector, self.detector_name, classes, self.target_on_ground)
        elif classes != pipeline.config.classes or self.target_on_ground != pipeline.config.target_on_ground:
            pipeline.use_detector(pipeline.detector, pipeline.detector_name, classes, self.target_on_ground)


@dataclass(frozen=True)
class PerceptionResult:
    """One processed frame: the estimate (None: no target in it), the frame, the followed box and its
    label (:attr:`chaser_bt.vision.trackers.Track.label`).

    ``processed_t`` is the clock's time when processing ended; ``estimate.t`` and ``frame.t`` are
    the frame's.
    """

    frame: Frame
    estimate: TargetEstimate | None
    box: tuple[float, float, float, float] | None
    processed_t: float
    sequence: int
    label: str = ""


@dataclass(frozen=True)
class PerceptionStats:
    """Counters of a worker, for logs and diagnostics."""

    running: bool
    frames_read: int
    frames_processed: int
    frames_dropped: int  # replaced by a newer frame before processing, or read before any inputs came
    frames_without_time: int  # the clock had no time yet (vehicle time before the first telemetry)
    read_errors: int
    errors: int
    last_error: str


@dataclass(frozen=True)
class _Inputs:
    ownship: OwnshipPose
    target_range_m: float | None
    cue: TargetCue | None


class PerceptionWorker:
    """A camera pipeline in its own threads (see the module docstring); the ``camera`` resource of a flight.

    Args:
        sensor: the frame source and pipeline the worker owns from :meth:`start` on (the tick must
            not call ``sensor.step`` meanwhile).
        clock: the mission's clock: stamps frames and judges staleness.
        max_fps: read the source at most this often (s^-1); None: as fast as it gives frames (a live
            camera blocks until its next frame; a file or a replay would be read flat out).
        stale_after_s: :meth:`health` reports a last result older than this (s of the clock).
        join_timeout_s: how long :meth:`stop` waits for each thread.
    """

    def __init__(self, sensor: CameraSensor, clock: Clock, *, max_fps: float | None = None,
                 stale_after_s: float = 1.0, join_timeout_s: float = 2.0) -> None:
        if max_fps is not None and not max_fps > 0:
            raise ValueError(f"max_fps must be positive or None, got {max_fps}")
        if not stale_after_s > 0:
            raise ValueError(f"stale_after_s must be positive, got {stale_after_s}")
        self.sensor = sensor
        self.clock = clock
        self.max_fps = max_fps
        self.stale_after_s = float(stale_after_s)
        self.join_timeout_s = float(join_timeout_s)
        self._lock = threading.Lock()
        self._new_frame = threading.Condition(self._lock)
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._inputs: _Inputs | None = None
        self._setup: PipelineSetup | None = None
        self._frame: Frame | None = None  # newest frame not yet taken for processing
        self._result: PerceptionResult | None = None
        self._died = ""
        self._frames_read = self._processed = self._dropped = self._untimed = 0
        self._read_errors = self._errors = 0
        self._last_error = ""

    # -- what the tree's resources and the recorder see ------------------------------------------

    @property
    def pipeline(self) -> VisionPipeline:
        """The pipeline the worker runs (read its settings; its state belongs to the processing thread)."""
        return self.sensor.pipeline

    @property
    def last_frame(self) -> Frame | None:
        """The frame of the latest result (for streaming and logs)."""
        result = self._result
        return None if result is None else result.frame

    # -- lifecycle ---------------------------------------------------------------------------------

    @property
    def running(self) -> bool:
        """True while both threads run and no stop was asked for."""
        return bool(self._threads) and not self._stop.is_set() and all(t.is_alive() for t in self._threads)

    def start(self) -> None:
        """Start the capture and processing threads (daemons); does nothing while they run."""
        if self.running:
            return
        if self._threads:
            self.stop()
        self._stop.clear()
        self._died = ""
        self._threads = [threading.Thread(target=self._guard, args=(loop,), name=f"perception-{name}", daemon=True)
                         for name, loop in (("capture", self._capture_loop), ("process", self._process_loop))]
        for thread in self._threads:
            thread.start()
        log.info("perception worker started (max %s frames/s)", "any" if self.max_fps is None else f"{self.max_fps:g}")

    def stop(self) -> bool:
        """Stop both threads and join each for up to ``join_timeout_s``; True when both ended. Never raises."""
        self._stop.set()
        with self._new_frame:
            self._new_frame.notify_all()
        ended = True
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(self.join_timeout_s)
            ended = ended and not thread.is_alive()
        if not ended:
            log.warning("perception worker: a thread did not end within %.1f s (it is a daemon: it ends with the process)",
                        self.join_timeout_s)
        return ended

    def close(self) -> None:
        """Stop the worker and close its frame source (the end of a flight). Never raises."""
        self.stop()
        try:
            self.sensor.source.close()
        except Exception:
            log.exception("perception worker: closing the frame source raised")

    # -- the tick's side: O(1), never waits on processing ------------------------------------------

    def submit(self, ownship: OwnshipPose, target_range_m: float | None = None, cue: TargetCue | None = None) -> None:
        """The newest inputs for the next frame processed: ownship pose, telemetry range, cue."""
        inputs = _Inputs(ownship, target_range_m, cue)
        with self._lock:
            self._inputs = inputs

    def configure(self, setup: PipelineSetup) -> None:
        """The detector setup the processing thread applies before its next frame."""
        with self._lock:
            self._setup = setup

    def latest(self) -> PerceptionResult | None:
        """The latest processed frame's result (None before the first)."""
        with self._lock:
            return self._result

    def health(self, now: float) -> str | None:
        """Why the latest result cannot be trusted at ``now`` (a sentence), or None when it can."""
        with self._lock:
            result, died, errors, last_error = self._result, self._died, self._errors, self._last_error
        if died:
            return f"perception worker died: {died}"
        if not self.running:
            return "perception worker stopped"
        errs = f" ({errors} processing errors, last: {last_error})" if errors else ""
        if result is None:
            return f"perception: no frame processed yet{errs}"
        age = now - result.frame.t
        if age > self.stale_after_s:
            return f"perception stale: the last processed frame is {age:.1f} s old{errs}"
        return None

    def stats(self) -> PerceptionStats:
        """The counters now."""
        with self._lock:
            return PerceptionStats(self.running, self._frames_read, self._processed, self._dropped, self._untimed,
                                   self._read_errors, self._errors, self._last_error)

    # -- the threads ------------------------------------------------------------------------------

    def _guard(self, loop: Callable[[], None]) -> None:
        """Run ``loop``; whatever ends it other than a stop is recorded, so :meth:`health` shows it."""
        try:
            loop()
        except BaseException as exc:  # noqa: BLE001 - a thread has nowhere to raise to: record it
            log.critical("perception worker died: %s", exc, exc_info=True)
            with self._new_frame:
                self._died = f"{type(exc).__name__}: {exc}"
                self._new_frame.notify_all()
            self._stop.set()

    def _capture_loop(self) -> None:
        next_read = -math.inf
        while not self._stop.is_set():
            if self.max_fps is not None:
                now = self.clock.now()
                if math.isfinite(now) and now < next_read:
                    self._stop.wait(next_read - now)
                    continue
                next_read = max(next_read + 1.0 / self.max_fps, now) if math.isfinite(now) else next_read
            source: FrameSource = self.sensor.source
            try:
                frame = source.read(self.clock.now())
            except Exception as exc:  # a camera glitch: counted, and the next read is tried
                self._count_error(exc, "reading a frame", read=True)
                self._stop.wait(0.05)
                continue
            if frame is None:  # no frame now (a dropped one, an ended file): try again shortly
                self._stop.wait(0.01 if self.max_fps is None else 1.0 / self.max_fps)
                continue
            t = self.clock.now()  # stamped when the source handed it over
            with self._new_frame:
                self._frames_read += 1
                if math.isfinite(t):
                    if self._frame is not None:
                        self._dropped += 1
                    self._frame = frame if frame.t == t else replace(frame, t=t)
                    self._new_frame.notify()
                else:
                    self._untimed += 1
            if not math.isfinite(t):
                self._stop.wait(0.05)

    def _process_loop(self) -> None:
        pipeline = self.sensor.pipeline
        while True:
            with self._new_frame:
                while self._frame is None and not self._stop.is_set():
                    self._new_frame.wait(0.5)
                if self._stop.is_set():
                    return
                frame, inputs, setup = self._frame, self._inputs, self._setup
                self._frame = None
                if inputs is None or frame.t - inputs.ownship.t > self.stale_after_s:
                    self._dropped += 1  # the tick has not asked (lately): no pose to place the frame with
                    continue
            try:
                if setup is not None:
                    setup.apply(pipeline)
                estimate = pipeline.process(frame, _at(inputs.ownship, frame.t), inputs.target_range_m, inputs.cue)
                track = pipeline.track
                box = None if track is None else (float(track.box[0]), float(track.box[1]), float(track.box[2]),
                                                  float(track.box[3]))
                label = "" if track is None else track.label
            except Exception as exc:  # a bad frame or a detector fault must not end perception
                self._count_error(exc, f"processing frame {frame.index}")
                continue
            done = self.clock.now()
            with self._lock:
                self._processed += 1
                self._result = PerceptionResult(frame, estimate, box, done, self._processed, label)

    def _count_error(self, exc: Exception, what: str, read: bool = False) -> None:
        with self._lock:
            if read:
                self._read_errors += 1
            else:
                self._errors += 1
            self._last_error = f"{type(exc).__name__}: {exc}"
            n = self._read_errors + self._errors
        if n <= _LOGGED_ERRORS:
            log.error("perception: %s raised (counted; the worker goes on)", what, exc_info=exc)
        elif n % _ERROR_LOG_EVERY == 0:
            log.error("perception: %d errors so far, the last %s: %s", n, what, exc)


def _at(pose: OwnshipPose, t: float) -> OwnshipPose:
    """``pose`` carried to time ``t`` along its velocity (the attitude is kept)."""
    dt = t - pose.t
    if dt == 0.0 or not np.all(np.isfinite(pose.velocity_enu)):
        return pose
    return OwnshipPose(t, pose.position_enu + pose.velocity_enu * dt, pose.velocity_enu, pose.attitude)
