"""VisionPipeline and TargetInView behaviours in a one-node tree, with a scripted camera."""

from __future__ import annotations

import argparse
import json

import cv2
import numpy as np
import py_trees
import pytest
from scipy.spatial.transform import Rotation

from chaser_bt.clock import ManualClock
from chaser_bt.cue import TargetCue
from chaser_bt.tree import load_tree_text
from chaser_bt.vehicle.state import VehicleState
from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detector.inference import Detection
from chaser_bt.vision.frame_source import Frame
from chaser_bt.vision.pipeline import CameraSensor, PipelineConfig, VisionPipeline

Status = py_trees.common.Status
CAM = CameraModel(width_px=320, height_px=240, tilt_rad=0.0)


class _Source:
    def read(self, t):
        return Frame(t, np.zeros((240, 320, 3), np.uint8), 0)

    def close(self):
        pass


class _Detector:
    def __init__(self):
        self.box = (150.0, 110.0, 170.0, 130.0)

    def __call__(self, image):
        return [Detection(self.box, 0.9, 0, "s1000")] if self.box else []


def _tree(body: str, detector, clock):
    tree = load_tree_text("version: 1\ntrees:\n  Test:\n    " + body + "\n", source="<test>")
    sensor = CameraSensor(_Source(), VisionPipeline(CAM, detector, PipelineConfig(detect_every=1, tracker_kinds=(), confirm_hits=1, focus=False)))
    bt = py_trees.trees.BehaviourTree(tree.root)
    bt.setup(link=object(), clock=clock, camera=sensor)
    return bt


def _state():
    return VehicleState(position_enu=np.array([0.0, 0.0, 20.0]), velocity_enu=np.zeros(3), attitude=Rotation.identity())


def test_vision_pipeline_writes_the_estimate_and_target_in_view_follows_its_age():
    clock = ManualClock(10.0)
    det = _Detector()
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
    bb.register_key("/target/estimate", access=py_trees.common.Access.READ)
    bb.set("/vehicle/state", _state())
    vision = _tree("VisionPipeline: {}", det, clock)
    in_view = _tree("TargetInView: {max_age_s: 0.5}", det, clock)
    vision.tick()
    assert vision.root.status == Status.SUCCESS
    est = bb.get("/target/estimate")
    assert est.t == 10.0 and est.source == "vision" and est.bearing_enu == pytest.approx([1.0, 0.0, 0.0], abs=1e-9)
    in_view.tick()
    assert in_view.root.status == Status.SUCCESS
    clock.advance(1.0)
    in_view.tick()
    assert in_view.root.status == Status.FAILURE  # estimate 1 s old
    det.box = None
    vision.tick()
    assert vision.root.status == Status.FAILURE


def _with_telemetry_25_m_out() -> py_trees.blackboard.Client:
    """A blackboard with the vehicle's state and the target's telemetry 25 m east of the camera."""
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
    bb.register_key("/target/telemetry", access=py_trees.common.Access.WRITE)
    bb.register_key("/target/estimate", access=py_trees.common.Access.READ)
    bb.set("/vehicle/state", _state())
    bb.set("/target/telemetry", TargetCue(t=5.0, position_enu=np.array([25.0, 0.0, 20.0]), source="telemetry"))
    return bb


def test_range_from_telemetry_when_remapped():
    clock, bb = ManualClock(5.0), _with_telemetry_25_m_out()
    vision = _tree('VisionPipeline: {range_cue: "{@target/telemetry}"}', _Detector(), clock)
    vision.tick()
    assert bb.get("/target/estimate").range_m == pytest.approx(25.0, abs=0.01)


def test_range_from_the_box_unless_a_range_cue_is_remapped():
    """Nothing reads the target's own telemetry by default: written but not remapped, it changes nothing."""
    clock, bb = ManualClock(5.0), _with_telemetry_25_m_out()
    vision = _tree("VisionPipeline: {}", _Detector(), clock)
    vision.tick()
    assert bb.get("/target/estimate").range_m != pytest.approx(25.0, abs=0.5)


def test_setup_without_a_camera_names_what_is_missing():
    tree = load_tree_text("version: 1\ntrees:\n  Test:\n    VisionPipeline: {}\n", source="<test>")
    with pytest.raises(KeyError, match="camera=CameraSensor"):
        py_trees.trees.BehaviourTree(tree.root).setup(link=object(), clock=ManualClock(0.0))


def test_cli_commands_parse_and_refuse_a_missing_folder(tmp_path, capsys):
    from chaser_bt.vision.commands import add_command

    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    args = parser.parse_args(["eval-detector", "--data", str(tmp_path / "nope")])
    assert args.handler(args) == 2 and "no images/ folder" in capsys.readouterr().err
    args = parser.parse_args(["train-detector", "--data", str(tmp_path / "nope")])
    assert args.handler(args) == 2
    args = parser.parse_args(["train-refiner", "--data", str(tmp_path / "nope"), "--out", str(tmp_path / "r.pt")])
    assert args.handler(args) == 2 and "no images/ folder" in capsys.readouterr().err


