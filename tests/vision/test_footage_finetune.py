"""The own-footage workflow end to end on tiny data: a CVAT COCO export of rendered frames ->
``import-footage`` -> ``train-detector --init <shipped weights>`` (a few steps) -> weights and their
ONNX copy -> ``eval-detector`` -> a tree whose VisionPipeline loads the result by path and runs."""

from __future__ import annotations

import json

import numpy as np
import py_trees
import pytest
import torch
from footage_exports import H, W, rendered_frames, write_coco10
from scipy.spatial.transform import Rotation

from chaser_bt.cli import main
from chaser_bt.clock import ManualClock
from chaser_bt.tree import load_tree_text
from chaser_bt.vehicle.state import VehicleState
from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detector.inference import DEFAULT_WEIGHTS, Detector, load_model
from chaser_bt.vision.frame_source import Frame
from chaser_bt.vision.pipeline import CameraSensor, PipelineConfig, VisionPipeline


class _Frames:
    def __init__(self, image):
        self.image = image

    def read(self, t):
        return Frame(t, self.image, 0)

    def close(self):
        pass


@pytest.fixture(scope="module")
def fine_tuned(tmp_path_factory):
    torch.set_num_threads(1)
    tmp = tmp_path_factory.mktemp("footage")
    images, boxes = rendered_frames(8, seed=5)
    export = write_coco10(tmp / "task_1_dataset.zip", ("s1000", "phantom"), boxes, images)
    assert main(["import-footage", str(export), "--out", str(tmp / "data"), "--chunk", "4", "--val-frac", "0.5"]) == 0
    weights = tmp / "ours.pt"
    assert main(["train-detector", "--data", str(tmp / "data" / "train"), "--out", str(weights), "--init", str(DEFAULT_WEIGHTS),
                 "--steps", "2", "--batch", "2", "--lr", "1e-4", "--threads", "1"]) == 0
    return tmp, weights, images


def test_fine_tune_from_the_shipped_weights_writes_loadable_weights_and_onnx(fine_tuned):
    _, weights, images = fine_tuned
    model = load_model(weights)
    assert model.config.class_names == ("s1000", "phantom")
    shipped = load_model(DEFAULT_WEIGHTS).state_dict()
    moved = [k for k, v in model.state_dict().items() if v.is_floating_point() and not torch.equal(v, shipped[k])]
    assert moved  # it trained (from the shipped weights: same shapes, new values)
    onnx = weights.with_suffix(".onnx")
    assert onnx.exists()
    a = Detector(weights, image_size=160, backend="torch", conf_threshold=0.05, refiner=None)(images[0])
    b = Detector(weights, image_size=160, backend="onnx", conf_threshold=0.05, refiner=None)(images[0])
    assert len(a) == len(b)
    for da, db in zip(a, b):
        assert da.class_id == db.class_id and np.allclose(da.box, db.box, atol=1e-2) and da.score == pytest.approx(db.score, abs=1e-4)


def test_eval_detector_scores_the_held_out_chunks(fine_tuned, capsys):
    tmp, weights, _ = fine_tuned
    capsys.readouterr()
    assert main(["eval-detector", "--data", str(tmp / "data" / "val"), "--weights", str(weights), "--sizes", "160", "--backend", "torch"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["images"] == 4 and result["image_size"] == 160 and 0.0 <= result["ap50"] <= 1.0


def test_a_tree_runs_the_fine_tuned_detector_by_path(fine_tuned):
    _, weights, images = fine_tuned
    tree = load_tree_text(f"version: 1\ntrees:\n  Test:\n    VisionPipeline: {{weights: '{weights}', classes: [s1000, phantom]}}\n",
                          source="<test>")
    pipeline = VisionPipeline(CameraModel(width_px=W, height_px=H), lambda image: [], PipelineConfig(detect_every=1, focus=False))
    bt = py_trees.trees.BehaviourTree(tree.root)
    bt.setup(link=object(), clock=ManualClock(1.0), camera=CameraSensor(_Frames(images[0]), pipeline))
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
    bb.set("/vehicle/state", VehicleState(position_enu=np.array([0.0, 0.0, 20.0]), velocity_enu=np.zeros(3), attitude=Rotation.identity()))
    bt.tick()
    assert bt.root.status in (py_trees.common.Status.SUCCESS, py_trees.common.Status.FAILURE)
    assert pipeline.detector_name == str(weights) and isinstance(pipeline.detector, Detector)
    assert pipeline.detector_frames == 1  # the fine-tuned detector ran on the frame
    assert pipeline.detector.class_names == ("s1000", "phantom")


def test_a_tree_with_missing_weights_fails_at_setup(tmp_path):
    tree = load_tree_text(f"version: 1\ntrees:\n  Test:\n    VisionPipeline: {{weights: '{tmp_path / 'nope.pt'}'}}\n", source="<test>")
    pipeline = VisionPipeline(CameraModel(width_px=W, height_px=H), lambda image: [], PipelineConfig(detect_every=1, focus=False))
    bt = py_trees.trees.BehaviourTree(tree.root)
    with pytest.raises(FileNotFoundError, match="nope.pt"):
        bt.setup(link=object(), clock=ManualClock(1.0), camera=CameraSensor(_Frames(np.zeros((H, W, 3), np.uint8)), pipeline))


def test_a_tree_with_an_empty_weights_file_fails_at_setup_naming_it(tmp_path):
    """Not torch's "EOFError: Ran out of input": the file, and that it is empty."""
    empty = tmp_path / "empty.pt"
    empty.write_bytes(b"")
    tree = load_tree_text(f"version: 1\ntrees:\n  Test:\n    VisionPipeline: {{weights: '{empty}'}}\n", source="<test>")
    pipeline = VisionPipeline(CameraModel(width_px=W, height_px=H), lambda image: [], PipelineConfig(detect_every=1, focus=False))
    bt = py_trees.trees.BehaviourTree(tree.root)
    with pytest.raises(ValueError, match=f"^{empty}: empty file, not detector weights$"):
        bt.setup(link=object(), clock=ManualClock(1.0), camera=CameraSensor(_Frames(np.zeros((H, W, 3), np.uint8)), pipeline))
