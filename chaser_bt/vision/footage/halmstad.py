"""The Halmstad drone-detection dataset's visible-light videos into the project's YOLO folders.

The dataset (Svanström, Alonso-Fernandez, Englund, "A dataset for multi-sensor drone detection",
Data in Brief 2021; CC0; public repository ``DroneDetectionThesis/Drone-detection-dataset``) films
drones, birds, airplanes and helicopters from the ground at 640 x 512, 30 frames/s. Each video
``Data/Video_V/V_<KIND>_<NNN>.mp4`` has a MATLAB ``groundTruth`` label file ``V_<KIND>_<NNN>_LABELS.mat``
holding the boxes of each frame, read with the PyPI package ``mcos-decoder``.

The split is by video and fixed: the highest-numbered third of each kind (:data:`HELD_OUT`) is the
``test`` part, which nothing trains, tunes or calibrates on; of the rest, a seeded ``val_frac`` of
each kind's videos is ``val`` and the others ``train``. Every ``every``-th frame is written (the
frames between are near copies). Boxes of the kinds in ``classes`` are written; the other kinds'
frames are written without their box, as hard negatives (a bird is what a drone detector must not
call a drone). A video whose labels cannot be read, or whose label count is not its frame count, is
skipped, named and counted.
"""

from __future__ import annotations

import json
import logging
import re
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from chaser_bt.vision.footage.cvat import FootageError
from chaser_bt.vision.footage.video import VideoFrames
from chaser_bt.vision.footage.yolo_folder import box_line, draw_preview, prepare_parts, write_example

__all__ = ["HALMSTAD_KINDS", "HELD_OUT", "HalmstadSummary", "HalmstadVideo", "align_labels", "decode_workspace", "find_videos",
           "import_halmstad", "is_halmstad", "read_labels", "split_videos"]

log = logging.getLogger(__name__)

#: The dataset's target kinds, as class names, in the label table's order.
HALMSTAD_KINDS = ("airplane", "bird", "drone", "helicopter")
#: Per kind, the video numbers (inclusive) of the held-out test: the highest-numbered third.
HELD_OUT: dict[str, tuple[int, int]] = {"drone": (77, 114), "bird": (35, 51), "airplane": (40, 59), "helicopter": (41, 61)}
PARTS = ("train", "val", "test")
_NAME = re.compile(r"V_(DRONE|BIRD|AIRPLANE|HELICOPTER)_(\d+)")

Box = tuple[float, float, float, float]
FrameLabels = list[tuple[str, Box]]


@dataclass(frozen=True)
class HalmstadVideo:
    """One visible-light video: its kind (a :data:`HALMSTAD_KINDS` name), number and files."""

    name: str
    kind: str
    number: int
    video: Path
    labels: Path

    @property
    def held_out(self) -> bool:
        lo, hi = HELD_OUT[self.kind]
        return lo <= self.number <= hi


@dataclass
class HalmstadSummary:
    """What an import did: per part the videos, frames and boxes written; the videos skipped and why."""

    root: str
    classes: tuple[str, ...]
    every: int
    videos: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PARTS, 0))
    frames: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PARTS, 0))
    boxes: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PARTS, 0))
    negatives: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PARTS, 0))
    skipped: list[tuple[str, str]] = field(default_factory=list)
    dropped_boxes: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["skipped"] = [{"video": n, "reason": r} for n, r in self.skipped]
        return d


def is_halmstad(path: str | Path) -> bool:
    """The folder holds Halmstad label files (the dataset's root, ``Data/`` or ``Data/Video_V``)."""
    p = Path(path)
    return p.is_dir() and any(_video_folder(p).glob("V_*_LABELS.mat"))


def _video_folder(root: Path) -> Path:
    for sub in ("Data/Video_V", "Video_V"):
        if (root / sub).is_dir():
            return root / sub
    return root