def test_train_refiner_writes_a_refiner_the_detector_can_load(tmp_path, capsys):
    from chaser_bt.vision.commands import add_command
    from chaser_bt.vision.detector.inference import Detector
    from sitl.bench.camera_dataset import write_dataset

    write_dataset(tmp_path / "d", 4, seed=4, split="train", ground_size_px=256)
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    out = tmp_path / "r.pt"
    args = parser.parse_args(["train-refiner", "--data", str(tmp_path / "d"), "--out", str(out), "--steps", "3", "--threads", "1"])
    assert args.handler(args) == 0
    printed = capsys.readouterr().out
    assert str(out) in printed and str(out.with_suffix(".onnx")) in printed
    det = Detector(refiner=out)
    img = np.full((480, 640, 3), 120, np.uint8)
    assert det.refiner is not None and det.refiner.backend == "onnx"  # the copy written beside it runs
    assert det.refiner.boxes(img, [(100.0, 100.0, 140.0, 120.0)]).shape == (1, 4)


def test_a_folder_read_in_chunks_is_the_folder_read_whole_and_the_refiner_set_the_same(tmp_path):
    from chaser_bt.vision.detector.refine import RefinerConfig, make_refiner_set
    from chaser_bt.vision.detector.train import iter_yolo_folder, load_yolo_folder
    from sitl.bench.camera_dataset import write_dataset

    write_dataset(tmp_path / "d", 5, seed=4, split="train", ground_size_px=256)
    images, boxes, _ = load_yolo_folder(tmp_path / "d", 640)
    chunks = list(iter_yolo_folder(tmp_path / "d", 640, chunk=2))
    assert [len(c[0]) for c in chunks] == [2, 2, 1]
    assert all(np.array_equal(a, b) for a, b in zip(images, [im for c in chunks for im in c[0]]))
    assert all(np.array_equal(a, b) for a, b in zip(boxes, [bx for c in chunks for bx in c[1]]))
    # The refiner's crops, drawn chunk by chunk from one generator, are the whole folder's.
    cfg = RefinerConfig()
    whole = make_refiner_set(images, boxes, cfg, 3, np.random.default_rng(1))
    rng = np.random.default_rng(1)
    parts = [make_refiner_set(ims, bxs, cfg, 3, rng) for ims, bxs in chunks]
    assert all(np.array_equal(w, np.concatenate(ps)) for w, ps in zip(whole, zip(*parts)))


def test_train_refiner_on_a_folder_without_labels_says_so(tmp_path, capsys):
    from chaser_bt.vision.commands import add_command

    (tmp_path / "d" / "images").mkdir(parents=True)
    (tmp_path / "d" / "classes.txt").write_text("drone\n")
    cv2.imwrite(str(tmp_path / "d" / "images" / "a.jpg"), np.full((48, 64, 3), 90, np.uint8))
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    args = parser.parse_args(["train-refiner", "--data", str(tmp_path / "d"), "--out", str(tmp_path / "r.pt")])
    assert args.handler(args) == 2 and "no labelled targets" in capsys.readouterr().err


def test_train_refiner_with_negatives_from_a_detector_writes_a_scoring_refiner(tmp_path, capsys):
    from chaser_bt.vision.commands import add_command
    from chaser_bt.vision.detector.inference import DEFAULT_WEIGHTS, Detector
    from sitl.bench.camera_dataset import write_dataset

    write_dataset(tmp_path / "d", 3, seed=4, split="train", ground_size_px=256)
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    out = tmp_path / "r.pt"
    args = parser.parse_args(["train-refiner", "--data", str(tmp_path / "d"), "--out", str(out), "--steps", "3", "--threads", "1",
                              "--negatives-from", str(DEFAULT_WEIGHTS), "--negative-conf", "0.001"])
    assert args.handler(args) == 0
    assert "of false boxes" in capsys.readouterr().err
    det = Detector(refiner=out)
    assert det.refiner.config.scores and det.refiner.backend == "onnx"
    box, prob = det.refiner.refine(np.full((480, 640, 3), 120, np.uint8), [(100.0, 100.0, 140.0, 120.0)])
    assert box.shape == (1, 4) and 0.0 < prob[0] < 1.0
    args = parser.parse_args(["train-refiner", "--data", str(tmp_path / "d"), "--out", str(out),
                              "--negatives-from", str(tmp_path / "none.pt")])
    assert args.handler(args) == 2 and "--negatives-from" in capsys.readouterr().err


def test_eval_detector_prints_model_card_metrics_on_a_rendered_folder(tmp_path, capsys):
    from chaser_bt.vision.commands import add_command
    from sitl.bench.camera_dataset import write_dataset

    write_dataset(tmp_path / "d", 5, seed=4, split="heldout")
    parser = argparse.ArgumentParser()
    add_command(parser.add_subparsers())
    args = parser.parse_args(["eval-detector", "--data", str(tmp_path / "d"), "--sizes", "416"])
    assert args.handler(args) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert row["images"] == 5 and set(row) >= {"ap50", "iou", "precision", "recall", "f1", "fps"}


