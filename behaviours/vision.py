"""Vision behaviours (paper section 3.1): the camera pipeline and the "target in view" check.

:class:`VisionPipeline` ticks a :class:`chaser_bt.vision.pipeline.CameraSensor` handed to ``setup``
as ``camera=`` (beside ``link`` and ``clock``): one frame per tick through detector, trackers and
projection, and writes the :class:`~chaser_bt.cue.TargetEstimate` to ``/target/estimate``. The range
comes from the box size unless ``range_cue`` is remapped to a fresh position of the target (its own
telemetry, ``{@target/telemetry}``, in the paper's development flights). The tree picks the model:
``detector`` names a shipped detector (``tiny_yolo`` for the drones, ``person_yolo`` for search and
rescue; ``camera`` keeps the one the camera resource was built with) or ``weights`` a weights file
(a detector fine-tuned on your own footage: ``chaser-bt train-detector``), ``classes`` the class names
that count as the target, and ``target_on_ground`` ranges a target standing on flat ground (a
person) where its bearing meets the ground. ``cue`` (unset by default; remap it to the radar cue or
the target's telemetry) tells the pipeline where to look and which tracks can be the target
(:class:`~chaser_bt.vision.pipeline.PipelineConfig` ``focus`` and ``cue_gate_deg``), and
``detect_every`` sets how often the detector runs. With a
:class:`~chaser_bt.vision.perception.PerceptionWorker` as the camera (a real flight's default) the
pipeline runs in the worker's threads: the node hands it this tick's inputs, writes the latest
estimate (stamped with its frame's time) and fails, saying why, when the worker stopped, died or
fell behind. :class:`TargetInView` is SUCCESS while a confident estimate is fresh.
"""

from __future__ import annotations

import enum
from functools import lru_cache
from typing import Any

import numpy as np
import py_trees

from behaviours.base import VehicleBehaviour, optional_input, state_port
from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.tree import NodeKind, input_port, output_port, register_behaviour
from chaser_bt.vision.perception import PerceptionWorker, PipelineSetup
from chaser_bt.vision.pipeline import CameraSensor, OwnshipPose

Status = py_trees.common.Status

FRAMES_DROPPED_KEY = "/camera/frames_dropped"

ESTIMATE_KEY = "/target/estimate"


class DetectorChoice(enum.Enum):
    """Which detector the pipeline runs: the camera resource's own, or a shipped one by name."""

    CAMERA = "camera"
    TINY_YOLO = "tiny_yolo"      # s1000, phantom (the chase)
    PERSON_YOLO = "person_yolo"  # person (search and rescue)


@lru_cache(maxsize=4)
def _shipped(name: str):
    from chaser_bt.vision.detector.inference import shipped_detector

    return shipped_detector(name)


@lru_cache(maxsize=4)
def _from_file(path: str):
    from chaser_bt.vision.detector.inference import Detector

    return Detector(path)


