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
from chaser_bt.vision.footage.yolo_folder import box_line, draw_preview, prepare_parts, write_example

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
        summary = ImportSummary(str(export), labels.format, out_classes, frames=len(labels.frames))
        train, val = chunk_split([f.frame for f in labels.frames], chunk, val_frac, seed)
        part_of = {i: "train" for i in train} | {i: "val" for i in val}
        source = VideoFrames(video, video_start, video_step) if video is not None else None  # a bad video: nothing written
        dropped: Counter[str] = Counter()
        chunks: dict[str, set[int]] = {"train": set(), "val": set()}
        try:
            prepare_parts(out, ("train", "val"), out_classes, [f"{prefix}{f.frame:06d}" for f in labels.frames])
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
                    line = box_line(k, x0, y0, x1, y1, w, h, min_box_px)
                    if line is None:
                        dropped[f"under {min_box_px:g} px once clipped to the image"] += 1
                        continue
                    lines.append(line)
                part = part_of[i]
                stem = f"{prefix}{frame.frame:06d}"
                write_example(out / part, stem, img, lines, jpeg_quality)
                if summary.imported < preview:
                    draw_preview(out / "preview" / f"{stem}.png", img, lines, out_classes)
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
