"""The cut-and-paste training frames: drone designs to scale, anti-aliased pastes, labels on what was
drawn, and the photograph sources kept for tests refused."""

from __future__ import annotations

import zipfile

import cv2
import numpy as np
import pytest

from sitl.bench.cut_paste import CutPaste, PhotoLibrary, draw_drone, draw_person, write_folder
from sitl.world.camera.models import PERSON_HEIGHT_M, random_multirotor, random_person


def _photo(path, value=(128, 128, 128), size=(300, 400)) -> None:
    img = np.empty((*size, 3), np.uint8)
    img[:] = value
    cv2.imwrite(str(path), img)


def test_a_design_spans_its_rotor_tips_and_keeps_its_rotors_translucent():
    rng = np.random.default_rng(4)
    arms_seen = set()
    for _ in range(40):
        m = random_multirotor(rng)
        discs = [p for p in m.parts if p.shape == "disc"]
        # The largest horizontal reach of any rotor disc, both sides: worked out from the parts alone.
        reach = max(np.hypot(p.a[0], p.a[1]) + p.radius for p in discs)
        assert m.span_m == pytest.approx(2 * reach)
        assert all(0.0 < p.alpha < 1.0 for p in discs)
        arms = [p for p in m.parts if p.shape == "rod" and p.a == (0.0, 0.0, 0.0)]
        assert len(discs) in (len(arms), 2 * len(arms))  # one rotor per arm, or a coaxial pair
        arms_seen.add(len(arms))
    assert arms_seen == {3, 4, 6, 8}


def test_a_random_person_stands_on_their_feet_to_their_height():
    rng = np.random.default_rng(6)
    for _ in range(30):
        m = random_person(rng)
        # Lowest point of any part (shoes) at the ground, the head's top at the model's height.
        low = min(min(p.a[2], p.b[2] if p.shape == "rod" else p.a[2]) - p.radius for p in m.parts)
        head = max(p.a[2] + p.radius for p in m.parts if p.shape == "sphere" and abs(p.a[1]) < 0.01 and p.a[2] > 1.0)
        assert -0.005 <= low <= 0.01
        assert 1.55 <= head <= 1.95 + 0.1 and head == pytest.approx(m.height_m, abs=0.12)
        assert 1.55 / PERSON_HEIGHT_M * 1.75 <= m.height_m <= 1.95


@pytest.mark.parametrize("span", [12.0, 30.0, 60.0])
def test_a_drawn_drone_is_about_its_span_across_and_its_patch_is_premultiplied(span):
    rng = np.random.default_rng(int(span))
    for _ in range(15):
        patch, cover = draw_drone(rng, span)
        assert patch.shape[:2] == cover.shape and 0.0 <= cover.min() and cover.max() <= 1.0
        # Premultiplied by its coverage: nothing where nothing was drawn, never brighter than covered.
        assert np.all(patch <= 255.0 * cover[..., None] + 1.0)
        ys, xs = np.nonzero(cover >= 0.2)
        # From any side, the rotor ring is seen across its full width along the camera's horizontal.
        across = max(xs.max() - xs.min() + 1, ys.max() - ys.min() + 1)
        assert 0.7 * span - 2 <= across <= 1.3 * span + 2


def test_a_drawn_person_is_never_longer_than_their_reach_and_lying_ones_are_seen_at_it():
    rng = np.random.default_rng(9)
    length, longest = 50.0, []
    for _ in range(30):
        patch, cover = draw_person(rng, length)
        assert np.all(patch <= 255.0 * cover[..., None] + 1.0)
        ys, xs = np.nonzero(cover >= 0.2)
        longest.append(max(xs.max() - xs.min() + 1, ys.max() - ys.min() + 1))
    # People are 1.55-1.95 m, drawn length_px per 1.75 m; the longest reach is a 1.95 m person's waving
    # hand, 2.0 * 1.95 / 1.75 m up (2.28 m with the hand): at most 1.31 lengths on the image, plus a rim
    # of anti-aliasing. Lying ones, half of them, show all of it; standing ones seen steeply far less.
    assert max(longest) <= 1.31 * length + 2
    assert np.median(longest) > 0.5 * length and min(longest) < 0.5 * length