def _ground_state():
    # 20 m up, pitched 30 deg nose-down: the camera (tilt 0) looks at the ground 20 / tan(30 deg) ahead.
    att = Rotation.from_euler("ZY", [0.0, np.radians(30.0)])
    return VehicleState(position_enu=np.array([0.0, 0.0, 20.0]), velocity_enu=np.zeros(3), attitude=att)


def test_classes_port_filters_detections_and_ground_ranging_meets_the_ground():
    clock = ManualClock(3.0)
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
    bb.register_key("/target/estimate", access=py_trees.common.Access.READ)
    bb.set("/vehicle/state", _ground_state())
    det = _Detector()  # class "s1000" at the image centre
    wrong = _tree("VisionPipeline: {classes: [person]}", det, clock)
    wrong.tick()
    assert wrong.root.status == Status.FAILURE and wrong.root.camera.pipeline.config.classes == ("person",)
    ground = _tree("VisionPipeline: {classes: [s1000, person], target_on_ground: true}", det, clock)
    ground.tick()
    assert ground.root.status == Status.SUCCESS
    est = bb.get("/target/estimate")
    # The optical axis meets z = 0 at 20 / sin(30 deg) = 40 m, at (34.64, 0, 0).
    assert est.range_m == pytest.approx(40.0, rel=1e-3)
    assert est.position_enu == pytest.approx([20.0 / np.tan(np.radians(30.0)), 0.0, 0.0], abs=0.05)


def test_detector_port_swaps_in_a_shipped_detector_and_rejects_unknown_names():
    from chaser_bt.vision.detector.inference import Detector

    clock = ManualClock(1.0)
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
    bb.set("/vehicle/state", _state())
    vision = _tree("VisionPipeline: {detector: tiny_yolo}", _Detector(), clock)
    vision.tick()  # a blank frame: no target, but the shipped detector now runs
    pipeline = vision.root.camera.pipeline
    assert isinstance(pipeline.detector, Detector) and pipeline.detector_name == "tiny_yolo"
    assert pipeline.detector.class_names == ("s1000", "phantom")
    with pytest.raises(Exception, match="detector"):
        load_tree_text("version: 1\ntrees:\n  Test:\n    VisionPipeline: {detector: yolo9000}\n", source="<test>")


def test_ground_range_is_height_over_the_downward_component():
    from chaser_bt.vision.pipeline import ground_range

    b = np.array([3.0, 4.0, -5.0]) / np.sqrt(50.0)
    assert ground_range(np.array([1.0, 2.0, 10.0]), b) == pytest.approx(10.0 * np.sqrt(50.0) / 5.0)
    assert ground_range(np.array([0.0, 0.0, 10.0]), np.array([1.0, 0.0, 0.0])) is None
    assert ground_range(np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, -1.0])) is None


def test_setup_refuses_a_shipped_detector_whose_weights_are_missing(monkeypatch, tmp_path):
    from behaviours import vision as vision_behaviours
    from chaser_bt.vision.detector import inference

    monkeypatch.setitem(inference.SHIPPED_WEIGHTS, "person_yolo", tmp_path / "absent.pt")
    vision_behaviours._shipped.cache_clear()
    try:
        with pytest.raises(FileNotFoundError, match="absent.pt"):
            _tree("VisionPipeline: {detector: person_yolo}", _Detector(), ManualClock(0.0))
    finally:
        vision_behaviours._shipped.cache_clear()


def test_detector_port_person_yolo_runs_the_person_model():
    clock = ManualClock(1.0)
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
    bb.set("/vehicle/state", _state())
    vision = _tree("VisionPipeline: {detector: person_yolo, classes: [person], target_on_ground: true}", _Detector(), clock)
    vision.tick()
    pipeline = vision.root.camera.pipeline
    assert pipeline.detector_name == "person_yolo" and pipeline.detector.class_names == ("person",)
    assert pipeline.config.classes == ("person",) and pipeline.config.target_on_ground


def test_frames_the_camera_dropped_are_counted_on_the_blackboard():
    class _Glitchy(_Source):
        def __init__(self):
            self.dropped: dict[str, int] = {}

        def read(self, t):  # every other frame is not 8-bit BGR, as VideoCaptureSource counts it
            if int(round(t * 10)) % 2:
                self.dropped["not_bgr8"] = self.dropped.get("not_bgr8", 0) + 1
                return None
            return super().read(t)

    clock = ManualClock(0.0)
    tree = load_tree_text("version: 1\ntrees:\n  Test:\n    VisionPipeline: {}\n", source="<test>")
    sensor = CameraSensor(_Glitchy(), VisionPipeline(CAM, _Detector(), PipelineConfig(detect_every=1, tracker_kinds=(), focus=False)))
    bt = py_trees.trees.BehaviourTree(tree.root)
    bt.setup(link=object(), clock=clock, camera=sensor)
    py_trees.blackboard.Blackboard.set("/vehicle/state", _state())
    for k in range(6):
        clock.set(0.1 * k)
        bt.tick()
    assert py_trees.blackboard.Blackboard.storage.get("/camera/frames_dropped") == {"not_bgr8": 3}
