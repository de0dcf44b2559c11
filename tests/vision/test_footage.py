"""CVAT exports and recorded video into YOLO folders: boxes worked out by hand, the contiguous split,
and what bad input gives (a clear error naming the file and line, or the frame skipped and counted)."""

from __future__ import annotations

import json
import shutil
import zipfile

import cv2
import numpy as np
import pytest
from footage_exports import H, W, coco_document, rendered_frames, write_coco10, write_video, write_yolo11
from hypothesis import given, settings
from hypothesis import strategies as st

from chaser_bt.cli import main
from chaser_bt.vision.footage import ExportArchive, FootageError, chunk_split, import_footage, read_export

CLASSES = ("s1000", "phantom")
# Pixel boxes in a 160 x 120 frame, and their YOLO fractions worked out by hand:
# (40, 30)-(80, 60): centre (60, 45) -> 60/160 = 0.375, 45/120 = 0.375; size 40/160 = 0.25, 30/120 = 0.25.
# (100, 90)-(116, 102): centre (108, 96) -> 0.675, 0.8; size 16/160 = 0.1, 12/120 = 0.1.
BOX_A = [0, 40.0, 30.0, 80.0, 60.0]
BOX_B = [1, 100.0, 90.0, 116.0, 102.0]
FRAC_A = [0, 0.375, 0.375, 0.25, 0.25]
FRAC_B = [1, 0.675, 0.8, 0.1, 0.1]
BOXES = [np.array([BOX_A]), np.array([BOX_A, BOX_B]), np.zeros((0, 5)), np.array([BOX_B]), np.array([BOX_A]), np.array([BOX_B])]


@pytest.fixture(scope="module")
def images():
    return rendered_frames(len(BOXES))[0]


def _unzip(path, folder):
    with zipfile.ZipFile(path) as z:
        z.extractall(folder)
    return folder


@pytest.mark.parametrize("fmt", ["yolo", "coco"])
@pytest.mark.parametrize("as_folder", [False, True])
def test_both_formats_read_back_the_hand_worked_boxes(tmp_path, images, fmt, as_folder):
    write = write_yolo11 if fmt == "yolo" else write_coco10
    export = write(tmp_path / "export.zip", CLASSES, BOXES, images)
    if as_folder:
        export = _unzip(export, tmp_path / "unpacked")
    with ExportArchive(export) as archive:
        labels = read_export(archive)
    assert labels.format == {"yolo": "yolo1.1", "coco": "coco1.0"}[fmt] and labels.classes == CLASSES
    assert [f.frame for f in labels.frames] == [0, 1, 2, 3, 4, 5]
    np.testing.assert_allclose(labels.frames[1].boxes, [FRAC_A, FRAC_B], atol=1e-12)
    np.testing.assert_allclose(labels.frames[1].pixel_boxes(W, H), [BOX_A, BOX_B], atol=1e-9)
    assert labels.frames[2].boxes.shape == (0, 5)
    assert labels.frames[1].size == (None if fmt == "yolo" else (W, H))


def test_a_zip_of_the_unpacked_folder_reads_like_the_export(tmp_path, images):
    folder = _unzip(write_yolo11(tmp_path / "e.zip", CLASSES, BOXES, images), tmp_path / "task_12_dataset")
    wrapped = shutil.make_archive(str(tmp_path / "wrapped"), "zip", tmp_path, "task_12_dataset")
    with ExportArchive(wrapped) as a:
        labels = read_export(a)
    np.testing.assert_allclose(labels.frames[3].boxes, [FRAC_B], atol=1e-12)
    assert labels.frames[3].name == "obj_train_data/frame_000003.PNG"
    holder = tmp_path / "downloads"
    shutil.copytree(folder, holder / folder.name)
    with ExportArchive(holder) as a:  # the folder holding the unpacked export
        assert read_export(a).frames[3].name == "obj_train_data/frame_000003.PNG"
        assert a.where("obj.names") == str(holder / folder.name / "obj.names")


