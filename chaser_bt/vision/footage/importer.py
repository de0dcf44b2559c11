"""A CVAT export (and the video its frames come from) into the project's YOLO folders.

``import_footage`` reads the export (:mod:`~chaser_bt.vision.footage.cvat`), maps its label names
onto the detector's classes, splits the frames by contiguous chunks
(:func:`~chaser_bt.vision.footage.split.chunk_split`) and writes ``OUT/train`` and ``OUT/val``, each
``images/<prefix>NNNNNN.jpg`` (the frame index), ``labels/<prefix>NNNNNN.txt`` and ``classes.txt``: what
``chaser-bt train-detector`` and ``eval-detector`` read. Frames whose pixels cannot be had (missing
from the export, unreadable, past the video's end, another size than the export says) are skipped
and counted with the reason; boxes are clipped to the image and dropped when nothing is left of them
or their label is not one of the classes. ``OUT/import.json`` keeps the summaries. Several flights
go into one folder with a ``prefix`` each (same classes; an existing file is never overwritten).
"""

from __future__ import annotations

import json
import logging
import re
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from chaser_bt.vision.footage.archive import ExportArchive
from chaser_bt.vision.footage.cvat import FootageError, LabelledFrame, read_export
from chaser_bt.vision.footage.split import chunk_split
from chaser_bt.vision.footage.video import VideoFrames

__all__ = ["ImportSummary", "import_footage"]

log = logging.getLogger(__name__)


@dataclass
class ImportSummary:
    """What an import did. ``skipped`` lists (image name, reason); ``dropped_boxes`` counts boxes by reason."""

    export: str
    format: str
    classes: tuple[str, ...]
    frames: int = 0
    imported: int = 0
    boxes: int = 0
    train: int = 0
    val: int = 0
    train_chunks: int = 0
    val_chunks: int = 0
    skipped: list[tuple[str, str]] = field(default_factory=list)
    dropped_boxes: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["skipped"] = [{"image": n, "reason": r} for n, r in self.skipped]
        return d


def _class_map(export_classes: Sequence[str], classes: Sequence[str] | None, rename: Mapping[str, str]) -> tuple[tuple[str, ...], list[int | None]]:
    """Output classes and, per export class id, the output id (None: not one of them)."""
    renamed = [rename.get(c, c) for c in export_classes]
    unknown = sorted(set(rename) - set(export_classes))
    if unknown:
        raise FootageError(f"rename: {unknown} are not labels of the export (it has {list(export_classes)})")
    out = tuple(classes) if classes else tuple(dict.fromkeys(renamed))
    if len(set(out)) != len(out):
        raise FootageError(f"classes: {list(out)} names a class twice")
    return out, [out.index(c) if c in out else None for c in renamed]


def _pixels(frame: LabelledFrame, archive: ExportArchive, video: VideoFrames | None) -> tuple[np.ndarray | None, str]:
    """The frame's BGR image, or None and why not."""
    if video is not None:
        img = video.frame(frame.frame)
        return (img, "") if img is not None else (None, f"frame {frame.frame} is past the end of {video.path.name}")
    if not archive.exists(frame.name):
        return None, "image missing from the export (exported without images? pass the video)"
    img = cv2.imdecode(np.frombuffer(archive.read_bytes(frame.name), np.uint8), cv2.IMREAD_COLOR)
    return (img, "") if img is not None else (None, "not a readable image")


def _write_preview(path: Path, image: np.ndarray, lines: list[str], classes: Sequence[str]) -> None:
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