@register_behaviour
class VisionPipeline(VehicleBehaviour):
    """Process one camera frame; SUCCESS with a target estimate written, FAILURE when none is seen."""

    NODE_KIND = NodeKind.ACTION
    REQUIRES_RESOURCES = ("camera",)  # checked before the flight (chaser_bt.mission.resources)
    INPUT_PORTS = {
        "range_cue": input_port(TargetCue, "A position of the target whose distance replaces the box-size range "
                                           "(remap to {@target/telemetry} for its own GPS); unset: range from vision",
                                required=False),
        "max_range_cue_age_s": input_port(float, "An older range cue is not used (s)", default=2.0, minimum=0),
        "detector": input_port(DetectorChoice, "Shipped detector to run (tiny_yolo, person_yolo) or camera: the camera's own",
                               default=DetectorChoice.CAMERA),
        "weights": input_port(str, "Detector weights file to run instead of detector (a fine-tuned .pt; its .onnx copy "
                                   "beside it is used when fresh); empty: use detector", default=""),
        "classes": input_port(list[str], "Class names that count as the target (empty: the camera's setting)", default=[]),
        "target_on_ground": input_port(bool, "Target stands on flat ground: range where the bearing meets it", default=False),
        "cue": input_port(TargetCue, "Where the target should be (radar or telemetry): the detector looks there and "
                                     "tracks far from it are not the target", required=False),
        "max_cue_age_s": input_port(float, "An older cue is not used (s)", default=2.0, minimum=0),
        "cue_coast_s": input_port(float, "A cue older than max_cue_age_s but younger than this still gates, carried on "
                                         "its velocity with a widening gate (0: off)", default=0.0, minimum=0),
        "cue_accel_mps2": input_port(float, "How hard the target may accelerate while the cue coasts (m/s^2)",
                                     default=6.0, minimum=0),
        "detect_every": input_port(int, "Run the detector on every k-th frame, trackers between (0: the camera's setting)",
                                   default=0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS = {
        "estimate": output_port(TargetEstimate, "Where the camera sees the target", default_key=ESTIMATE_KEY),
        "frames_dropped": output_port(dict, "Camera frames the source dropped, per reason (not 8-bit BGR, empty, "
                                            "resized); written when it changes", default_key=FRAMES_DROPPED_KEY),
    }

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        self._dropped_seen: dict[str, int] = {}
        if not isinstance(kwargs.get("camera"), (CameraSensor, PerceptionWorker)):
            raise KeyError(f"{self.name}: setup() needs camera=CameraSensor(...) or PerceptionWorker(...) "
                           f"(the mission runner passes it)")
        self.camera: CameraSensor | PerceptionWorker = kwargs["camera"]
        choice = self.get_input("detector")
        weights = str(self.get_input("weights") or "")
        if weights:
            _from_file(weights)  # loaded before take-off, like a shipped one
        elif choice is not DetectorChoice.CAMERA:
            _shipped(choice.value)  # loaded before take-off: missing weights stop the mission here, not in flight
        if isinstance(self.camera, PerceptionWorker):
            self.camera.start()  # the camera runs beside the tick from now on (stopped by whoever built it)

    def _setup(self) -> PipelineSetup:
        """This node's detector, classes, ground ranging and detector rate for the camera's pipeline."""
        choice: DetectorChoice = self.get_input("detector")
        every = int(self.get_input("detect_every"))
        if every < 0:
            raise ValueError(f"detect_every must be >= 0, got {every}")
        weights = str(self.get_input("weights") or "")
        if weights:
            detector, name = _from_file(weights), weights
        elif choice is not DetectorChoice.CAMERA:
            detector, name = _shipped(choice.value), choice.value
        else:
            detector, name = None, ""
        return PipelineSetup(detector, name, tuple(self.get_input("classes") or ()),
                             bool(self.get_input("target_on_ground")), every)

    def update(self) -> Status:
        threaded = isinstance(self.camera, PerceptionWorker)
        try:
            setup = self._setup()
        except (ValueError, FileNotFoundError) as e:
            self.feedback_message = f"detector: {e}"
            return Status.FAILURE
        if threaded:
            self.camera.configure(setup)  # applied by the worker before its next frame
        else:
            setup.apply(self.camera.pipeline)
        s = self.state
        if s.attitude is None or not np.all(np.isfinite(s.position_enu)):
            self.feedback_message = "no ownship attitude/position yet"
            return Status.FAILURE
        now = self._now()
        known_range = None
        ranged = optional_input(self, "range_cue")
        if ranged is not None and ranged.age(now) <= self.get_input("max_range_cue_age_s"):
            cam = self.camera.pipeline.camera.position_enu(s.position_enu, s.attitude)
            known_range = float(np.linalg.norm(ranged.position_enu - cam))
        cue = optional_input(self, "cue")
        if cue is not None and cue.age(now) > self.get_input("max_cue_age_s"):
            # A designated target's cue, briefly unconfirmed, still says where a detection cannot be it.
            cue = cue.coasted(now, self.get_input("cue_accel_mps2")) if cue.age(now) <= self.get_input("cue_coast_s") else None
        vel = s.velocity_enu if np.all(np.isfinite(s.velocity_enu)) else np.zeros(3)
        pose = OwnshipPose(now, s.position_enu, vel, s.attitude)
        if threaded:  # hand the worker this tick's inputs, read its latest result: no waiting
            self.camera.submit(pose, known_range, cue)
            problem = self.camera.health(now)
            if problem is not None:
                self.feedback_message = problem
                return Status.FAILURE
            est = self.camera.latest().estimate
        else:
            est = self.camera.step(now, pose, known_range, cue)
        self._report_drops()
        if est is None:
            self.feedback_message = "no target in view"
            return Status.FAILURE
        self._set_output("estimate", est)
        self.feedback_message = f"target at {est.range_m:.1f} m, confidence {est.confidence:.2f}"
        return Status.SUCCESS


    def _report_drops(self) -> None:
        """Put the source's dropped-frame counts on the blackboard when they change."""
        sensor = self.camera.sensor if isinstance(self.camera, PerceptionWorker) else self.camera
        dropped = getattr(sensor.source, "dropped", None)
        if dropped and dict(dropped) != self._dropped_seen:
            self._dropped_seen = dict(dropped)
            self._set_output("frames_dropped", dict(dropped))


@register_behaviour
class TargetInView(VehicleBehaviour):
    """SUCCESS while the camera's estimate is younger than ``max_age_s`` and at least ``min_confidence``."""

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS = {
        "estimate": input_port(TargetEstimate, "The camera's target estimate", required=False, default_key=ESTIMATE_KEY),
        "max_age_s": input_port(float, "An estimate older than this is out of view (s)", default=0.5, minimum=0),
        "min_confidence": input_port(float, "Least confidence that counts (0..1)", default=0.3, minimum=0, maximum=1),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def update(self) -> Status:
        est = optional_input(self, "estimate")
        if est is None:
            self.feedback_message = "no estimate"
            return Status.FAILURE
        age = est.age(self._now())
        if age > self.get_input("max_age_s") or est.confidence < self.get_input("min_confidence"):
            self.feedback_message = f"estimate age {age:.2f} s, confidence {est.confidence:.2f}"
            return Status.FAILURE
        self.feedback_message = f"in view, {est.range_m:.1f} m"
        return Status.SUCCESS
