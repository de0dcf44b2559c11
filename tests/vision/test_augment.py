"""Training augmentations: mixup and blur checked against hand-worked properties, and the train-detector options."""

from __future__ import annotations

import numpy as np
import pytest

from chaser_bt.vision.detector.augment import gaussian_blur, mixup, motion_blur, motion_kernel, random_blur


def test_mixup_is_the_weighted_mean_of_the_images_and_keeps_the_boxes_of_both():
    a = np.full((4, 6, 3), 200, np.uint8)
    b = np.full((4, 6, 3), 100, np.uint8)
    b[0, 0] = (0, 50, 255)
    ba = np.array([[0, 1.0, 1.0, 3.0, 3.0]])
    bb = np.array([[1, 2.0, 0.0, 5.0, 2.0], [0, 0.0, 0.0, 1.0, 1.0]])
    img, boxes = mixup(a, ba, b, bb, 0.25)
    assert img[1, 1].tolist() == [125, 125, 125]  # 0.25 * 200 + 0.75 * 100
    assert img[0, 0].tolist() == [50, 88, 241]  # 50 + 0, 50 + 37.5 -> 88 (rounded), 50 + 191.25 -> 241
    assert boxes.tolist() == [ba[0].tolist(), *bb.tolist()]  # the union, in order
    assert mixup(a, ba, b, np.zeros((0, 5)), 1.0)[0].tolist() == a.tolist()
    with pytest.raises(ValueError, match="one size"):
        mixup(a, ba, b[:3], bb, 0.5)


def test_a_motion_kernel_spreads_a_point_evenly_along_its_line():
    k = motion_kernel(5, 0.0)
    assert k.shape == (5, 5) and k.sum() == pytest.approx(1.0)
    assert k[2].tolist() == pytest.approx([0.2] * 5) and k[[0, 1, 3, 4]].sum() == 0.0
    img = np.zeros((9, 9, 3), np.uint8)
    img[4, 4] = 250
    out = motion_blur(img, 5, np.pi / 2)  # vertical: the point becomes a 5 px column of 250 / 5
    assert out[2:7, 4, 0].tolist() == [50] * 5 and int(out.sum()) == 3 * 250


def test_blur_keeps_the_mean_brightness_and_smooths():
    rng = np.random.default_rng(0)
    img = (rng.random((96, 128, 3)) * 255).astype(np.uint8)
    for out in (motion_blur(img, 7, 0.6), gaussian_blur(img, 1.2), random_blur(img, np.random.default_rng(1))):
        assert out.shape == img.shape and out.dtype == np.uint8
        assert float(out.mean()) == pytest.approx(float(img.mean()), abs=0.5)  # the kernel sums to one
        assert float(out.std()) < 0.8 * float(img.std())  # and it does blur
    assert gaussian_blur(img, 0.0).tolist() == img.tolist() and motion_blur(img, 1, 0.0).tolist() == img.tolist()


def test_train_detector_takes_the_mixup_and_blur_options(tmp_path, monkeypatch):
    from chaser_bt.cli import main
    from chaser_bt.vision.detector import inference, train

    seen = {}
    monkeypatch.setattr(train, "train_detector", lambda cfg, resume=True: seen.setdefault("cfg", cfg) and tmp_path / "w.pt")
    monkeypatch.setattr(inference, "export_onnx", lambda weights, out: out)
    (tmp_path / "d" / "images").mkdir(parents=True)
    main(["train-detector", "--data", str(tmp_path / "d"), "--out", str(tmp_path / "w.pt"), "--mixup", "0.4", "--mixup-beta", "8", "--blur", "0"])
    cfg = seen["cfg"]
    assert (cfg.mixup, cfg.mixup_beta, cfg.blur) == (0.4, 8.0, 0.0)
    with pytest.raises(SystemExit):
        main(["train-detector", "--data", str(tmp_path / "d"), "--mixup", "1.5"])


def test_a_batch_with_mixup_and_blur_holds_the_boxes_of_both_mosaics():
    from chaser_bt.vision.detector.train import TrainConfig, _batch

    rng = np.random.default_rng(3)
    images = [np.full((64, 64, 3), 90, np.uint8) for _ in range(4)]
    for img in images:
        img[20:40, 20:40] = 220
    boxes = [np.array([[0, 20.0, 20.0, 40.0, 40.0]]) for _ in range(4)]
    cfg = TrainConfig("", "", batch=6, crop=64, mixup=1.0, blur=1.0, scale_range=(1.0, 1.0))
    x, targets = _batch(images, boxes, cfg, rng)
    assert tuple(x.shape) == (6, 3, 64, 64)
    assert all(len(t) >= 2 for t in targets)  # each mosaic's crop is placed on a box (focus), and mixup keeps both sets
