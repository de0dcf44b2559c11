"""The Halmstad drone-detection dataset's importer: label decoding from hand-built MAT5 bytes, the fixed
split by video, the YOLO folders it writes from small videos, and the bad input a user meets. The
real dataset is read too where ``$CHASER_BT_HALMSTAD`` names its folder (skipped, saying so, elsewhere)."""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.io

from chaser_bt.cli import main as cli_main
from chaser_bt.vision.footage import FootageError
from chaser_bt.vision.footage.halmstad import (HELD_OUT, HalmstadVideo, align_labels, decode_workspace, find_videos,
                                               import_halmstad, is_halmstad, read_labels, split_videos)

W, H = 64, 48


def _element(type_id: int, payload: bytes) -> bytes:
    """A MAT5 element: tag (type, size) and the payload padded to 8 bytes."""
    return struct.pack("<II", type_id, len(payload)) + payload + b"\0" * (-len(payload) % 8)


def _cell(values: list[float]) -> bytes:
    """A miMATRIX cell holding a double array (flags, dims and name elements first, as MATLAB writes)."""
    body = _element(6, b"\0" * 8) + _element(5, struct.pack("<ii", 1, len(values))) + _element(1, b"")
    return _element(14, body + _element(9, struct.pack(f"<{len(values)}d", *values)))


def _workspace(cells: list[bytes], depth: int = 5) -> bytes:
    """Cells nested ``depth`` miMATRIX levels down, after the 8-byte preamble the workspace starts with."""
    body = b"".join(cells)
    for _ in range(depth):
        body = _element(14, body)
    return b"\0" * 8 + body


def test_the_label_table_decodes_into_boxes_per_frame_and_kind():
    # Frame 0: one drone at (10, 20) 30 x 40. Frame 1: two drones and a bird; the 2 x 4 matrix is
    # column-major (x's, y's, widths, heights). A one-double metadata cell among them is not a label.
    empty = _cell([])
    cells = [empty, empty, _cell([10, 20, 30, 40]), empty,
             _cell([7.0]),
             empty, _cell([1, 2, 3, 4]), _cell([100, 200, 5, 6, 7, 8, 9, 10]), empty]
    frames = decode_workspace(_workspace(cells))
    assert frames == [
        [("drone", (10.0, 20.0, 30.0, 40.0))],
        [("bird", (1.0, 2.0, 3.0, 4.0)), ("drone", (100.0, 5.0, 7.0, 9.0)), ("drone", (200.0, 6.0, 8.0, 10.0))],
    ]


def test_cells_that_are_not_whole_frames_are_refused():
    with pytest.raises(ValueError, match="5 label cells, not 4 a frame"):
        decode_workspace(_workspace([_cell([])] * 5))
    with pytest.raises(ValueError, match="0 label cells"):
        decode_workspace(_workspace([_cell([])] * 4, depth=3))  # the table is not where a groundTruth keeps it


def test_a_mat_file_without_a_matlab_object_and_a_garbage_file_name_the_file(tmp_path):
    plain = tmp_path / "V_DRONE_001_LABELS.mat"
    scipy.io.savemat(plain, {"boxes": np.zeros((3, 4))})
    with pytest.raises(FootageError, match=r"V_DRONE_001_LABELS\.mat: not a MATLAB groundTruth label file"):
        read_labels(plain)
    garbage = tmp_path / "V_DRONE_002_LABELS.mat"
    garbage.write_bytes(b"\x00\x01not a mat file" * 10)
    with pytest.raises(FootageError, match=r"V_DRONE_002_LABELS\.mat: not a MATLAB label file"):
        read_labels(garbage)


def test_labels_for_another_number_of_frames_than_the_video_name_the_file():
    assert align_labels([[], []], 2, "x.mat") == [[], []]
    with pytest.raises(FootageError, match=r"x\.mat: labels for 3 frames, the video has 2"):
        align_labels([[], [], []], 2, "x.mat")


