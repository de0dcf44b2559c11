"""Dataset writer (YOLO layout) and the training augmentations."""

from __future__ import annotations

import numpy as np
import pytest

from chaser_bt.vision.detector.augment import (
    flip_horizontal,
    hsv_jitter,
    letterbox,
    mosaic,
)
from sitl.bench.camera_dataset import CLASSES, SPLITS, read_yolo_labels, write_dataset


def test_written_dataset_round_trips_its_labels(tmp_path):
    out = write_dataset(tmp_path / "d", 6, seed=3, split="heldout", ground_size_px=512)
    assert (out / "classes.txt").read_text().split() == list(CLASSES)
    images = sorted((out / "images").glob("*.jpg"))
    assert len(images) == 6
    boxes = [read_yolo_labels(out / "labels" / (p.stem + ".txt"), 640, 480) for p in images]
    allb = np.concatenate(boxes)
    assert len(allb) >= 3
    assert np.all(allb[:, 1:] >= -0.01) and np.all(allb[:, [1, 3]] <= 640.01) and np.all(allb[:, [2, 4]] <= 480.01)
    assert set(allb[:, 0].astype(int)) <= {0, 1}


def test_training_and_heldout_splits_share_no_ground():
    for train in ("train", "train_wide"):
        assert not set(SPLITS[train].ground_seeds) & set(SPLITS["heldout"].ground_seeds)
    assert 1003 not in SPLITS["train_wide"].ground_seeds  # the follow benchmark's ground


def test_mosaic_keeps_boxes_on_their_pixels():
    rng = np.random.default_rng(0)
    imgs, boxes = [], []
    for k in range(4):
        img = np.zeros((100, 120, 3), np.uint8)
        img[40:60, 50:70] = 255
        imgs.append(img)
        boxes.append(np.array([[k % 2, 50.0, 40.0, 70.0, 60.0]]))
    for _ in range(10):
        out, b = mosaic(imgs, boxes, 128, rng, scale_range=(1.0, 1.0), focus=1.0)
        assert out.shape == (128, 128, 3) and len(b) >= 1
        for _, x0, y0, x1, y1 in b:
            patch = out[int(np.ceil(y0)):int(y1), int(np.ceil(x0)):int(x1)]
            assert patch.size and patch.min() == 255


def test_flip_letterbox_and_hsv():
    img = np.zeros((100, 200, 3), np.uint8)
    img[10:20, 30:50] = 200
    f, b = flip_horizontal(img, np.array([[0, 30.0, 10.0, 50.0, 20.0]]))
    assert b[0, 1:].tolist() == [150.0, 10.0, 170.0, 20.0] and f[15, 160].max() == 200
    lb, scale, (px, py) = letterbox(img, 64)
    assert lb.shape == (64, 64, 3) and scale == pytest.approx(0.32) and (px, py) == (0, 16)
    assert hsv_jitter(img, np.random.default_rng(0)).shape == img.shape


def test_person_dataset_puts_people_on_the_ground_with_their_own_class_list(tmp_path):
    from sitl.bench.camera_dataset import PERSON_CLASSES, DatasetRenderer

    out = write_dataset(tmp_path / "p", 6, seed=2, split="train", kinds=PERSON_CLASSES, ground_size_px=256)
    assert (out / "classes.txt").read_text().split() == ["person"]
    boxes = np.concatenate([read_yolo_labels(p, 640, 480) for p in sorted((out / "labels").glob("*.txt"))])
    assert len(boxes) >= 4 and set(boxes[:, 0].astype(int)) == {0}
    rng = np.random.default_rng(0)
    data = DatasetRenderer("train", ground_size_px=256, kinds=PERSON_CLASSES)
    frame = data.sample(rng)
    assert all(lab.kind == "person" for lab in frame.labels)
    with pytest.raises(ValueError, match="known"):
        DatasetRenderer("train", kinds=("person", "yeti"))


def test_follow_views_put_one_target_near_the_image_centre():
    from sitl.bench.camera_dataset import DatasetRenderer

    data = DatasetRenderer("train", ground_size_px=256, follow_share=1.0)
    rng = np.random.default_rng(1)
    for _ in range(4):
        (lab,) = data.sample(rng).labels
        cx, cy = lab.centre_px
        assert abs(cx - 320) < 0.25 * 640 and abs(cy - 240) < 0.25 * 480  # nose on it within a few degrees
        assert 8 <= lab.box[2] - lab.box[0] <= 200
    with pytest.raises(ValueError, match="follow_share"):
        DatasetRenderer("train", ground_size_px=256, follow_share=1.5)


def test_a_dataset_from_camera_world_families_draws_another_world_reproducibly():
    from sitl.bench.camera_dataset import DatasetRenderer

    plain = DatasetRenderer("heldout", 320, 240, 512)
    coast = DatasetRenderer("heldout", 320, 240, families=("coast",))
    assert len(coast.renderers) == len(SPLITS["heldout"].ground_seeds)  # one world per family and ground seed
    frames = [coast.sample(np.random.default_rng(seed)) for seed in range(6)]
    again = coast.sample(np.random.default_rng(0))
    assert np.array_equal(frames[0].image, again.image) and frames[0].labels == again.labels
    assert sum(len(f.labels) for f in frames) >= 3
    for f in frames:
        for lab in f.labels:
            x0, y0, x1, y1 = lab.box
            assert 0 <= x0 < x1 <= 320 and 0 <= y0 < y1 <= 240
    # The coast's ground (water, rock, overcast) is not the plain field's green: compare mean colours.
    green = np.mean([plain.sample(np.random.default_rng(s)).image.reshape(-1, 3).mean(axis=0) for s in range(6)], axis=0)
    grey = np.mean([f.image.reshape(-1, 3).mean(axis=0) for f in frames], axis=0)
    assert green[1] - green[2] > grey[1] - grey[2] + 5  # the plain field is greener (G - R 22 vs 13 here)