def find_videos(root: str | Path) -> tuple[list[HalmstadVideo], list[tuple[str, str]]]:
    """The visible-light videos under ``root`` with a label file, in name order, and (name, why) of each
    label file whose video is missing."""
    folder = _video_folder(Path(root))
    found, missing = [], []
    for labels in sorted(folder.glob("V_*_LABELS.mat")):
        m = _NAME.fullmatch(labels.name[: -len("_LABELS.mat")])
        if m is None:
            continue
        name = m.group(0)
        video = folder / f"{name}.mp4"
        if not video.is_file():
            missing.append((name, f"video {video.name} is missing"))
            continue
        found.append(HalmstadVideo(name, m.group(1).lower(), int(m.group(2)), video, labels))
    if not found and not missing:
        raise FootageError(f"{root}: no Halmstad label files (V_<KIND>_<NNN>_LABELS.mat) in {folder}")
    return found, missing


def read_labels(path: Path) -> list[FrameLabels]:
    """Per video frame, the (kind, (x, y, w, h)) pixel boxes of a MATLAB ``groundTruth`` label file."""
    import scipy.io

    try:
        workspace = scipy.io.loadmat(str(path)).get("__function_workspace__")
    except Exception as exc:  # noqa: BLE001 - scipy raises whatever its parse meets
        raise FootageError(f"{path}: not a MATLAB label file ({type(exc).__name__}: {exc})") from None
    if workspace is None:
        raise FootageError(f"{path}: not a MATLAB groundTruth label file (it holds no MATLAB object)")
    try:
        return decode_workspace(workspace.tobytes())
    except ValueError as exc:
        raise FootageError(f"{path}: {exc}") from None


