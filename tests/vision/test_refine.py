"""The box refiner: crop geometry by hand, the no-op and fallback cases, that it learns, and the shipped one."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from chaser_bt.vision.detection import Detection
from chaser_bt.vision.detector.refine import (
    BoxRefiner,
    BoxRefinerNet,
    RefinerConfig,
    _crops,
    crop_window,
    false_detections,
    jitter_boxes,
    make_negative_set,
    make_refiner_set,
    refiner_path,
    train_refiner,
)


def test_crop_window_is_context_times_the_larger_side_around_the_centre_and_never_under_the_minimum():
    cfg = RefinerConfig(context=1.6, min_side_px=24.0)
    assert crop_window((10, 20, 30, 30), cfg) == pytest.approx((4.0, 9.0, 32.0))  # centre (20, 25), side 1.6 * 20
    assert crop_window((0, 0, 5, 5), cfg) == pytest.approx((2.5 - 12, 2.5 - 12, 24.0))


def test_crops_map_the_window_onto_the_network_input():
    img = np.zeros((100, 100, 3), np.uint8)
    img[30:50, 40:60] = 255  # a white square x 40-60, y 30-50
    (crop,) = _crops(img, [(30.0, 20.0, 40.0)], 64)  # the square at fractions 0.25-0.75 of the window
    assert crop[32, 32].min() == 255 and crop[20, 20].min() == 255 and crop[43, 43].min() == 255
    assert crop[10, 32].max() == 0 and crop[32, 10].max() == 0 and crop[53, 53].max() == 0


def _save(net: BoxRefinerNet, path) -> None:
    torch.save({"config": net.config.to_dict(), "state_dict": net.state_dict()}, path)


def test_a_head_predicting_no_offset_returns_the_boxes_given_and_a_wild_one_is_not_trusted(tmp_path):
    net = BoxRefinerNet(RefinerConfig())
    torch.nn.init.zeros_(net.head[-1].weight)
    torch.nn.init.zeros_(net.head[-1].bias)
    _save(net, tmp_path / "r.pt")
    img = (np.random.default_rng(0).random((120, 160, 3)) * 255).astype(np.uint8)
    boxes = [(40.0, 30.0, 80.0, 50.0), (100.0, 60.0, 130.0, 100.0)]
    assert BoxRefiner(tmp_path / "r.pt").boxes(img, boxes) == pytest.approx(np.array(boxes))
    with torch.no_grad():
        net.head[-1].bias.copy_(torch.tensor([0.5, 0.0, 0.5, 0.0]))  # everything half a crop to the right
    _save(net, tmp_path / "r.pt")
    refiner = BoxRefiner(tmp_path / "r.pt", max_shift=0.5)
    assert refiner.boxes(img, boxes) == pytest.approx(np.array(boxes))  # moved 0.8 box sizes: kept as they were
    dets = refiner(img, [Detection(boxes[0], 0.7, 1, "phantom")])
    assert dets[0].box == pytest.approx(boxes[0]) and dets[0].score == 0.7 and dets[0].class_name == "phantom"


def test_jittered_boxes_scatter_around_the_label_as_asked():
    rng = np.random.default_rng(1)
    b = jitter_boxes(np.array([100.0, 100.0, 140.0, 120.0]), 20000, rng, shift_sigma=0.1, scale_sigma=0.2)
    centre = 0.5 * (b[:, :2] + b[:, 2:])
    # A mixture: 80 % at sigma 0.1 of the size, 20 % at 0.3 -> sd sqrt(0.8 * 0.01 + 0.2 * 0.09) = 0.161.
    assert np.std(centre[:, 0] - 120.0) / 40.0 == pytest.approx(0.161, rel=0.05)
    assert np.std(np.log((b[:, 3] - b[:, 1]) / 20.0)) == pytest.approx(0.2, rel=0.05)


def _squares(n: int, rng: np.random.Generator, centre: int = 230) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Dark squares (10-30 px) on noise, one a frame, with a centre of value ``centre`` (the bright-centred
    ones are the targets); labels (1, 5) class, x0, y0, x1, y1."""
    images, boxes = [], []
    for _ in range(n):
        img = (rng.random((96, 96, 3)) * 80 + 120).astype(np.uint8)
        s = int(rng.integers(10, 31))
        x, y = (int(v) for v in rng.integers(15, 96 - 15 - s, 2))
        img[y:y + s, x:x + s] = 30
        img[y + s // 3:y + 2 * s // 3, x + s // 3:x + 2 * s // 3] = centre
        images.append(img)
        boxes.append(np.array([[0, x, y, x + s, y + s]], float))
    return images, boxes


def test_a_refiner_trained_on_squares_places_jittered_boxes_better_than_it_got_them(tmp_path):
    from chaser_bt.vision.detector.evaluate import iou_matrix

    torch.set_num_threads(1)
    cfg = RefinerConfig(input_px=32, widths=(8, 16, 16))
    rng = np.random.default_rng(0)
    crops, given, targets = make_refiner_set(*_squares(300, rng), cfg, 4, rng)
    train_refiner(crops, given, targets, tmp_path / "sq.pt", cfg, steps=300, batch=64, lr=3e-3, progress=None)
    refiner = BoxRefiner(tmp_path / "sq.pt")
    images, labels = _squares(60, np.random.default_rng(7))
    before, after = [], []
    for img, lab in zip(images, labels):
        jittered = jitter_boxes(lab[0, 1:], 1, rng)
        before.append(iou_matrix(jittered, lab[:, 1:])[0, 0])
        after.append(iou_matrix(refiner.boxes(img, jittered), lab[:, 1:])[0, 0])
    assert np.mean(after) > np.mean(before) + 0.07, (np.mean(before), np.mean(after))  # measured 0.61 -> 0.73


def test_false_detections_are_the_boxes_that_overlap_no_label():
    labels = [np.array([[0, 10, 10, 30, 30]], float), np.zeros((0, 5))]
    found = {0: [(12, 10, 32, 30), (20, 20, 40, 40), (60, 60, 80, 80)], 1: [(5, 5, 9, 9)]}
    frames = [np.full((4, 4, 3), k, np.uint8) for k in range(2)]  # the frame's value says which it is

    def detect(frame):
        return [Detection(b, 0.5, 0, "person") for b in found[int(frame[0, 0, 0])]]

    # IoU with the label: 360/440 = 0.82 (a true box), 100/700 = 0.14 (false at max_iou 0.3), 0 (false).
    out = false_detections(detect, frames, labels, max_iou=0.3)
    assert out[0].tolist() == [[20, 20, 40, 40], [60, 60, 80, 80]] and out[1].tolist() == [[5, 5, 9, 9]]
    assert false_detections(detect, frames, labels, max_iou=0.1)[0].tolist() == [[60, 60, 80, 80]]


def test_negative_crops_are_cut_around_the_false_boxes_as_the_refiner_cuts_them():
    cfg = RefinerConfig(input_px=32, context=2.0, min_side_px=8.0)
    img = np.zeros((100, 100, 3), np.uint8)
    img[40:60, 40:60] = 255
    crops, given = make_negative_set([img, img], [np.array([[40.0, 40.0, 60.0, 60.0]]), np.zeros((0, 4))], cfg)
    assert crops.shape == (1, 32, 32, 3) and given.dtype == np.float32
    assert given[0] == pytest.approx([0.25, 0.25, 0.75, 0.75])  # window 30-70: side 2 x 20 around the centre
    assert crops[0, 16, 16].min() == 255 and crops[0, 2, 2].max() == 0
    empty, none = make_negative_set([img], [np.zeros((0, 4))], cfg)
    assert empty.shape == (0, 32, 32, 3) and none.shape == (0, 4)


def _look_alikes(n: int, rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The squares with a grey centre (not targets) and their (1, 4) boxes."""
    images, labels = _squares(n, rng, centre=150)
    return images, [lab[:, 1:] for lab in labels]


def test_a_scoring_refiner_learns_to_tell_the_target_from_a_look_alike_and_the_detector_drops_what_it_rejects(tmp_path):
    """Targets: dark squares with a bright centre; look-alikes: the same squares with a grey one. After
    training on both, held-out targets score over 0.5 and look-alikes under it, and a detection's score
    becomes the detector's times the refiner's."""
    torch.set_num_threads(1)
    cfg = RefinerConfig(input_px=32, widths=(8, 16, 16), scores=True)
    rng = np.random.default_rng(0)
    crops, given, targets = make_refiner_set(*_squares(300, rng), cfg, 2, rng)
    negatives = make_negative_set(*_look_alikes(300, rng), cfg)
    with pytest.raises(ValueError, match="negative"):
        train_refiner(crops, given, targets, tmp_path / "x.pt", cfg, steps=1, progress=None)
    train_refiner(crops, given, targets, tmp_path / "sc.pt", cfg, steps=300, batch=64, lr=3e-3, progress=None, negatives=negatives)
    refiner = BoxRefiner(tmp_path / "sc.pt", backend="torch")
    test_rng = np.random.default_rng(7)
    images, labels = _squares(40, test_rng)
    look_alikes, boxes = _look_alikes(40, test_rng)
    p_target = np.array([refiner.refine(img, lab[:, 1:])[1][0] for img, lab in zip(images, labels)])
    p_false = np.array([refiner.refine(img, b)[1][0] for img, b in zip(look_alikes, boxes)])
    assert (p_target > 0.5).mean() >= 0.9 and (p_false < 0.5).mean() >= 0.9, (p_target, p_false)
    det = refiner(images[0], [Detection(tuple(labels[0][0, 1:]), 0.64, 0, "person")])[0]
    assert det.score == pytest.approx(0.64 * p_target[0], rel=1e-5)
    assert refiner.refine(images[0], [])[1].shape == (0,)

    from chaser_bt.vision.detector.refine import export_refiner_onnx

    pytest.importorskip("onnxruntime")
    export_refiner_onnx(tmp_path / "sc.pt")
    onnx = BoxRefiner(tmp_path / "sc.pt", backend="onnx")
    assert onnx.config.scores and onnx.refine(look_alikes[0], boxes[0])[1] == pytest.approx(p_false[:1], abs=1e-4)


def test_the_detector_keeps_only_what_clears_its_threshold_after_a_scoring_refiner(tmp_path):
    """A scoring refiner whose head says "no target" everywhere (probability 0.018) leaves nothing over 0.25
    of what the detector found; one that says "a target" (0.982) keeps each box whose score times 0.982
    still clears 0.25, re-scored."""
    from chaser_bt.vision.detector.inference import Detector
    from sitl.bench.camera_dataset import DatasetRenderer, frame_boxes

    rng = np.random.default_rng(3)
    data = DatasetRenderer("train", ground_size_px=1024)
    frame = next(f.image for f in iter(lambda: data.sample(rng), None) if len(frame_boxes(f)))
    plain = Detector(refiner=None)(frame)
    assert plain, "the shipped detector finds the rendered target"
    for logit in (-4.0, 4.0):
        net = BoxRefinerNet(RefinerConfig(scores=True))
        torch.nn.init.zeros_(net.head[-1].weight)
        with torch.no_grad():
            net.head[-1].bias.copy_(torch.tensor([0.0, 0.0, 0.0, 0.0, logit]))
        _save(net, tmp_path / "r.pt")
        p = 1 / (1 + np.exp(-logit))
        want = sorted(d.score * p for d in plain if d.score * p >= 0.25)
        rescored = Detector(refiner=tmp_path / "r.pt")(frame)
        assert sorted(d.score for d in rescored) == pytest.approx(want, rel=1e-4)
        assert [d.score for d in rescored] == sorted((d.score for d in rescored), reverse=True)
    assert want, "the boxes the shipped detector is sure of survive a refiner that agrees"


def test_the_shipped_refiner_improves_the_shipped_detectors_boxes_on_a_fresh_heldout_set():
    from chaser_bt.vision.detector.evaluate import iou_matrix
    from chaser_bt.vision.detector.inference import DEFAULT_WEIGHTS, Detector
    from sitl.bench.camera_dataset import DatasetRenderer, frame_boxes

    assert refiner_path(DEFAULT_WEIGHTS).exists()
    plain = Detector(conf_threshold=0.25, refiner=None)
    refined = Detector(conf_threshold=0.25)
    assert refined.refiner is not None
    data = DatasetRenderer("heldout", ground_size_px=1024)
    rng = np.random.default_rng(20261122)
    ious = {"plain": [], "refined": []}
    for _ in range(40):
        f = data.sample(rng)
        gt = frame_boxes(f)
        if not len(gt):
            continue
        for name, det in (("plain", plain), ("refined", refined)):
            for d in det(f.image):
                best = iou_matrix(np.array([d.box]), gt[:, 1:])[0].max()
                if best >= 0.5:
                    ious[name].append(best)
    assert np.mean(ious["refined"]) > np.mean(ious["plain"]), {k: np.mean(v) for k, v in ious.items()}


def test_an_exported_refiner_runs_in_onnxruntime_as_in_torch_and_a_stale_copy_is_not_used(tmp_path):
    import os

    pytest.importorskip("onnxruntime")
    from chaser_bt.vision.detector.refine import export_refiner_onnx, refiner_onnx_path

    torch.manual_seed(0)
    net = BoxRefinerNet(RefinerConfig(input_px=32, widths=(8, 16, 16)))
    _save(net, tmp_path / "r.pt")
    assert BoxRefiner(tmp_path / "r.pt").backend == "torch"  # no copy yet
    assert export_refiner_onnx(tmp_path / "r.pt") == refiner_onnx_path(tmp_path / "r.pt") == tmp_path / "r.onnx"
    onnx, plain = BoxRefiner(tmp_path / "r.pt"), BoxRefiner(tmp_path / "r.pt", backend="torch")
    assert onnx.backend == "onnx" and onnx.config == plain.config
    img = (np.random.default_rng(4).random((120, 160, 3)) * 255).astype(np.uint8)
    boxes = np.array([(40.0, 30.0, 80.0, 50.0), (100.0, 60.0, 130.0, 100.0), (0.0, 0.0, 6.0, 9.0)])
    with torch.inference_mode():  # the network by hand, on the crops the refiner cuts
        w = np.array([crop_window(b, plain.config) for b in boxes])
        crops = torch.from_numpy(np.ascontiguousarray(_crops(img, w, 32)[..., ::-1])).permute(0, 3, 1, 2).float() / 255.0
        frac = net.eval()(crops, torch.from_numpy(((boxes - w[:, [0, 1, 0, 1]]) / w[:, [2, 2, 2, 2]]).astype(np.float32))).numpy()
    by_hand = w[:, [0, 1, 0, 1]] + frac * w[:, [2, 2, 2, 2]]
    kept = np.linalg.norm(0.5 * (by_hand[:, :2] + by_hand[:, 2:] - boxes[:, :2] - boxes[:, 2:]), axis=1) <= 0.5 * (boxes[:, 2:] - boxes[:, :2]).max(1)
    want = np.where(kept[:, None], by_hand, boxes)
    assert plain.boxes(img, boxes) == pytest.approx(want, abs=1e-4)
    assert onnx.boxes(img, boxes) == pytest.approx(want, abs=1e-3)
    t = (tmp_path / "r.pt").stat().st_mtime
    os.utime(tmp_path / "r.onnx", (t - 60, t - 60))  # retrained after the copy was made
    assert BoxRefiner(tmp_path / "r.pt").backend == "torch"


def test_the_shipped_refiners_onnx_copy_places_the_detectors_boxes_as_torch_does_on_rendered_frames():
    pytest.importorskip("onnxruntime")
    from chaser_bt.vision.detector.inference import DEFAULT_WEIGHTS, Detector
    from sitl.bench.camera_dataset import DatasetRenderer

    onnx = BoxRefiner(refiner_path(DEFAULT_WEIGHTS))
    plain = BoxRefiner(refiner_path(DEFAULT_WEIGHTS), backend="torch")
    assert onnx.backend == "onnx"
    det = Detector(refiner=None)
    data = DatasetRenderer("heldout", ground_size_px=1024, follow_share=0.5)
    rng = np.random.default_rng(20261202)
    count = 0
    for _ in range(12):
        image = data.sample(rng).image
        boxes = [d.box for d in det(image)]
        if boxes:
            count += len(boxes)
            assert onnx.boxes(image, boxes) == pytest.approx(plain.boxes(image, boxes), abs=0.01)
    assert count >= 8