def _videos(kind: str, numbers) -> list[HalmstadVideo]:
    return [HalmstadVideo(f"V_{kind.upper()}_{n:03d}", kind, n, Path("v.mp4"), Path("l.mat")) for n in numbers]


def test_the_split_holds_out_the_highest_numbered_third_and_draws_val_per_kind():
    videos = _videos("drone", range(1, 115)) + _videos("bird", range(1, 52)) + _videos("airplane", range(1, 60))
    part = split_videos(videos, 0.2, seed=3)
    for v in videos:
        lo, hi = HELD_OUT[v.kind]
        assert (part[v.name] == "test") == (lo <= v.number <= hi)
    assert part["V_DRONE_076"] != "test" and part["V_DRONE_077"] == "test" and part["V_BIRD_035"] == "test"
    for kind, pool in (("drone", 76), ("bird", 34), ("airplane", 39)):
        vals = [v for v in videos if v.kind == kind and part[v.name] == "val"]
        assert len(vals) == round(0.2 * pool)
    assert split_videos(videos, 0.2, seed=3) == part
    assert split_videos(videos, 0.2, seed=4) != part
    assert all(p != "val" for p in split_videos(videos, 0.0, seed=3).values())


def _write_video(path: Path, count: int) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (W, H))
    assert writer.isOpened()
    for i in range(count):
        writer.write(np.full((H, W, 3), 20 + 10 * i, np.uint8))
    writer.release()


@pytest.fixture
def dataset(tmp_path) -> tuple[Path, dict]:
    """A tiny dataset: drones 1 (train or val), 2 and 80 (test), bird 40 (test), a label file without its
    video (drone 3), and a video whose labels are one frame short (drone 4). Labels are injected."""
    folder = tmp_path / "Data" / "Video_V"
    folder.mkdir(parents=True)
    labels = {}
    for name, frames in (("V_DRONE_001", 6), ("V_DRONE_002", 6), ("V_DRONE_080", 4), ("V_BIRD_040", 4), ("V_DRONE_004", 5)):
        _write_video(folder / f"{name}.mp4", frames)
        kind = name.split("_")[1].lower()
        labels[name] = [[(kind, (8.0 + i, 4.0, 10.0, 6.0))] if i % 3 else [] for i in range(frames)]
    labels["V_DRONE_004"] = labels["V_DRONE_004"][:-1]
    for name in (*labels, "V_DRONE_003"):
        (folder / f"{name}_LABELS.mat").write_bytes(b"")
    return tmp_path, labels


def _reader(labels):
    return lambda path: labels[path.name[: -len("_LABELS.mat")]]


def test_import_writes_every_nth_frame_with_drone_boxes_and_bird_frames_as_negatives(dataset, tmp_path):
    root, labels = dataset
    out = tmp_path / "yolo"
    assert is_halmstad(root) and not is_halmstad(tmp_path / "nothing")
    s = import_halmstad(root, out, every=2, val_frac=0.0, labels_reader=_reader(labels))
    assert s.videos == {"train": 2, "val": 0, "test": 2}
    assert sorted(p.stem for p in (out / "test" / "images").glob("*.jpg")) == [
        "V_BIRD_040_000000", "V_BIRD_040_000002", "V_DRONE_080_000000", "V_DRONE_080_000002"]
    # Frame 2 of drone 80: box (10, 4) 10 x 6 in a 64 x 48 image -> centre (15, 7).
    assert (out / "test" / "labels" / "V_DRONE_080_000002.txt").read_text() == "0 0.234375 0.145833 0.156250 0.125000\n"
    assert (out / "test" / "labels" / "V_DRONE_080_000000.txt").read_text() == ""
    assert (out / "test" / "labels" / "V_BIRD_040_000002.txt").read_text() == ""  # a bird is a negative
    assert s.dropped_boxes == {"bird: a hard negative (not one of the classes)": 1}
    assert s.frames == {"train": 6, "val": 0, "test": 4} and s.boxes == {"train": 4, "val": 0, "test": 1}  # frames 2 and 4 of drones 1 and 2
    assert (out / "train" / "classes.txt").read_text() == "drone\n"
    assert dict(s.skipped) == {"V_DRONE_003": "video V_DRONE_003.mp4 is missing",
                               "V_DRONE_004": "V_DRONE_004_LABELS.mat: labels for 4 frames, the video has 5"}
    assert not list(out.glob("*/images/V_DRONE_004_*"))
    assert json.loads((out / "import.json").read_text())[0]["skipped"][0]["video"] == "V_DRONE_003"