def decode_workspace(workspace: bytes) -> list[FrameLabels]:
    """Per frame, the (kind, (x, y, w, h)) boxes in a ``groundTruth``'s ``__function_workspace__`` bytes.

    The bytes are walked with ``mcos-decoder``'s MAT stream. The label table holds, frame after frame,
    one cell per kind in :data:`HALMSTAD_KINDS` order (the labels' alphabetical order): an N x 4 double
    matrix, column-major (x's, y's, widths, heights), N = 0 when that kind is absent. It is read whole
    here: ``mcos-decoder``'s own ``load_groundtruth`` takes only one-box cells, reading a frame with two
    boxes as an empty one.

    Raises:
        ValueError: the cells are not a whole number of frames.
    """
    from mcos_decoder import MatStream  # pure Python; only the importer needs it

    cells: list[np.ndarray] = []
    for top in MatStream(workspace, skip_header=8).walk():
        _table_cells(top, 0, cells)
    per_frame = len(HALMSTAD_KINDS)
    if not cells or len(cells) % per_frame:
        raise ValueError(f"{len(cells)} label cells, not {per_frame} a frame (not a Halmstad label table)")
    frames = []
    for f in range(len(cells) // per_frame):
        boxes: FrameLabels = []
        for kind, cell in zip(HALMSTAD_KINDS, cells[f * per_frame:(f + 1) * per_frame]):
            boxes += [(kind, tuple(float(v) for v in row)) for row in cell.reshape(4, -1).T]
        frames.append(boxes)
    return frames


_FRAME_DEPTH = 5  # where the label table's cells sit in the workspace (mcos-decoder's frame_depth)


def _table_cells(element, depth: int, out: list[np.ndarray]) -> None:
    """Append the doubles of each label-table cell under ``element``: a cell (MAT type 14) at the table's
    depth holding a double array (type 9) whose length is a multiple of 4 (other cells there are metadata)."""
    if element.type_id == 14 and depth == _FRAME_DEPTH:
        for child in element.children:
            if child.type_id == 9:
                values = child.as_array()
                if len(values) % 4 == 0:
                    out.append(values)
                return
        return
    for child in element.children:
        _table_cells(child, depth + 1, out)


def align_labels(frames: Sequence[FrameLabels], count: int, where: str) -> list[FrameLabels]:
    """The labels, checked to be one a video frame (``count``)."""
    if len(frames) != count:
        raise FootageError(f"{where}: labels for {len(frames)} frames, the video has {count}")
    return list(frames)


def split_videos(videos: Sequence[HalmstadVideo], val_frac: float, seed: int) -> dict[str, str]:
    """Video name -> part: the fixed held-out third is ``test``; of each kind's other videos a seeded
    ``val_frac`` (at least one when there are two or more) is ``val``, the rest ``train``."""
    if not 0.0 <= val_frac < 1.0:
        raise FootageError(f"val_frac must be in [0, 1), got {val_frac}")
    rng = np.random.default_rng(seed)
    part = {v.name: "test" for v in videos if v.held_out}
    for kind in HALMSTAD_KINDS:
        pool = sorted(v.name for v in videos if v.kind == kind and not v.held_out)
        n_val = min(max(round(val_frac * len(pool)), 1), len(pool) - 1) if val_frac > 0 and len(pool) >= 2 else 0
        held = set(rng.permutation(pool)[:n_val].tolist()) if pool else set()
        part.update({n: "val" if n in held else "train" for n in pool})
    return part


def _class_ids(classes: Sequence[str], rename: Mapping[str, str]) -> dict[str, int | None]:
    """Kind -> output class id (None: written as a hard negative)."""
    unknown = sorted(set(rename) - set(HALMSTAD_KINDS))
    if unknown:
        raise FootageError(f"rename: {unknown} are not Halmstad kinds {list(HALMSTAD_KINDS)}")
    if len(set(classes)) != len(classes):
        raise FootageError(f"classes: {list(classes)} names a class twice")
    out = {}
    for kind in HALMSTAD_KINDS:
        name = rename.get(kind, kind)
        out[kind] = classes.index(name) if name in classes else None
    if all(v is None for v in out.values()):
        raise FootageError(f"classes {list(classes)}: none is a Halmstad kind {list(HALMSTAD_KINDS)} (after --rename)")
    return out


def import_halmstad(root: str | Path, out_dir: str | Path, classes: Sequence[str] = ("drone",),
                    rename: Mapping[str, str] | None = None, every: int = 10, val_frac: float = 0.2, seed: int = 0,
                    parts: Sequence[str] = PARTS, min_box_px: float = 1.0, preview: int = 0, jpeg_quality: int = 95,
                    labels_reader: Callable[[Path], list[FrameLabels]] | None = None,
                    progress: Callable[[int, int, str], None] | None = None) -> HalmstadSummary:
    """Write ``out_dir/train``, ``val`` and ``test`` (see module docstring).

    Args:
        root: the dataset's root (or its ``Data/`` or ``Data/Video_V`` folder).
        out_dir: where the YOLO folders go (a new folder, or one an import with the same classes wrote).
        classes: output class names in id order; a kind (after ``rename``) not among them is a hard negative.
        rename: kind -> class name (``{"drone": "phantom"}`` to fine-tune the shipped two-class weights).
        every: write every ``every``-th frame of each video (frame 0, every, 2 every, ...).
        val_frac, seed: the share of each kind's non-held-out videos kept for validation, and which.
        parts: which parts to write (``("test",)``: only the held-out test).
        min_box_px: a box narrower or lower than this after clipping to the image is dropped (counted).
        preview: also draw the first ``preview`` written frames of each part to ``out_dir/preview/``.
        labels_reader: label file -> per-frame boxes (default :func:`read_labels`).
        progress: called ``(videos done, videos, name)`` after each video.

    Raises:
        FootageError: no label files under ``root``, bad ``classes``/``rename``/``parts``, another
            import's classes in ``out_dir``, or nothing imported at all.
    """
    if every < 1:
        raise FootageError(f"every must be >= 1, got {every}")
    bad_parts = sorted(set(parts) - set(PARTS))
    if bad_parts or not parts:
        raise FootageError(f"parts: {bad_parts or 'none'} (expected some of {list(PARTS)})")
    out = Path(out_dir)
    classes = tuple(classes)
    ids = _class_ids(classes, rename or {})
    videos, missing = find_videos(root)
    part_of = split_videos(videos, val_frac, seed)
    chosen = [v for v in videos if part_of[v.name] in parts]
    prepare_parts(out, parts, classes, [f"{v.name}_{0:06d}" for v in chosen])
    labels_reader = labels_reader or read_labels
    summary = HalmstadSummary(str(root), classes, every, skipped=list(missing))
    dropped: Counter[str] = Counter()
    previews: Counter[str] = Counter()
    for n, v in enumerate(chosen, 1):
        part = part_of[v.name]
        try:
            for stem, image, lines in _video_examples(v, out / part, ids, every, min_box_px, jpeg_quality, labels_reader, dropped):
                summary.frames[part] += 1
                summary.boxes[part] += len(lines)
                summary.negatives[part] += not lines
                if previews[part] < preview:
                    previews[part] += 1
                    draw_preview(out / "preview" / part / f"{stem}.png", image, lines, classes)
        except FootageError as exc:
            summary.skipped.append((v.name, str(exc)))
            log.warning("skipped %s: %s", v.name, exc)
        else:
            summary.videos[part] += 1
        if progress is not None:
            progress(n, len(chosen), v.name)
    summary.dropped_boxes = dict(dropped)
    record = out / "import.json"
    earlier = json.loads(record.read_text()) if record.exists() else []
    record.write_text(json.dumps([*earlier, summary.to_dict()], indent=1) + "\n")
    if not sum(summary.frames.values()):
        raise FootageError(f"{root}: no frame imported ({len(summary.skipped)} videos skipped: "
                           f"{Counter(r.split(':')[-1].strip() for _, r in summary.skipped).most_common(2)})")
    log.info("imported %s frames (%s boxes) from %s videos; %d skipped", summary.frames, summary.boxes, summary.videos,
             len(summary.skipped))
    return summary


def _video_examples(v: HalmstadVideo, part_dir: Path, ids: Mapping[str, int | None], every: int, min_box_px: float,
                    jpeg_quality: int, labels_reader: Callable[[Path], list[FrameLabels]],
                    dropped: Counter[str]) -> Iterator[tuple[str, np.ndarray, list[str]]]:
    """Write one video's chosen frames, yielding (stem, image, lines) of each as it is written. The labels
    are checked against the video before anything is written."""
    per_frame = labels_reader(v.labels)
    with VideoFrames(v.video) as frames:
        count = frames.declared_frames or _count_frames(v.video)
        labels = align_labels(per_frame, count, v.labels.name)
        for i in range(0, count, every):
            image = frames.frame(i)
            if image is None:
                raise FootageError(f"{v.video.name}: frame {i} of {count} could not be decoded")
            h, w = image.shape[:2]
            lines = []
            for kind, box in labels[i]:
                x, y, bw, bh = box
                k = ids[kind]
                if not np.isfinite(box).all():
                    dropped["not a finite box"] += 1
                elif k is None:
                    dropped[f"{kind}: a hard negative (not one of the classes)"] += 1
                else:
                    line = box_line(k, x, y, x + bw, y + bh, w, h, min_box_px)
                    if line is None:
                        dropped[f"under {min_box_px:g} px once clipped to the image"] += 1
                    else:
                        lines.append(line)
            stem = f"{v.name}_{i:06d}"
            write_example(part_dir, stem, image, lines, jpeg_quality)
            yield stem, image, lines


def _count_frames(path: Path) -> int:
    """Frames of a video whose container does not say, by decoding it."""
    capture = cv2.VideoCapture(str(path))
    count = 0
    while capture.grab():
        count += 1
    capture.release()
    return count
