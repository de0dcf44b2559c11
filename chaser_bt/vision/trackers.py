"""Visual trackers between detector frames (paper section 3.1, "Visual Tracking").

The detector is too slow to run on every frame, so each detection seeds an OpenCV tracker that
follows the box on the frames in between. Trackers cannot detect, so on every detector frame
they are checked against the detections: a track that overlaps a detection of a similar size is
reseeded on it, a track that overlaps none is pruned (the paper's tracker drifting onto a bush),
and a detection that no track overlaps starts a new track. With ``max_misses`` > 0 a confirmed
track (two or more detector hits) may instead coast on its trackers through that many detector
frames in a row that miss it, unless the detector contradicts it (sees something at least as
confident elsewhere); a detection much larger than a track it covers (the detector boxing the
target together with the road under it) neither reseeds it nor starts a track. A small box moves
more than its own width between frames, so a detection also agrees with a track when its centre is
within ``match_centre_sizes`` of the track's box size. Only tracks the detector could have seen are
judged: a track outside the detector's ``region`` (a focus window), or any track when the detector
looked at the whole frame at a coarser scale (``judge=False``), is carried unchanged. A detector
whose score is its box's IoU can say a box is badly placed: below ``reseed_min_score`` a matching
detection confirms a followed track but leaves it on its trackers. ``refine`` (the detector's box
refiner) re-places every box the trackers moved.

Trackers in the installed OpenCV (opencv-contrib 5.0): cv2.TrackerKCF, TrackerCSRT, TrackerMIL
(and the learned DaSiamRPN / Nano / Vit, which need model files we do not ship); cv2.legacy adds
MOSSE, MedianFlow, Boosting and TLD. :data:`TRACKER_KINDS` lists the ones usable here.

Small boxes give correlation trackers too little texture, so a tracker works on a window at least
``min_window_px`` wide around the box and reports the box with the detection's size at the
tracked centre.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Callable, Sequence

import cv2
import numpy as np

from chaser_bt.vision.detection import Detection
from chaser_bt.vision.detector.evaluate import iou_matrix

__all__ = ["TRACKER_KINDS", "make_tracker", "Track", "TrackerBank"]

log = logging.getLogger(__name__)

TRACKER_KINDS: dict[str, Callable[[], object]] = {
    "kcf": cv2.TrackerKCF_create,
    "csrt": cv2.TrackerCSRT_create,
    "mil": cv2.TrackerMIL_create,
    "mosse": cv2.legacy.TrackerMOSSE_create,
    "medianflow": cv2.legacy.TrackerMedianFlow_create,
}


def make_tracker(kind: str):
    """A fresh OpenCV tracker of ``kind`` (one of :data:`TRACKER_KINDS`)."""
    try:
        return TRACKER_KINDS[kind]()
    except KeyError:
        raise ValueError(f"unknown tracker {kind!r}; available: {sorted(TRACKER_KINDS)}") from None


@dataclass
class Track:
    """One target followed in the image."""

    track_id: int
    box: tuple[float, float, float, float]
    class_name: str
    score: float
    t_detected: float
    t: float
    size: tuple[float, float]
    hits: int = 1
    trackers: list = field(default_factory=list)
    misses: int = 0  # detector frames in a row without a matching detection
    seed: tuple[np.ndarray, tuple[int, int, int, int]] | None = None  # frame and window the trackers start on, until they do

    @property
    def centre(self) -> tuple[float, float]:
        return (0.5 * (self.box[0] + self.box[2]), 0.5 * (self.box[1] + self.box[3]))

    @property
    def label(self) -> str:
        """What a person sees written by the box: the class and the last detection's score."""
        return f"{self.class_name} {self.score:.2f}"


def _window(box, min_px: float, w: int, h: int) -> tuple[int, int, int, int]:
    cx, cy = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
    bw, bh = max(box[2] - box[0], min_px), max(box[3] - box[1], min_px)
    x0 = int(round(min(max(cx - bw / 2, 0), w - bw)))
    y0 = int(round(min(max(cy - bh / 2, 0), h - bh)))
    return (x0, y0, int(round(bw)), int(round(bh)))


