"""The ``photo`` family: drones and people drawn to the asked size and view, labelled by their drawn pixels."""

from __future__ import annotations

import numpy as np
import pytest

from sitl.bench.photo_family import draw_multirotor, draw_person


def _extent(cover: np.ndarray) -> tuple[int, int]:
    ys, xs = np.nonzero(cover >= 0.25)
    return xs.max() - xs.min() + 1, ys.max() - ys.min() + 1


@pytest.mark.parametrize("span", [8.0, 30.0, 80.0])
def test_a_drone_seen_from_above_is_its_span_plus_its_rotor_discs_across(span):
    # Four arms at 45, 135, 225 and 315 deg: the motors sit at +-span/2 * cos(45 deg) in x and in y, and
    # their rotor discs (radius 0.2 span, at least 1.5 px) reach beyond them on each side.
    patch, cover = draw_multirotor(span, 4, 90.0, 0.0, (200, 200, 200), gear=False)
    assert patch.shape[:2] == cover.shape and 0.0 <= cover.min() and cover.max() <= 1.0
    width, height = _extent(cover)
    expected = span * np.cos(np.radians(45)) + 2 * max(0.2 * span, 1.5)
    assert abs(width - expected) <= 2.5 and abs(height - expected) <= 2.5


def test_a_lower_view_squashes_the_drone_and_more_arms_fill_it():
    _, high = draw_multirotor(60.0, 4, 75.0, 0.0, (30, 30, 30), gear=False)
    _, low = draw_multirotor(60.0, 4, 20.0, 0.0, (30, 30, 30), gear=False)
    assert _extent(low)[1] < 0.6 * _extent(high)[1]
    assert abs(_extent(low)[0] - _extent(high)[0]) <= 2
    _, octo = draw_multirotor(60.0, 8, 75.0, 0.0, (30, 30, 30), gear=False)
    assert (octo >= 0.25).sum() > (high >= 0.25).sum()


def test_every_label_is_the_tight_box_of_a_drawn_drone():
    pytest.importorskip("skimage", reason="the photo family's backgrounds are scikit-image's sample photographs")
    from sitl.bench.photo_family import PhotoFamily

    family = PhotoFamily(320, 240)
    rng = np.random.default_rng(0)
    for _ in range(10):
        frame = family.sample(rng)
        assert frame.image.shape == (240, 320, 3) and 1 <= len(frame.boxes) <= 2
        for _, x0, y0, x1, y1 in frame.boxes:
            assert 0 <= x0 < x1 <= 320 and 0 <= y0 < y1 <= 240 and x1 - x0 >= 3


def test_the_family_writes_a_folder_eval_detector_reads(tmp_path):
    pytest.importorskip("skimage", reason="the photo family's backgrounds are scikit-image's sample photographs")
    from sitl.bench.photo_family import write_folder

    root = write_folder(tmp_path / "photo", 3, seed=1)
    assert (root / "classes.txt").read_text() == "drone\n"
    assert sorted(p.stem for p in (root / "images").glob("*.jpg")) == ["photo_drone_000000", "photo_drone_000001", "photo_drone_000002"]
    for label in (root / "labels").glob("*.txt"):
        rows = [line.split() for line in label.read_text().splitlines()]
        assert 1 <= len(rows) <= 2 and all(r[0] == "0" and all(0 < float(v) <= 1 for v in r[1:]) for r in rows)


def test_a_person_lying_seen_from_straight_above_is_their_height_long():
    # Lying along the image x axis (yaw 0), orthographic from 90 deg: feet to the top of the head is
    # 1.75 m plus the hair's overhang, drawn at length_px per 1.75 m; across: shoulders and arms.
    length = 60.0
    _, cover = draw_person(length, lying=True, elevation_deg=90.0, yaw_deg=0.0, top=(30, 30, 180), legs=(90, 60, 40),
                           skin=(160, 190, 230))
    width, height = _extent(cover)
    assert 0.95 * length <= width <= 1.1 * length
    assert height < 0.45 * length


def test_a_person_standing_is_a_small_blob_from_above_and_tall_from_a_low_view():
    length = 60.0
    kwargs = dict(lying=False, yaw_deg=0.0, top=(30, 30, 180), legs=(90, 60, 40), skin=(160, 190, 230))
    _, above = draw_person(length, elevation_deg=90.0, **kwargs)
    _, low = draw_person(length, elevation_deg=25.0, **kwargs)
    assert max(_extent(above)) < 0.45 * length
    # Seen from 25 deg above, 1.75 m of height spans cos(25 deg) of its length, plus head and shoes.
    assert 0.85 * np.cos(np.radians(25)) * length <= _extent(low)[1] <= 1.15 * length


def test_an_unknown_kind_is_refused():
    pytest.importorskip("skimage", reason="the photo family's backgrounds are scikit-image's sample photographs")
    from sitl.bench.photo_family import PhotoFamily

    with pytest.raises(ValueError, match="one of drone, person"):
        PhotoFamily(kind="car")


def test_the_person_family_labels_people(tmp_path):
    pytest.importorskip("skimage", reason="the photo family's backgrounds are scikit-image's sample photographs")
    from sitl.bench.photo_family import write_folder

    root = write_folder(tmp_path / "people", 2, seed=3, kind="person")
    assert (root / "classes.txt").read_text() == "person\n"
    assert sorted(p.stem for p in (root / "images").glob("*.jpg")) == ["photo_person_000000", "photo_person_000001"]