def test_renamed_and_extra_classes_and_only_the_test_part(dataset, tmp_path):
    root, labels = dataset
    s = import_halmstad(root, tmp_path / "a", classes=("s1000", "phantom", "bird"), rename={"drone": "phantom"},
                        every=2, parts=("test",), labels_reader=_reader(labels))
    assert s.videos == {"train": 0, "val": 0, "test": 2} and not (tmp_path / "a" / "train").exists()
    assert (tmp_path / "a" / "test" / "labels" / "V_BIRD_040_000002.txt").read_text().startswith("2 ")
    assert (tmp_path / "a" / "test" / "labels" / "V_DRONE_080_000002.txt").read_text().startswith("1 ")
    with pytest.raises(FootageError, match="none is a Halmstad kind"):
        import_halmstad(root, tmp_path / "b", classes=("s1000",), labels_reader=_reader(labels))
    with pytest.raises(FootageError, match=r"rename: \['dron'\]"):
        import_halmstad(root, tmp_path / "b", rename={"dron": "x"}, labels_reader=_reader(labels))
    with pytest.raises(FootageError, match="an earlier import has other classes"):
        import_halmstad(root, tmp_path / "a", parts=("test",), labels_reader=_reader(labels))


def test_cli_imports_the_dataset_and_refuses_cvat_flags(dataset, tmp_path, capsys, monkeypatch):
    root, labels = dataset
    monkeypatch.setattr("chaser_bt.vision.footage.halmstad.read_labels", _reader(labels))
    assert cli_main(["import-footage", str(root), "--out", str(tmp_path / "o"), "--every", "2"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["videos"]["test"] == 2
    assert "skipped V_DRONE_003: video V_DRONE_003.mp4 is missing" in err and "skipped 2 videos" in err
    assert cli_main(["import-footage", str(root), "--out", str(tmp_path / "p"), "--chunk", "10"]) == 2
    assert "--chunk: not for the Halmstad dataset" in capsys.readouterr().err
    assert cli_main(["import-footage", str(tmp_path / "none"), "--format", "halmstad", "--out", str(tmp_path / "q")]) == 2
    assert "no Halmstad label files" in capsys.readouterr().err


REAL = os.environ.get("CHASER_BT_HALMSTAD", "")


@pytest.mark.skipif(not REAL, reason="the Halmstad dataset is not here: set $CHASER_BT_HALMSTAD to its folder "
                                     "(public repository DroneDetectionThesis/Drone-detection-dataset)")
def test_the_real_dataset_decodes_one_label_a_frame_each_kind_in_its_own_videos():
    videos, _ = find_videos(REAL)
    for v in videos[::25]:
        frames = read_labels(v.labels)
        capture = cv2.VideoCapture(str(v.video))
        assert len(frames) == int(capture.get(cv2.CAP_PROP_FRAME_COUNT)), v.name
        kinds = {k for f in frames for k, _ in f}
        assert kinds == {v.kind}, v.name
        boxes = np.array([b for f in frames for _, b in f])
        assert (boxes[:, 2:] > 0).all() and (boxes[:, :2] > -50).all() and (boxes[:, 0] < 640).all() and (boxes[:, 1] < 512).all()