def _inside(point: tuple[float, float], region: tuple[float, float, float, float] | None) -> bool:
    return region is None or (region[0] <= point[0] <= region[2] and region[1] <= point[1] <= region[3])


class TrackerBank:
    """Zero or more trackers per track, reseeded and pruned by detections (see module docstring).

    Args:
        kinds: tracker kinds run on every track ([] = detections only, boxes held between them).
        match_iou: overlap for a track and a detection to agree.
        min_window_px: smallest tracker window.
        max_tracks: most tracks kept (the highest scores).
        max_misses: detector frames in a row a confirmed track may coast without a detection (0: prune at once).
        max_size_ratio: largest ratio of the square roots of a detection's and a track's areas for them to agree.
        match_centre_sizes: a detection whose centre is within this many track box sizes (the larger side)
            of the track's centre agrees with it even without overlap.
        reseed_min_score: a detection scoring less confirms a confirmed track (a hit) without moving its
            box or reseeding its trackers: a detector whose score is the predicted box's IoU (trained with
            ``obj_iou``) says by a low score that the box is badly placed (0: always reseed).
        refine: re-places boxes the trackers moved (frame, (N, 4) boxes) -> (N, 4) boxes, e.g. the
            detector's :class:`chaser_bt.vision.detector.refine.BoxRefiner`; trackers keep the detection's size
            and drift by a pixel or two a frame. None: the trackers' boxes as they are.
    """

    def __init__(self, kinds: Sequence[str] = ("mosse", "medianflow"), match_iou: float = 0.2, min_window_px: float = 32.0, max_tracks: int = 5,
                 max_misses: int = 0, max_size_ratio: float = 1.8, match_centre_sizes: float = 1.0,
                 reseed_min_score: float = 0.0, refine: Callable[[np.ndarray, list], np.ndarray] | None = None) -> None:
        for k in kinds:
            make_tracker(k)
        self.kinds = tuple(kinds)
        self.max_misses = max_misses
        self.max_size_ratio = max_size_ratio
        self.match_iou = match_iou
        self.match_centre_sizes = match_centre_sizes
        self.reseed_min_score = reseed_min_score
        self.refine = refine
        self.min_window_px = min_window_px
        self.max_tracks = max_tracks
        self.tracks: list[Track] = []
        self._next_id = 1
        self.pruned = 0

    def _seed(self, frame: np.ndarray, track: Track) -> None:
        """Seed ``track``'s trackers on ``frame``: started when first needed (:meth:`_started`), since
        most seeds are replaced by the next detection before a tracker ever moves the box."""
        h, w = frame.shape[:2]
        track.trackers = []
        track.seed = (frame, _window(track.box, self.min_window_px, w, h)) if self.kinds else None

    def _started(self, track: Track) -> list:
        """``track``'s trackers, started now on the frame and window of its seed if they were not yet."""
        if track.seed is not None:
            frame, win = track.seed
            track.seed = None
            for k in self.kinds:
                tr = make_tracker(k)
                try:
                    tr.init(frame, win)
                    track.trackers.append(tr)
                except cv2.error as e:
                    log.debug("tracker %s failed to start: %s", k, e)
        return track.trackers

    def correct(self, frame: np.ndarray, detections: Sequence[Detection], t: float,
                region: tuple[float, float, float, float] | None = None, judge: bool = True) -> list[Track]:
        """A detector frame: reseed agreeing tracks, prune the rest, start tracks on new detections.

        ``region`` (x0, y0, x1, y1) is the part of the frame the detector saw (None: all of it);
        with ``judge`` False no track is pruned for want of a detection."""
        kept: list[Track] = []
        used = set()
        agree = np.zeros((len(self.tracks), len(detections)), bool)
        covers = np.zeros((len(self.tracks), len(detections)), bool)
        ious = np.zeros((len(self.tracks), len(detections)))
        dist = np.zeros((len(self.tracks), len(detections)))
        if self.tracks and detections:
            tb = np.array([tr.box for tr in self.tracks], float)
            db = np.array([d.box for d in detections], float)
            ious = iou_matrix(tb, db)
            ta = np.prod(np.clip(tb[:, 2:] - tb[:, :2], 1e-6, None), axis=1)
            da = np.prod(np.clip(db[:, 2:] - db[:, :2], 1e-6, None), axis=1)
            ratio = np.sqrt(da[None, :] / ta[:, None])
            tc, dc = 0.5 * (tb[:, :2] + tb[:, 2:]), 0.5 * (db[:, :2] + db[:, 2:])
            dist = np.linalg.norm(tc[:, None] - dc[None], axis=2)
            near = dist <= self.match_centre_sizes * np.max(tb[:, 2:] - tb[:, :2], axis=1)[:, None]
            agree = ((ious >= self.match_iou) | near) & (ratio <= self.max_size_ratio) & (ratio >= 1.0 / self.max_size_ratio)
            inter = np.prod(np.clip(np.minimum(tb[:, None, 2:], db[None, :, 2:]) - np.maximum(tb[:, None, :2], db[None, :, :2]), 0, None), axis=2)
            covers = (inter >= 0.6 * ta[:, None]) & (ratio > self.max_size_ratio)
        for i, track in enumerate(self.tracks):
            order = sorted((j for j in range(len(detections)) if j not in used and agree[i, j]), key=lambda j: (-ious[i, j], dist[i, j]))
            if not order and not (judge and _inside(track.centre, region)):
                kept.append(track)  # the detector could not have seen it: no evidence either way
                continue
            if not order:
                # The detector contradicts the track when it is at least as sure of something else.
                contradicted = any(d.score >= track.score for j, d in enumerate(detections) if not covers[i, j])
                if track.hits >= 2 and track.misses < self.max_misses and not contradicted and self._started(track):
                    track.misses += 1
                    kept.append(track)
                else:
                    self.pruned += 1
                continue
            j = int(order[0])
            used.add(j)
            d = detections[j]
            track.class_name, track.score, track.t_detected, track.t = d.class_name, d.score, t, t
            track.misses = 0
            if d.score >= self.reseed_min_score or track.hits < 2 or not self._move(frame, track, t):
                track.box = d.box
                track.size = (d.box[2] - d.box[0], d.box[3] - d.box[1])
                self._seed(frame, track)
            track.hits += 1
            kept.append(track)
        kept_ids = {id(tr) for tr in kept}
        for j, d in enumerate(detections):
            if j in used or any(covers[i, j] and id(tr) in kept_ids for i, tr in enumerate(self.tracks)):
                continue
            track = Track(self._next_id, d.box, d.class_name, d.score, t, t, (d.box[2] - d.box[0], d.box[3] - d.box[1]))
            self._next_id += 1
            self._seed(frame, track)
            kept.append(track)
        self.tracks = sorted(kept, key=lambda tr: -tr.score)[: self.max_tracks]
        return self.tracks

    def advance(self, frame: np.ndarray, t: float) -> list[Track]:
        """A frame between detections: move each track by its trackers (mean centre); drop tracks all trackers lost."""
        alive = []
        for track in self.tracks:
            if not self.kinds or self._move(frame, track, t):
                alive.append(track)
            else:
                self.pruned += 1
        self.tracks = alive
        return self.tracks

    def _move(self, frame: np.ndarray, track: Track, t: float) -> bool:
        """Move ``track`` to its trackers' mean centre in ``frame``; False when every tracker lost it."""
        centres = []
        for tr in self._started(track):
            ok, (x, y, bw, bh) = tr.update(frame)
            if ok:
                centres.append((x + bw / 2, y + bh / 2))
        if not centres:
            return False
        cx, cy = np.mean(centres, axis=0)
        sw, sh = track.size
        track.box = (float(cx - sw / 2), float(cy - sh / 2), float(cx + sw / 2), float(cy + sh / 2))
        if self.refine is not None:
            track.box = tuple(float(v) for v in self.refine(frame, [track.box])[0])
        track.t = t
        return True