def test_import_writes_train_and_val_yolo_folders_split_by_chunks(tmp_path, images):
    export = write_coco10(tmp_path / "coco.zip", CLASSES, BOXES, images)
    s = import_footage(export, tmp_path / "out", chunk=2, val_frac=0.34, seed=0)  # 3 chunks {0,1} {2,3} {4,5}, one held out
    assert (s.frames, s.imported, s.boxes, s.skipped) == (6, 6, 6, [])
    assert (s.train, s.val, s.train_chunks, s.val_chunks) == (4, 2, 2, 1)
    val = sorted(p.stem for p in (tmp_path / "out" / "val" / "images").glob("*.jpg"))
    assert val in (["000000", "000001"], ["000002", "000003"], ["000004", "000005"])
    for part in ("train", "val"):
        assert (tmp_path / "out" / part / "classes.txt").read_text() == "s1000\nphantom\n"
    where = "val" if "000001" in val else "train"
    assert (tmp_path / "out" / where / "labels" / "000001.txt").read_text() == (
        "0 0.375000 0.375000 0.250000 0.250000\n1 0.675000 0.800000 0.100000 0.100000\n")
    img = cv2.imread(str(tmp_path / "out" / where / "images" / "000001.jpg"))
    assert img.shape == (H, W, 3) and np.abs(img.astype(float) - images[1]).mean() < 3.0  # JPEG 95 of the same pixels
    assert json.loads((tmp_path / "out" / "import.json").read_text())[0]["imported"] == 6


def test_labels_are_renamed_mapped_onto_the_classes_and_clipped(tmp_path, images):
    boxes = [np.array([[0, -10.0, 100.0, 20.0, 130.0], [1, 10.0, 10.0, 20.0, 20.0]])]  # the first sticks out left and below
    export = write_coco10(tmp_path / "c.zip", ("drone", "bird"), boxes, images[:1])
    s = import_footage(export, tmp_path / "out", val_frac=0.0, classes=CLASSES, rename={"drone": "s1000"})
    # Clipped to (0, 100)-(20, 120): centre (10, 110) -> 0.0625, 0.916667; size 0.125, 0.166667. "bird" is no class.
    assert (tmp_path / "out" / "train" / "labels" / "000000.txt").read_text() == "0 0.062500 0.916667 0.125000 0.166667\n"
    assert s.dropped_boxes == {"label 'bird' is not one of the classes": 1} and s.boxes == 1


def test_frames_come_from_the_video_when_the_export_has_no_images(tmp_path, images):
    video = write_video(tmp_path / "flight.avi", images)
    for fmt, write in (("yolo", write_yolo11), ("coco", write_coco10)):
        export = write(tmp_path / f"{fmt}.zip", CLASSES, BOXES, None)
        s = import_footage(export, tmp_path / fmt, video=video, val_frac=0.0)
        assert (s.imported, s.boxes, s.skipped) == (6, 6, [])
        out = [cv2.imread(str(tmp_path / fmt / "train" / "images" / f"{i:06d}.jpg")).astype(float) for i in range(6)]
        # Each written frame is the video's frame of the same index (nearest of all six by mean difference).
        for i, img in enumerate(out):
            assert int(np.argmin([np.abs(img - ref).mean() for ref in images])) == i


def test_video_start_and_step_map_export_frames_onto_video_frames(tmp_path, images):
    video = write_video(tmp_path / "v.avi", images)
    export = write_yolo11(tmp_path / "y.zip", CLASSES, BOXES[:3], None)  # export frames 0, 1, 2 = video frames 1, 3, 5
    import_footage(export, tmp_path / "out", video=video, val_frac=0.0, video_start=1, video_step=2)
    for k, v in enumerate([1, 3, 5]):
        img = cv2.imread(str(tmp_path / "out" / "train" / "images" / f"{k:06d}.jpg")).astype(float)
        assert int(np.argmin([np.abs(img - ref).mean() for ref in images])) == v