def import_footage(export: str | Path, out_dir: str | Path, video: str | Path | None = None, chunk: int = 150,
                   val_frac: float = 0.2, seed: int = 0, classes: Sequence[str] | None = None,
                   rename: Mapping[str, str] | None = None, video_start: int = 0, video_step: int = 1,
                   min_box_px: float = 1.0, prefix: str = "", preview: int = 0, jpeg_quality: int = 95) -> ImportSummary:
    """Write ``out_dir/train`` and ``out_dir/val`` from a CVAT export (see module docstring).

    Args:
        export: a CVAT "YOLO 1.1" or "COCO 1.0" export, zip or unpacked folder.
        out_dir: where the two YOLO folders go (new, or holding other imports with the same classes).
        video: take every frame's pixels from this video (frame index = the number in the export's
            image name) instead of the export's images.
        chunk: frames per chunk of the split (at 30 frames/s, 150 is 5 s of flight).
        val_frac: share of chunks held out for validation.
        seed: which chunks are held out.
        classes: the output class names in id order (the detector's, e.g. ``s1000 phantom`` to
            fine-tune the shipped weights); default: the export's labels after ``rename``.
        rename: export label -> class name (``{"drone": "s1000"}``).
        video_start, video_step: the video frame of export frame 0, and video frames per export frame.
        min_box_px: a box narrower or lower than this after clipping to the image is dropped.
        prefix: starts every written file's name (one per flight when several share ``out_dir``).
        preview: also write the first ``preview`` imported frames with their boxes drawn to
            ``out_dir/preview/`` (PNG) (look at them: a wrong ``video_start`` shows as boxes beside the targets).
        jpeg_quality: of the written images.

    Raises:
        FootageError: an unreadable export, video or label line (the message names the file and line);
            other classes than an earlier import into ``out_dir``, or a file it would overwrite; frame
            indices that are not the video's; nothing left to import.
    """
    out = Path(out_dir)
    if not re.fullmatch(r"[A-Za-z0-9_.-]*", prefix):
        raise FootageError(f"prefix {prefix!r}: letters, digits, '_', '-' and '.' only")
    with ExportArchive(export) as archive:
        labels = read_export(archive)
        if video is not None and not labels.numbered:
            raise FootageError(f"{export}: its image names carry no distinct frame numbers (frame_000042...), "
                               f"so they cannot be matched to the frames of {video}")
        out_classes, cmap = _class_map(labels.classes, classes, rename or {})
        for part in ("train", "val"):
            have = out / part / "classes.txt"
            if have.exists() and tuple(x.strip() for x in have.read_text().splitlines() if x.strip()) != out_classes:
                raise FootageError(f"{have}: an earlier import has other classes than {list(out_classes)} (use a new folder)")
            for f in labels.frames:
                taken = out / part / "images" / f"{prefix}{f.frame:06d}.jpg"
                if taken.exists():
                    raise FootageError(f"{taken} exists: an earlier import wrote it (give this one another --prefix)")
        summary = ImportSummary(str(export), labels.format, out_classes, frames=len(labels.frames))
        train, val = chunk_split([f.frame for f in labels.frames], chunk, val_frac, seed)
        part_of = {i: "train" for i in train} | {i: "val" for i in val}
        source = VideoFrames(video, video_start, video_step) if video is not None else None  # a bad video: nothing written
        for part in ("train", "val"):
            (out / part / "images").mkdir(parents=True, exist_ok=True)
            (out / part / "labels").mkdir(parents=True, exist_ok=True)
            (out / part / "classes.txt").write_text("\n".join(out_classes) + "\n")
        dropped: Counter[str] = Counter()
        chunks: dict[str, set[int]] = {"train": set(), "val": set()}
        try:
            for i, frame in enumerate(labels.frames):
                img, why = _pixels(frame, archive, source)
                if img is None:
                    summary.skipped.append((frame.name, why))
                    continue
                h, w = img.shape[:2]
                if frame.size is not None and frame.size != (w, h):
                    summary.skipped.append((frame.name, f"image is {w} x {h}, the export says {frame.size[0]} x {frame.size[1]}"))
                    continue
                lines = []
                for c, x0, y0, x1, y1 in frame.pixel_boxes(w, h):
                    k = cmap[int(c)]
                    if k is None:
                        dropped[f"label {labels.classes[int(c)]!r} is not one of the classes"] += 1
                        continue
                    x0, x1 = np.clip([x0, x1], 0, w)
                    y0, y1 = np.clip([y0, y1], 0, h)
                    if x1 - x0 < min_box_px or y1 - y0 < min_box_px:
                        dropped[f"under {min_box_px:g} px once clipped to the image"] += 1
                        continue
                    lines.append(f"{k} {(x0 + x1) / 2 / w:.6f} {(y0 + y1) / 2 / h:.6f} {(x1 - x0) / w:.6f} {(y1 - y0) / h:.6f}")
                part = part_of[i]
                stem = f"{prefix}{frame.frame:06d}"
                if not cv2.imwrite(str(out / part / "images" / f"{stem}.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality]):
                    raise FootageError(f"{out / part / 'images' / stem}.jpg: could not be written")
                (out / part / "labels" / f"{stem}.txt").write_text("".join(x + "\n" for x in lines))
                if summary.imported < preview:
                    _write_preview(out / "preview" / f"{stem}.png", img, lines, out_classes)
                summary.imported += 1
                summary.boxes += len(lines)
                setattr(summary, part, getattr(summary, part) + 1)
                chunks[part].add(frame.frame // chunk)
        finally:
            if source is not None:
                source.close()
    summary.train_chunks, summary.val_chunks = len(chunks["train"]), len(chunks["val"])
    summary.dropped_boxes = dict(dropped)
    record = out / "import.json"
    earlier = json.loads(record.read_text()) if record.exists() else []
    record.write_text(json.dumps([*earlier, summary.to_dict()], indent=1) + "\n")
    for name, why in summary.skipped:
        log.warning("skipped %s: %s", name, why)
    if not summary.imported:
        reasons = Counter(r for _, r in summary.skipped).most_common(2)
        raise FootageError(f"{export}: no frame imported ({summary.frames} labelled, all skipped: {reasons})")
    log.info("imported %d of %d frames (%d boxes): train %d, val %d", summary.imported, summary.frames, summary.boxes,
             summary.train, summary.val)
    return summary
