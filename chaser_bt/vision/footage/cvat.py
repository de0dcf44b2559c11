"""Readers for CVAT's detection exports: YOLO 1.1 and COCO 1.0 (docs.cvat.ai, "Dataset formats").

YOLO 1.1: ``obj.names`` (class names in id order), ``obj.data`` (``train = data/train.txt``,
``names = data/obj.names``, darknet paths under ``data/``), ``train.txt`` / ``valid.txt`` listing
``data/obj_<subset>_data/<image>``, and beside each image a ``<stem>.txt`` of ``class cx cy w h``
lines, fractions of the image. COCO 1.0: ``annotations/instances_<subset>.json`` (``default``
unless the task has subsets) with ``images`` (id, file_name, width, height), ``annotations``
(image_id, category_id, ``bbox`` = x, y, w, h in pixels) and ``categories`` (id from 1, name);
images, when saved, under ``images/`` (``images/<subset>/`` for projects with subsets). A video
task names its frames ``frame_000000.PNG`` and so on: the number is the frame index.

Both become :class:`LabelledFrame`s with boxes in YOLO's normalised form (the form the project's
folders keep); a label line that does not parse is a :class:`FootageError` naming file and line.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import PurePosixPath

import numpy as np

from chaser_bt.vision.footage.archive import ExportArchive

__all__ = ["FootageError", "LabelledFrame", "FootageLabels", "read_yolo11", "read_coco10", "read_export", "frame_number"]

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp")
_TRAILING_NUMBER = re.compile(r"(\d+)$")


class FootageError(ValueError):
    """An export or video that cannot be read as labelled footage; the message names the file (and line)."""


@dataclass(frozen=True)
class LabelledFrame:
    """One labelled image of an export.

    Attributes:
        name: the image's path inside the export (``obj_train_data/frame_000012.PNG``, ``images/x.jpg``).
        frame: the frame index (the number ending the name; else the image's place in the export).
        boxes: (N, 5) class id, cx, cy, w, h as fractions of the image (YOLO's form).
        size: (width, height) the export states (COCO), or None (YOLO does not say).
    """

    name: str
    frame: int
    boxes: np.ndarray
    size: tuple[int, int] | None = None

    def pixel_boxes(self, width: int, height: int) -> np.ndarray:
        """(N, 5) class id, x0, y0, x1, y1 in pixels of a ``width`` x ``height`` image."""
        b = self.boxes
        cx, cy, w, h = b[:, 1] * width, b[:, 2] * height, b[:, 3] * width, b[:, 4] * height
        return np.stack([b[:, 0], cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], 1).reshape(-1, 5)


@dataclass
class FootageLabels:
    """What an export holds: its format, class names in id order and labelled frames by frame index;
    ``numbered`` when the indices are the numbers in the image names (a video task's), not export order."""

    format: str
    classes: tuple[str, ...]
    frames: list[LabelledFrame] = field(default_factory=list)
    numbered: bool = True


def frame_number(name: str) -> int | None:
    """The number ending a file's stem (``frame_000042.PNG`` -> 42), or None."""
    m = _TRAILING_NUMBER.search(PurePosixPath(name).stem)
    return int(m.group(1)) if m else None


def _numbered(names: list[str]) -> tuple[list[int], bool]:
    """Frame indices: the numbers in the names when every name has a distinct one (True), else export order (False)."""
    nums = [frame_number(n) for n in names]
    if all(n is not None for n in nums) and len(set(nums)) == len(nums):
        return nums, True  # type: ignore[return-value]
    return list(range(len(names))), False


def _strip_data(path: str) -> str:
    """Darknet's lists say ``data/obj_train_data/x.jpg``; the export holds ``obj_train_data/x.jpg``."""
    p = path.strip().replace("\\", "/")
    while p.startswith("./"):
        p = p[2:]
    return p.removeprefix("data/")


def _parse_yolo_lines(text: str, where: str, num_classes: int) -> np.ndarray:
    rows = []
    for n, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        try:
            if len(parts) != 5:
                raise ValueError("expected 5 fields")
            c = int(parts[0])
            vals = [float(v) for v in parts[1:]]
        except ValueError:
            raise FootageError(f"{where}:{n}: expected 'class cx cy w h', got {line.strip()!r}") from None
        if not 0 <= c < num_classes:
            raise FootageError(f"{where}:{n}: class id {c} not in obj.names (0..{num_classes - 1})")
        if not all(np.isfinite(vals)):
            raise FootageError(f"{where}:{n}: not a finite number in {line.strip()!r}")
        rows.append([c, *vals])
    return np.array(rows, float).reshape(-1, 5)


def read_yolo11(archive: ExportArchive) -> FootageLabels:
    """The labelled frames of a CVAT "YOLO 1.1" export (see module docstring)."""
    names = archive.names()
    if not archive.exists("obj.names"):
        raise FootageError(f"{archive.path}: no obj.names (not a YOLO 1.1 export)")
    classes = tuple(x.strip() for x in archive.read_text("obj.names").splitlines() if x.strip())
    lists: list[str] = []
    if archive.exists("obj.data"):
        for line in archive.read_text("obj.data").splitlines():
            key, _, value = line.partition("=")
            if key.strip() in ("train", "valid") and value.strip():
                lists.append(_strip_data(value))
    lists = [x for x in lists if archive.exists(x)] or [n for n in ("train.txt", "valid.txt") if archive.exists(n)]
    images: list[str] = []
    for lst in lists:
        images += [_strip_data(x) for x in archive.read_text(lst).splitlines() if x.strip()]
    if not images:  # no image list: every label file under obj_<subset>_data/ names one
        for n in names:
            if n.startswith("obj_") and n.endswith(".txt"):
                stem = n[:-4]
                images.append(next((stem + s for s in _suffixes(stem, names)), stem + ".jpg"))
    frames = []
    nums, numbered = _numbered(images)
    for img, num in zip(images, nums):
        label = str(PurePosixPath(img).with_suffix(".txt"))
        boxes = _parse_yolo_lines(archive.read_text(label), archive.where(label), len(classes)) if archive.exists(label) else np.zeros((0, 5))
        frames.append(LabelledFrame(img, num, boxes))
    return FootageLabels("yolo1.1", classes, sorted(frames, key=lambda f: f.frame), numbered)


def _suffixes(stem: str, names: list[str]) -> list[str]:
    have = set(names)
    return [s for s in (*IMAGE_SUFFIXES, *(x.upper() for x in IMAGE_SUFFIXES)) if stem + s in have]


def read_coco10(archive: ExportArchive) -> FootageLabels:
    """The labelled frames of a CVAT "COCO 1.0" export: every ``annotations/instances_*.json`` (see module docstring)."""
    jsons = [n for n in archive.names() if n.startswith("annotations/") and n.endswith(".json") and "instances" in n]
    if not jsons:
        raise FootageError(f"{archive.path}: no annotations/instances_*.json (not a COCO 1.0 export)")
    classes: tuple[str, ...] | None = None
    found: list[tuple[str, str, np.ndarray, tuple[int, int]]] = []  # path, file_name, normalised boxes, size
    for js in jsons:
        where = archive.where(js)
        try:
            doc = json.loads(archive.read_text(js))
            cats = sorted(doc["categories"], key=lambda c: int(c["id"]))
            images = doc["images"]
            anns = doc.get("annotations", [])
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as e:
            raise FootageError(f"{where}: not a COCO instances file ({type(e).__name__}: {e})") from None
        names = tuple(str(c["name"]) for c in cats)
        if classes is not None and names != classes:
            raise FootageError(f"{where}: categories {names} differ from the other subsets' {classes}")
        classes = names
        cat_index = {int(c["id"]): i for i, c in enumerate(cats)}
        subset = PurePosixPath(js).stem.removeprefix("instances_")
        by_image: dict[int, list[list[float]]] = {int(im["id"]): [] for im in images}
        for a in anns:
            try:
                iid, cid = int(a["image_id"]), int(a["category_id"])
                x, y, w, h = (float(v) for v in a["bbox"])
            except (KeyError, TypeError, ValueError) as e:
                raise FootageError(f"{where}: annotation {a.get('id', '?')}: no usable image_id, category_id and bbox ({e})") from None
            if iid not in by_image:
                raise FootageError(f"{where}: annotation {a.get('id', '?')}: image_id {iid} is not in images")
            if cid not in cat_index:
                raise FootageError(f"{where}: annotation {a.get('id', '?')}: category_id {cid} is not in categories")
            by_image[iid].append([cat_index[cid], x, y, w, h])
        for im in images:
            try:
                width, height, _ = int(im["width"]), int(im["height"]), str(im["file_name"])
            except (KeyError, TypeError, ValueError) as e:
                raise FootageError(f"{where}: image {im.get('id', '?') if isinstance(im, dict) else im!r}: no usable width, height "
                                   f"and file_name ({e})") from None
            if width <= 0 or height <= 0:
                raise FootageError(f"{where}: image {im['id']} ({im['file_name']}): size {width} x {height}")
            rows = np.array(by_image[int(im["id"])], float).reshape(-1, 5)
            norm = np.stack([rows[:, 0], (rows[:, 1] + rows[:, 3] / 2) / width, (rows[:, 2] + rows[:, 4] / 2) / height,
                             rows[:, 3] / width, rows[:, 4] / height], 1).reshape(-1, 5)
            found.append((_coco_image_path(archive, str(im["file_name"]), subset), str(im["file_name"]), norm, (width, height)))
    nums, numbered = _numbered([f[1] for f in found])  # over every subset: one task's frames
    frames = [LabelledFrame(path, num, norm, size) for (path, _, norm, size), num in zip(found, nums)]
    return FootageLabels("coco1.0", classes or (), sorted(frames, key=lambda f: f.frame), numbered)


def _coco_image_path(archive: ExportArchive, file_name: str, subset: str) -> str:
    """Where the image is in the export (``images/<subset>/``, ``images/``), or ``images/<file_name>`` when absent."""
    for cand in (f"images/{subset}/{file_name}", f"images/{file_name}", file_name):
        if archive.exists(cand):
            return cand
    return f"images/{file_name}"


def read_export(archive: ExportArchive) -> FootageLabels:
    """Either format, told apart by its files (``obj.names``: YOLO 1.1; ``annotations/*.json``: COCO 1.0)."""
    if archive.exists("obj.names"):
        return read_yolo11(archive)
    if any(n.startswith("annotations/") and n.endswith(".json") for n in archive.names()):
        return read_coco10(archive)
    raise FootageError(f"{archive.path}: neither a CVAT YOLO 1.1 export (obj.names) nor a COCO 1.0 one (annotations/*.json)")
