"""The detector: metric definitions checked by hand, and the shipped weights on a freshly rendered set."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from chaser_bt.vision.detector.evaluate import ap11, evaluate_detections, iou_matrix
from chaser_bt.vision.detector.inference import DEFAULT_WEIGHTS, Detector, nms
from chaser_bt.vision.detector.loss import _assign, detection_loss, giou
from chaser_bt.vision.detector.model import DetectorConfig, TinyYolo, decode


def test_iou_and_giou_by_hand():
    a, b = np.array([[0, 0, 2, 2]]), np.array([[1, 1, 3, 3]])
    assert iou_matrix(a, b)[0, 0] == pytest.approx(1 / 7)
    # Hull 3x3 = 9, union 7: GIoU = 1/7 - 2/9.
    assert float(giou(torch.tensor(a, dtype=torch.float), torch.tensor(b, dtype=torch.float))[0]) == pytest.approx(1 / 7 - 2 / 9)


def test_eleven_point_ap_by_hand():
    # Two ground truths; ranked predictions TP, FP, TP: recall 0.5, 0.5, 1; precision 1, 0.5, 2/3.
    rec, prec = np.array([0.5, 0.5, 1.0]), np.array([1.0, 0.5, 2 / 3])
    assert ap11(rec, prec) == pytest.approx((6 * 1.0 + 5 * 2 / 3) / 11)


def test_evaluate_detections_counts_matches_once_and_by_class():
    gt = [np.array([[0, 0, 0, 10, 10], [1, 20, 20, 30, 30]])]
    preds = [[((0, 0, 10, 10), 0.9, 0), ((1, 1, 10, 10), 0.8, 0), ((20, 20, 30, 30), 0.7, 0)]]
    m = evaluate_detections(preds, gt, 2)
    # Class 0: TP then two FPs (duplicate, wrong class) -> AP 1; class 1: never found -> AP 0.
    assert m.ap50_per_class == {0: pytest.approx(1.0), 1: 0.0}
    assert m.precision == pytest.approx(1 / 3) and m.recall == pytest.approx(1 / 2)


def test_nms_keeps_the_best_of_overlapping_boxes():
    boxes = np.array([[0, 0, 10, 10], [1, 1, 10, 10], [50, 50, 60, 60]], float)
    assert nms(boxes, np.array([0.5, 0.9, 0.3]), 0.45) == [1, 2]


def test_assignment_puts_a_box_in_its_centre_cell_and_the_two_nearest_neighbours():
    bi, ci, rows = _assign([torch.tensor([[0, 18.0, 18.0, 22.0, 22.0]])], 8, 8, 8)  # centre (20, 20): cell (2, 2), fraction 0.5
    assert sorted(ci.tolist()) == sorted([2 * 8 + 2, 2 * 8 + 3, 3 * 8 + 2])


def test_network_shapes_and_a_finite_loss_with_and_without_targets():
    model = TinyYolo(DetectorConfig())
    raw = model(torch.rand(2, 3, 64, 96))
    assert raw.shape == (2, 7, 8, 12)
    assert decode(raw, 8).shape == (2, 96, 4 + 1 + 2)
    loss, parts = detection_loss(raw, [torch.tensor([[1, 10.0, 10.0, 30.0, 40.0]]), torch.zeros(0, 5)], 8)
    loss.backward()
    assert torch.isfinite(loss) and set(parts) == {"obj", "box", "cls"}


def test_iou_aware_objectness_scores_a_cell_on_the_iou_of_its_box():
    """A 4 x 4 grid of 8 px cells, every logit 0 except the width's (log 2): each cell predicts a
    16 x 8 px box at its centre ((cell + 0.5) * 8), objectness p = 0.5. The assigned cells'
    objectness target is 1 - g + g * IoU; the focal term 0.25 |y - p|^2 BCE(p, y) is summed by hand.
    """
    raw = torch.zeros(1, 7, 4, 4)
    raw[0, 3] = math.log(2.0)  # width 16 px everywhere
    target = torch.tensor([[0, 4.0, 8.0, 20.0, 16.0]])  # 16 x 8 centred (12, 12): cell (1, 1) plus neighbours
    _, parts_1 = detection_loss(raw, [target], 8, obj_iou=1.0)
    _, parts_0 = detection_loss(raw, [target], 8, obj_iou=0.0)
    bce = lambda y: -(y * math.log(0.5) + (1 - y) * math.log(0.5))  # noqa: E731 (p = 0.5)
    neg = 0.75 * 0.25 * bce(0.0) * (16 - 3)  # 13 unassigned cells, target 0
    # Cell (1, 1) predicts 16 x 8 at the target's centre: IoU 1. Its neighbours (2, 1) and (1, 2)
    # predict 16 x 8 boxes 8 px off: IoU 8*8 / (2*128 - 64) = 1/3 and 0 (the y-neighbour: 8 px down, no overlap).
    ious = sorted([1.0, (16 - 8) * 8 / (2 * 128 - (16 - 8) * 8), 0.0])
    assert parts_0["obj"] == pytest.approx((neg + 3 * 0.25 * 0.25 * bce(1.0)) / 3, rel=1e-5)
    expect = (neg + sum(0.25 * (y - 0.5) ** 2 * bce(y) for y in ious)) / 3
    assert parts_1["obj"] == pytest.approx(expect, rel=1e-5)


def test_shipped_weights_load_by_default_and_detect_targets_on_a_fresh_heldout_set():
    from sitl.bench.camera_dataset import DatasetRenderer, frame_boxes

    assert DEFAULT_WEIGHTS.exists() and DEFAULT_WEIGHTS.stat().st_size < 4_000_000
    det = Detector(conf_threshold=0.005)
    data = DatasetRenderer("heldout", ground_size_px=1024)
    rng = np.random.default_rng(20240601)
    frames = [data.sample(rng) for _ in range(40)]
    preds = [[(d.box, d.score, d.class_id) for d in det(f.image)] for f in frames]
    m = evaluate_detections(preds, [frame_boxes(f) for f in frames], 2)
    assert m.ap50 >= 0.8, m


def test_onnx_backend_gives_the_torch_detections():
    pytest.importorskip("onnxruntime")
    from chaser_bt.vision.detector.inference import DEFAULT_ONNX

    assert DEFAULT_ONNX.exists()
    img = (np.random.default_rng(0).random((480, 640, 3)) * 255).astype(np.uint8)
    a = Detector(conf_threshold=0.001, backend="torch", refiner=None)(img)  # the network alone
    b = Detector(conf_threshold=0.001, backend="onnx", refiner=None)(img)
    assert len(a) == len(b) > 0
    for x, y in zip(a, b):
        assert x.class_id == y.class_id and x.score == pytest.approx(y.score, abs=1e-4)
        assert np.allclose(x.box, y.box, atol=1e-2)


def test_shipped_person_detector_finds_people_on_a_fresh_heldout_set():
    from chaser_bt.vision.detector.inference import SHIPPED_WEIGHTS, shipped_detector
    from sitl.bench.camera_dataset import PERSON_CLASSES, DatasetRenderer, frame_boxes

    path = SHIPPED_WEIGHTS["person_yolo"]
    assert path.exists() and path.stat().st_size < 4_000_000
    det = shipped_detector("person_yolo", conf_threshold=0.005)
    assert det.class_names == PERSON_CLASSES and det.backend in ("torch", "onnx", "onnx-int8")
    data = DatasetRenderer("heldout", ground_size_px=1024, kinds=PERSON_CLASSES)
    rng = np.random.default_rng(20251122)
    frames = [data.sample(rng) for _ in range(40)]
    preds = [[(d.box, d.score, d.class_id) for d in det(f.image)] for f in frames]
    m = evaluate_detections(preds, [frame_boxes(f, PERSON_CLASSES) for f in frames], 1)
    assert m.ap50 >= 0.6, m
    with pytest.raises(ValueError, match="shipped"):
        shipped_detector("yolo9000")


def test_small_box_oversampling_weights_by_hand():
    from chaser_bt.vision.detector.train import sampling_weights

    boxes = [np.array([[0, 0.0, 0.0, 8.0, 8.0]]), np.array([[0, 0.0, 0.0, 30.0, 30.0], [1, 5.0, 5.0, 11.0, 40.0]]),
             np.zeros((0, 5)), np.array([[0, 0.0, 0.0, 20.0, 5.0]])]
    p = sampling_weights(boxes, small_box_px=10.0, small_weight=3.0)
    assert p == pytest.approx(np.array([3.0, 3.0, 1.0, 1.0]) / 8.0)  # 8 px and 6 px wide boxes are small; 20 px is not
    assert sampling_weights(boxes, 0.0, 3.0) is None


def test_fine_tuning_refuses_weights_for_other_classes(tmp_path):
    import cv2

    from chaser_bt.vision.detector.train import TrainConfig, train_detector

    data = tmp_path / "p"
    (data / "images").mkdir(parents=True)
    (data / "labels").mkdir()
    (data / "classes.txt").write_text("person\n")
    cv2.imwrite(str(data / "images" / "0.jpg"), np.zeros((48, 64, 3), np.uint8))
    (data / "labels" / "0.txt").write_text("0 0.5 0.5 0.2 0.4\n")
    with pytest.raises(ValueError, match="classes"):
        train_detector(TrainConfig(str(data), str(tmp_path / "w.pt"), steps=1, init_weights=str(DEFAULT_WEIGHTS)), progress=None)
    assert not (tmp_path / "w.pt").exists()


class _CtrlCAtStep:
    """A progress stream that raises KeyboardInterrupt (as Ctrl-C would) when training reports step ``n``."""

    def __init__(self, n: int) -> None:
        self.n, self.text = n, ""

    def write(self, text: str) -> None:
        self.text += text
        if f"] {self.n}/" in text:
            raise KeyboardInterrupt

    def flush(self) -> None:
        pass


def test_ctrl_c_during_training_writes_a_checkpoint_that_resumes(tmp_path):
    import cv2
    import torch

    from chaser_bt.vision.detector.train import TrainConfig, TrainingInterrupted, train_detector

    data = tmp_path / "p"
    (data / "images").mkdir(parents=True)
    (data / "labels").mkdir()
    (data / "classes.txt").write_text("person\n")
    cv2.imwrite(str(data / "images" / "0.jpg"), np.zeros((48, 64, 3), np.uint8))
    (data / "labels" / "0.txt").write_text("0 0.5 0.5 0.2 0.4\n")
    cfg = TrainConfig(str(data), str(tmp_path / "w.pt"), steps=30, batch=1, image_size=64)
    with pytest.raises(TrainingInterrupted) as stop:
        train_detector(cfg, progress=_CtrlCAtStep(10))
    assert stop.value.step == 10
    assert torch.load(tmp_path / "w.ckpt", weights_only=False)["step"] == 10  # before the first regular checkpoint (50)
    progress = _CtrlCAtStep(-1)
    train_detector(cfg, progress=progress)
    assert "resuming from" in progress.text and "at step 10 of 30" in progress.text
    short = _CtrlCAtStep(-1)
    train_detector(TrainConfig(str(data), str(tmp_path / "w.pt"), steps=20, batch=1, image_size=64), progress=short)
    assert "nothing to train" in short.text


def _matched_ious(a, b):
    """IoU of each detection of ``a`` with its best overlapping same-class match in ``b`` (greedy, best
    score first); a box nothing overlaps is unmatched (two near-threshold false boxes in different
    places are two misses, not a match of IoU 0)."""
    used, ious = set(), []
    for x in a:
        cand = [(iou, j) for j, y in enumerate(b) if j not in used and y.class_id == x.class_id
                and (iou := float(iou_matrix(np.array([x.box]), np.array([y.box]))[0, 0])) > 0.0]
        if cand:
            iou, j = max(cand)
            used.add(j)
            ious.append(iou)
    return ious


def _agree(frames, fp32: Detector, int8: Detector) -> list:
    """Per frame, the int8 detections against the float ones: counts within 1, every matched box IoU > 0.8."""
    worst = []
    for f in frames:
        a, b = fp32(f), int8(f)
        assert abs(len(a) - len(b)) <= 1, (a, b)
        ious = _matched_ious(a, b)
        assert len(ious) >= min(len(a), len(b)) - 1 and all(v > 0.8 for v in ious), (a, b, ious)
        worst.extend(ious)
    return worst


def test_int8_copy_quantized_on_rendered_frames_gives_the_float_detections(tmp_path):
    """Quantize the shipped float ONNX network on a few rendered training frames; on fresh held-out frames
    the int8 network's detections match the float one's (count within 1, matched boxes IoU > 0.8); the
    shipped int8 copy does too."""
    pytest.importorskip("onnxruntime")
    from chaser_bt.vision.detector.inference import DEFAULT_ONNX, int8_path
    from chaser_bt.vision.detector.quantize import quantize_detector
    from sitl.bench.camera_dataset import DatasetRenderer

    calib_rng, test_rng = np.random.default_rng(7), np.random.default_rng(20260101)
    train = DatasetRenderer("train", ground_size_px=1024, follow_share=0.5)  # the plain field: a family world takes ~30 s to build
    calib = [train.sample(calib_rng).image for _ in range(10)]
    heldout = DatasetRenderer("heldout", ground_size_px=1024, follow_share=0.5)
    frames = [heldout.sample(test_rng).image for _ in range(12)]
    out = quantize_detector(DEFAULT_ONNX, tmp_path / "q.int8.onnx", calib)
    fp32 = Detector(backend="onnx", refiner=None)
    fresh = Detector(backend="onnx-int8", onnx_path=out, refiner=None)
    assert fresh.backend == "onnx-int8" and fresh.onnx_path == out
    ious = _agree(frames, fp32, fresh)
    assert len(ious) >= 8  # the frames have targets and both find them
    shipped = Detector(backend="onnx-int8", refiner=None)
    assert shipped.onnx_path == int8_path(DEFAULT_WEIGHTS) and int8_path(DEFAULT_WEIGHTS).stat().st_size < 1_000_000
    _agree(frames, fp32, shipped)


def _copy_weights(tmp_path):
    """The shipped weights and float ONNX copy in a scratch folder (no refiner): (weights, onnx, int8 path)."""
    import os
    import shutil

    from chaser_bt.vision.detector.inference import DEFAULT_ONNX, int8_path

    w = tmp_path / "w.pt"
    shutil.copy(DEFAULT_WEIGHTS, w)
    shutil.copy(DEFAULT_ONNX, tmp_path / "w.onnx")
    shutil.copy(int8_path(DEFAULT_WEIGHTS), int8_path(w))
    t = w.stat().st_mtime
    os.utime(tmp_path / "w.onnx", (t, t))
    os.utime(int8_path(w), (t, t))
    return w, tmp_path / "w.onnx", int8_path(w)


def test_auto_backend_runs_the_int8_copy_only_while_it_is_current(tmp_path):
    import os

    pytest.importorskip("onnxruntime")
    w, onnx, q = _copy_weights(tmp_path)
    assert q.name == "w.int8.onnx"
    det = Detector(w)
    assert det.backend == "onnx-int8" and det.onnx_path == q
    assert Detector(w, onnx_path=onnx).backend == "onnx"  # an explicit float file is what runs
    assert Detector(w, backend="onnx").onnx_path == onnx
    t = w.stat().st_mtime
    os.utime(q, (t - 60, t - 60))  # weights retrained after the int8 copy was made: stale
    assert Detector(w).backend == "onnx"
    assert Detector(w, backend="onnx-int8").backend == "onnx-int8"  # asked for by name, it runs anyway
    q.unlink()
    assert Detector(w).backend == "onnx"
    os.utime(onnx, (t - 60, t - 60))
    assert Detector(w).backend == "torch"


def test_a_missing_or_corrupt_int8_copy_falls_back_or_errors_naming_the_file(tmp_path):
    pytest.importorskip("onnxruntime")
    w, onnx, q = _copy_weights(tmp_path)
    q.write_bytes(b"not an onnx model")
    with pytest.warns(RuntimeWarning, match="w.int8.onnx"):
        det = Detector(w)
    assert det.backend == "onnx" and det.onnx_path == onnx
    with pytest.raises(ValueError, match="w.int8.onnx"):
        Detector(w, backend="onnx-int8")
    q.unlink()
    with pytest.raises(FileNotFoundError, match="w.int8.onnx"):
        Detector(w, backend="onnx-int8")
    with pytest.raises(ValueError, match="onnx-int8"):
        Detector(w, backend="int8")


def test_quantize_detector_command_writes_the_int8_copy_that_auto_then_runs(tmp_path, capsys):
    import cv2

    from chaser_bt.cli import main
    from sitl.bench.camera_dataset import DatasetRenderer

    pytest.importorskip("onnxruntime")
    w, onnx, q = _copy_weights(tmp_path)
    q.unlink()
    calib = tmp_path / "calib"
    calib.mkdir()
    rng, data = np.random.default_rng(3), DatasetRenderer("train", ground_size_px=1024)
    for k in range(6):
        cv2.imwrite(str(calib / f"{k}.jpg"), data.sample(rng).image)
    assert main(["quantize-detector", "--weights", str(w), "--calib", str(calib), "--frames", "4"]) == 0
    assert f"int8 copy written to {q} (calibrated on 4 frames)" in capsys.readouterr().out
    det = Detector(w)
    assert det.backend == "onnx-int8" and det.onnx_path == q
    assert _float_convs(q) == {"/stem/stem.0/stem.0.0/Conv", "/stem/stem.1/stem.1.0/Conv", "/head/Conv"}
    assert main(["quantize-detector", "--weights", str(w), "--calib", str(calib), "--frames", "4", "--keep-float", "/head/"]) == 0
    assert _float_convs(q) == {"/head/Conv"}
    assert main(["quantize-detector", "--weights", str(tmp_path / "none.pt"), "--calib", str(calib)]) == 2
    assert "--weights" in capsys.readouterr().err


def _float_convs(path) -> set[str]:
    """Names of the convolutions in an ONNX file whose weights are not an int8 tensor put through DequantizeLinear."""
    import onnx

    graph = onnx.load(str(path)).graph
    dequantized = {n.output[0] for n in graph.node if n.op_type == "DequantizeLinear"}
    return {n.name for n in graph.node if n.op_type == "Conv" and n.input[1] not in dequantized}


def test_the_head_decoded_in_numpy_is_the_torch_decode_of_the_cells_kept():
    from chaser_bt.vision.detector.inference import decode_head

    raw = torch.from_numpy(np.random.default_rng(3).normal(0.0, 2.5, (1, 7, 13, 17)).astype(np.float32))
    want = decode(raw, 8)[0].numpy()
    assert np.allclose(decode_head(raw.numpy(), 8), want, rtol=1e-5, atol=1e-4)
    kept = want[:, 4] >= 0.6
    assert 0 < kept.sum() < len(want)
    assert np.allclose(decode_head(raw.numpy(), 8, 0.6), want[kept], rtol=1e-5, atol=1e-4)


def test_shipped_onnx_copies_carry_the_weights_config_and_the_detector_runs_them_without_torch():
    """The metadata in each shipped ONNX copy is the .pt file's own config; a fresh interpreter runs the
    shipped detector (network, decode, refiner) without importing torch."""
    import subprocess
    import sys
    from pathlib import Path

    import onnxruntime

    from chaser_bt.vision.detector.inference import SHIPPED_WEIGHTS, int8_path
    from chaser_bt.vision.detector.onnx_copy import read_metadata

    for weights in SHIPPED_WEIGHTS.values():
        blob = torch.load(weights, map_location="cpu", weights_only=False)
        for copy in (weights.with_suffix(".onnx"), int8_path(weights)):
            meta = read_metadata(onnxruntime.InferenceSession(str(copy), providers=["CPUExecutionProvider"]))
            assert meta["config"]["class_names"] == list(blob["config"]["class_names"]), copy
            assert meta["config"]["stride"] == blob["config"]["stride"] and meta["obj_iou"] == float(blob.get("obj_iou", 0.0)), copy
    code = ("import sys, numpy as np; from chaser_bt.vision.detector.inference import Detector; d = Detector(); "
            "d(np.full((480, 640, 3), 100, np.uint8)); d.refiner.boxes(np.zeros((480, 640, 3), np.uint8), [(10, 10, 30, 30)]); "
            "print(d.backend, d.refiner.backend, 'torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=Path(__file__).parents[2])
    assert out.stdout.split() == ["onnx-int8", "onnx", "False"], out.stderr


def test_network_input_is_the_image_as_rgb_planes_in_zero_to_one():
    from chaser_bt.vision.detector.inference import network_input

    img = np.random.default_rng(5).integers(0, 256, (64, 96, 3), dtype=np.uint8)
    want = (img[..., ::-1].transpose(2, 0, 1).astype(np.float32) / np.float32(255.0))[None]
    got = network_input(img)
    assert got.dtype == np.float32 and got.shape == (1, 3, 64, 96) and got.flags.c_contiguous
    assert np.array_equal(got, want)
    assert got[0, 0, 3, 7] == np.float32(img[3, 7, 2]) / np.float32(255.0)  # plane 0 is red (BGR's last)


def test_a_square_window_the_network_can_take_runs_at_its_own_size_and_anything_else_is_letterboxed():
    """A focus window (square, a multiple of the stride, no larger than the input) goes to the network
    as it is, boxes in its own pixels; other images are letterboxed to the detector's size."""
    det = Detector(backend="onnx", refiner=None)
    seen = []
    session = det._session

    class Recording:
        def run(self, names, feeds):
            seen.append(feeds["images"].shape[2:])
            return session.run(names, feeds)

    det._session = Recording()
    rng = np.random.default_rng(0)
    for shape in ((320, 320, 3), (256, 256, 3), (416, 416, 3), (300, 300, 3), (480, 640, 3), (448, 448, 3)):
        det(rng.integers(0, 256, shape, dtype=np.uint8))
    assert seen == [(320, 320), (256, 256), (416, 416), (416, 416), (416, 416), (416, 416)]


def test_a_threshold_given_per_call_is_the_detectors_own_threshold_for_that_call():
    """Random noise makes hundreds of low-scoring boxes: asked for boxes down to 0.01, the detector
    built at 0.25 gives exactly what one built at 0.01 gives, and its own call still stops at 0.25."""
    img = (np.random.default_rng(0).random((480, 640, 3)) * 255).astype(np.uint8)
    at_025, at_001 = Detector(conf_threshold=0.25), Detector(conf_threshold=0.01)
    low = at_025.detect(img, conf_threshold=0.01)
    assert [(d.box, d.score) for d in low] == [(d.box, d.score) for d in at_001(img)] and len(low) > 0
    assert all(d.score >= 0.25 for d in at_025(img)) and at_025.conf_threshold == 0.25
    assert len(at_025(img)) < len(low)