def test_an_unknown_kind_is_refused(tmp_path):
    _photo(tmp_path / "grey.png")
    with pytest.raises(ValueError, match="one of drone, person"):
        CutPaste(PhotoLibrary([tmp_path / "grey.png"]), kind="car")


def test_the_sources_kept_for_independent_tests_are_refused(tmp_path):
    for name in ("skimage", "trigger-rally-data"):
        folder = tmp_path / name / "data"
        folder.mkdir(parents=True)
        _photo(folder / "grass.png")
        with pytest.raises(ValueError, match="kept for independent tests"):
            PhotoLibrary([folder])
        with pytest.raises(ValueError, match="kept for independent tests"):  # inside a folder given
            PhotoLibrary([tmp_path])


def test_photographs_come_from_folders_and_archives_and_unusable_ones_are_counted(tmp_path):
    (tmp_path / "walls").mkdir()
    _photo(tmp_path / "walls" / "field.jpg", (40, 120, 60))
    _photo(tmp_path / "walls" / "tiny.png", size=(50, 50))           # under min_side: dropped
    (tmp_path / "walls" / "broken.jpg").write_bytes(b"not a jpeg")     # unreadable: dropped
    _photo(tmp_path / "walls" / "rock_nm.png")                          # a normal map: not a picture
    ok, buf = cv2.imencode(".jpg", np.full((256, 256, 3), 90, np.uint8))
    with zipfile.ZipFile(tmp_path / "pack.pk3", "w") as z:
        z.writestr("textures/tex_nature/dirt.jpg", buf.tobytes())
        z.writestr("textures/readme.txt", "no image")
    lib = PhotoLibrary([tmp_path / "walls", tmp_path / "pack.pk3"])
    assert len(lib.photos) == 2 and lib.dropped == 2 and lib.maps_skipped == 1
    assert sorted(n.rsplit("/", 1)[-1] for n in lib.names) == ["dirt.jpg", "field.jpg"]
    with pytest.raises(ValueError, match="no usable photograph"):
        PhotoLibrary([tmp_path / "walls" / "tiny.png"])
    with pytest.raises(ValueError, match="no such photograph"):
        PhotoLibrary([tmp_path / "missing"])


def test_every_label_boxes_a_drawn_drone_and_nothing_is_drawn_outside_them(tmp_path):
    _photo(tmp_path / "grey.png", size=(480, 640))
    maker = CutPaste(PhotoLibrary([tmp_path / "grey.png"]), 320, 240, span_px=(16.0, 60.0), empty_share=0.0,
                     bird_rate=0.0, sky_share=0.0)
    rng = np.random.default_rng(2)
    labelled, strong = 0, 0
    for _ in range(12):
        frame = maker.sample(rng)
        assert frame.image.shape == (240, 320, 3)
        # What was pasted stands out of the flat grey photograph.
        smooth = cv2.GaussianBlur(frame.image.astype(np.float32), (0, 0), 1.5)
        residual = np.abs(smooth - cv2.GaussianBlur(smooth, (0, 0), 8.0)).max(axis=2)
        outside = np.ones(residual.shape, bool)
        for _, x0, y0, x1, y1 in frame.boxes.astype(int):
            assert 0 <= x0 < x1 <= 320 and 0 <= y0 < y1 <= 240
            labelled += 1
            strong += residual[y0:y1, x0:x1].max() > 15.0
            outside[max(y0 - 12, 0):y1 + 12, max(x0 - 12, 0):x1 + 12] = False
        assert np.percentile(residual[outside], 99.9) < 15.0
    assert labelled >= 12 and strong >= 0.9 * labelled


def test_the_folder_is_one_a_trainer_reads(tmp_path):
    from chaser_bt.vision.detector.train import load_yolo_folder

    _photo(tmp_path / "field.png", (50, 130, 70), size=(480, 640))
    root = write_folder(tmp_path / "cut", [tmp_path / "field.png"], 4, seed=0)
    images, boxes, classes = load_yolo_folder(root, 416)
    assert classes == ("drone",) and len(images) == 4
    assert all(b.shape[1] == 5 and np.all(b[:, 0] == 0) for b in boxes)
    people = write_folder(tmp_path / "people", [tmp_path / "field.png"], 2, seed=0, kind="person")
    assert load_yolo_folder(people, 416)[2] == ("person",)