@settings(max_examples=60, deadline=None)
@given(st.sets(st.integers(0, 400), min_size=1, max_size=80), st.integers(1, 25), st.floats(0.0, 0.9), st.integers(0, 9))
def test_contiguous_split_never_interleaves_chunks_and_uses_every_frame_once(frames, chunk, val_frac, seed):
    frames = list(frames)
    train, val = chunk_split(frames, chunk, val_frac, seed)
    assert sorted(train + val) == list(range(len(frames)))
    chunks_train = {frames[i] // chunk for i in train}
    chunks_val = {frames[i] // chunk for i in val}
    assert not chunks_train & chunks_val
    n = len(chunks_train | chunks_val)
    expected = 0 if val_frac == 0 or n < 2 else min(max(round(val_frac * n), 1), n - 1)
    assert len(chunks_val) == expected
    # Between two validation frames of one chunk lies no training frame: chunks are runs of frames.
    for c in chunks_val:
        lo, hi = c * chunk, (c + 1) * chunk - 1
        assert all(not lo <= frames[i] <= hi for i in train)


def test_split_is_seeded():
    frames = list(range(100))
    assert chunk_split(frames, 10, 0.3, seed=4) == chunk_split(frames, 10, 0.3, seed=4)
    assert chunk_split(frames, 10, 0.3, seed=4) != chunk_split(frames, 10, 0.3, seed=5)


# Bad input.

def test_a_label_line_that_does_not_parse_names_the_file_and_line(tmp_path, images):
    export = write_yolo11(tmp_path / "y.zip", CLASSES, BOXES, images, label_text={1: "0 0.5 0.5 0.1 0.1\n0 0.5 0.5 0.1\n"})
    with pytest.raises(FootageError, match=r"y\.zip!obj_train_data/frame_000001\.txt:2: expected 'class cx cy w h'"):
        import_footage(export, tmp_path / "out")
    export = write_yolo11(tmp_path / "z.zip", CLASSES, BOXES, images, label_text={4: "7 0.5 0.5 0.1 0.1\n"})
    with pytest.raises(FootageError, match=r"frame_000004\.txt:1: class id 7 not in obj.names"):
        import_footage(export, tmp_path / "out2")


def test_a_corrupt_image_and_a_missing_one_are_skipped_and_counted(tmp_path, images):
    export = write_yolo11(tmp_path / "y.zip", CLASSES, BOXES, images, image_bytes={2: b"\x89PNG not really"}, leave_out=(4,))
    s = import_footage(export, tmp_path / "out", val_frac=0.0)
    assert s.imported == 4 and s.boxes == 5
    assert dict(s.skipped) == {"obj_train_data/frame_000002.PNG": "not a readable image",
                               "obj_train_data/frame_000004.PNG": "image missing from the export (exported without images? pass the video)"}
    assert not (tmp_path / "out" / "train" / "images" / "000004.jpg").exists()


def test_an_export_without_any_image_and_no_video_is_an_error(tmp_path):
    export = write_coco10(tmp_path / "c.zip", CLASSES, BOXES, None)
    with pytest.raises(FootageError, match=r"c\.zip: no frame imported \(6 labelled, all skipped"):
        import_footage(export, tmp_path / "out")


def test_a_corrupt_or_short_video(tmp_path, images):
    export = write_coco10(tmp_path / "c.zip", CLASSES, BOXES, None)
    bad = tmp_path / "broken.avi"
    bad.write_bytes(b"RIFF\x00\x00garbage" * 50)
    with pytest.raises(FootageError, match=r"broken\.avi: cannot open as a video|broken\.avi: no frame could be decoded"):
        import_footage(export, tmp_path / "out", video=bad)
    assert not (tmp_path / "out").exists()
    short = write_video(tmp_path / "short.avi", images[:4])
    s = import_footage(export, tmp_path / "out2", video=short, val_frac=0.0)
    assert s.imported == 4 and [r for _, r in s.skipped] == ["frame 4 is past the end of short.avi", "frame 5 is past the end of short.avi"]


def test_coco_errors_name_the_json_and_the_annotation(tmp_path, images):
    doc = coco_document(CLASSES, BOXES)
    doc["annotations"][2]["image_id"] = 99
    export = write_coco10(tmp_path / "c.zip", CLASSES, BOXES, images, doc=doc)
    with pytest.raises(FootageError, match=r"instances_default\.json: annotation 3: image_id 99 is not in images"):
        import_footage(export, tmp_path / "out")
    wrong_size = write_coco10(tmp_path / "s.zip", CLASSES, BOXES, images, doc=coco_document(CLASSES, BOXES, size=(320, 240)))
    with pytest.raises(FootageError, match=r"no frame imported .*image is 160 x 120, the export says 320 x 240"):
        import_footage(wrong_size, tmp_path / "out3")


def test_not_an_export(tmp_path):
    junk = tmp_path / "junk.zip"
    junk.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match=r"junk\.zip: not a zip archive"):
        import_footage(junk, tmp_path / "out")
    with zipfile.ZipFile(tmp_path / "other.zip", "w") as z:
        z.writestr("readme.txt", "hi")
    with pytest.raises(FootageError, match="neither a CVAT YOLO 1.1 export"):
        import_footage(tmp_path / "other.zip", tmp_path / "out")


def test_cli_import_footage_prints_the_summary_and_names_bad_input(tmp_path, images, capsys):
    export = write_yolo11(tmp_path / "y.zip", CLASSES, BOXES, images, leave_out=(0,))
    assert main(["import-footage", str(export), "--out", str(tmp_path / "out"), "--chunk", "3", "--val-frac", "0.5"]) == 0
    out, err = capsys.readouterr()
    summary = json.loads(out)
    assert (summary["imported"], summary["train_chunks"], summary["val_chunks"]) == (5, 1, 1)
    assert "skipped obj_train_data/frame_000000.PNG: image missing" in err
    assert main(["import-footage", str(export), "--out", str(tmp_path / "out")]) == 2  # would overwrite
    assert "exists: an earlier import wrote it" in capsys.readouterr().err
    assert main(["import-footage", str(export), "--out", str(tmp_path / "o2"), "--rename", "drone"]) == 2
    assert "expected LABEL=CLASS" in capsys.readouterr().err


def test_several_flights_share_a_folder_with_a_prefix_each(tmp_path, images):
    a = write_yolo11(tmp_path / "a.zip", CLASSES, BOXES, images)
    b = write_coco10(tmp_path / "b.zip", CLASSES, BOXES[:3], images[:3])
    import_footage(a, tmp_path / "out", val_frac=0.0, prefix="f1_")
    with pytest.raises(FootageError, match=r"f1_000000\.jpg exists"):
        import_footage(b, tmp_path / "out", val_frac=0.0, prefix="f1_")
    import_footage(b, tmp_path / "out", val_frac=0.0, prefix="f2_")
    names = sorted(p.stem for p in (tmp_path / "out" / "train" / "labels").glob("*.txt"))
    assert names == [f"f1_{i:06d}" for i in range(6)] + [f"f2_{i:06d}" for i in range(3)]
    assert [r["imported"] for r in json.loads((tmp_path / "out" / "import.json").read_text())] == [6, 3]
    with pytest.raises(FootageError, match="an earlier import has other classes"):
        import_footage(b, tmp_path / "out", val_frac=0.0, prefix="f3_", classes=("person",), rename={"s1000": "person", "phantom": "person"})


def test_image_names_without_frame_numbers_keep_export_order_but_cannot_meet_a_video(tmp_path, images):
    doc = coco_document(CLASSES, BOXES[:3])
    for im, name in zip(doc["images"], ["b_last.jpg", "a_first.jpg", "c.jpg"]):
        im["file_name"] = name
    export = write_coco10(tmp_path / "c.zip", CLASSES, BOXES[:3], None, doc=doc)
    with ExportArchive(export) as archive:
        labels = read_export(archive)
    assert not labels.numbered and [(f.name, f.frame) for f in labels.frames] == [
        ("images/b_last.jpg", 0), ("images/a_first.jpg", 1), ("images/c.jpg", 2)]
    with pytest.raises(FootageError, match="no distinct frame numbers"):
        import_footage(export, tmp_path / "out", video=write_video(tmp_path / "v.avi", images))


def test_preview_draws_the_written_boxes(tmp_path, images):
    export = write_coco10(tmp_path / "c.zip", CLASSES, BOXES, images)
    import_footage(export, tmp_path / "out", val_frac=0.0, preview=2)
    assert sorted(p.name for p in (tmp_path / "out" / "preview").iterdir()) == ["000000.png", "000001.png"]
    drawn = cv2.imread(str(tmp_path / "out" / "preview" / "000000.png"))
    # BOX_A's right edge is the column x = 80 from y = 30 to 60, drawn pure green (PNG: lossless); beside it the frame.
    assert (drawn[35:58, 80] == (0, 255, 0)).all()
    assert (drawn[35:58, 83] == images[0][35:58, 83]).all()
