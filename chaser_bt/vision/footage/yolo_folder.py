"""Writing the project's YOLO folders (``images/*.jpg``, ``labels/*.txt``, ``classes.txt``): what
``chaser-bt train-detector`` and ``eval-detector`` read, and what every footage importer writes.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from chaser_bt.vision.footage.cvat import FootageError

__all__ = ["box_line", "draw_preview", "prepare_parts", "write_example"]


def prepare_parts(out: Path, parts: Sequence[str], classes: Sequence[str], stems: Sequence[str] = ()) -> None:
    """Check that ``out/<part>`` can take this import, then make its ``images`` and ``labels`` and write
    ``classes.txt``.

    Raises:
        FootageError: an earlier import into ``out`` has other classes, or already wrote one of ``stems``.
    """
    classes = tuple(classes)
    for part in parts:
        have = out / part / "classes.txt"
        if have.exists() and tuple(x.strip() for x in have.read_text().splitlines() if x.strip()) != classes:
            raise FootageError(f"{have}: an earlier import has other classes than {list(classes)} (use a new folder)")
        for stem in stems:
            taken = out / part / "images" / f"{stem}.jpg"
            if taken.exists():
                raise FootageError(f"{taken} exists: an earlier import wrote it (give this one another --prefix)")
    for part in parts:
        (out / part / "images").mkdir(parents=True, exist_ok=True)
        (out / part / "labels").mkdir(parents=True, exist_ok=True)
        (out / part / "classes.txt").write_text("\n".join(classes) + "\n")


def box_line(class_id: int, x0: float, y0: float, x1: float, y1: float, width: int, height: int,
             min_box_px: float = 1.0) -> str | None:
    """``class cx cy w h`` (fractions of a ``width`` x ``height`` image) of the pixel box clipped to the
    image; None when it is then narrower or lower than ``min_box_px``."""
    x0, x1 = np.clip([x0, x1], 0, width)
    y0, y1 = np.clip([y0, y1], 0, height)
    if x1 - x0 < min_box_px or y1 - y0 < min_box_px:
        return None
    return (f"{class_id} {(x0 + x1) / 2 / width:.6f} {(y0 + y1) / 2 / height:.6f} "
            f"{(x1 - x0) / width:.6f} {(y1 - y0) / height:.6f}")


def write_example(part_dir: Path, stem: str, image: np.ndarray, lines: Sequence[str], jpeg_quality: int = 95) -> None:
    """``images/<stem>.jpg`` and ``labels/<stem>.txt`` (empty for a frame with no target: a negative)."""
    path = part_dir / "images" / f"{stem}.jpg"
    if not cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality]):
        raise FootageError(f"{path}: could not be written")
    (part_dir / "labels" / f"{stem}.txt").write_text("".join(x + "\n" for x in lines))


def draw_preview(path: Path, image: np.ndarray, lines: Sequence[str], classes: Sequence[str]) -> None:
    """The frame with its written boxes drawn (green) and named, for a look by eye."""
    path.parent.mkdir(parents=True, exist_ok=True)
    img = image.copy()
    h, w = img.shape[:2]
    for line in lines:
        k, cx, cy, bw, bh = line.split()
        x0, y0 = (float(cx) - float(bw) / 2) * w, (float(cy) - float(bh) / 2) * h
        x1, y1 = x0 + float(bw) * w, y0 + float(bh) * h
        cv2.rectangle(img, (round(x0), round(y0)), (round(x1), round(y1)), (0, 255, 0), 1)
        cv2.putText(img, classes[int(k)], (round(x0), max(round(y0) - 2, 8)), cv2.FONT_HERSHEY_SIMPLEX, 0.3, (0, 255, 0), 1)
    cv2.imwrite(str(path), img)
