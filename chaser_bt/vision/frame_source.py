"""Where frames come from: the FrameSource protocol and its cv2.VideoCapture implementation.

A mission asks a source for the frame at mission time ``t``; a live or recorded camera returns its
next frame stamped with ``t``. A source that can read out regions of interest (the simulator's
renderer: drawing only what the pipeline will look at is most of a rehearsal's speed) says so with
``reads_regions`` and takes ``regions`` in :meth:`FrameSource.read`; the frame it returns is real
inside them (``Frame.regions``) and a flat fill elsewhere. The simulator's rendered camera (``sitl.world.camera.frame_source``)
implements the same protocol; a video file, a device index or any URL OpenCV opens (RTSP, HTTP,
GStreamer pipeline) go through :class:`VideoCaptureSource`.
"""

from __future__ import annotations

import logging
from collections import Counter
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import cv2
import numpy as np

__all__ = ["Frame", "FrameSource", "Region", "VideoCaptureSource", "reads_regions"]

log = logging.getLogger(__name__)

#: A rectangle of the frame, pixels: (x0, y0, x1, y1), x1 and y1 excluded.
Region = tuple[int, int, int, int]


@dataclass(frozen=True)
class Frame:
    """One BGR image (height x width x 3, uint8) taken at mission time ``t`` (s); ``regions``: the
    only parts that show the scene when the source was asked for regions of interest (None: all of it)."""

    t: float
    image: np.ndarray
    index: int
    regions: tuple[Region, ...] | None = None


@runtime_checkable
class FrameSource(Protocol):
    def read(self, t: float) -> Frame | None:
        """The frame for mission time ``t``, or None when the source has none (ended, dropped)."""
        ...

    def close(self) -> None: ...


def _frame_problem(image: np.ndarray, shape: tuple[int, ...] | None) -> str | None:
    """Why a captured image cannot be a camera frame: not_bgr8, empty, size_changed (None: it can)."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        return "not_bgr8"
    if image.shape[0] == 0 or image.shape[1] == 0:
        return "empty"
    if shape is not None and image.shape != shape:
        return "size_changed"
    return None


def reads_regions(source: object) -> bool:
    """Whether ``source.read`` takes ``regions=`` (a real camera reads whole frames; the renderer need not)."""
    return bool(getattr(source, "reads_regions", False))


class VideoCaptureSource:
    """Frames from ``cv2.VideoCapture(target)``: a file path, a device index or a stream URL.

    A frame is checked before it is believed: 8-bit, three channels (BGR), not empty, and the size
    of the first one (the camera model's intrinsics are for one size). Others are dropped and
    counted per reason in ``dropped``, and the first of each is logged.

    Args:
        target: path/URL string or integer device index.
        size: (width, height) to resize frames to, or None to keep them.
    """

    def __init__(self, target: str | int, size: tuple[int, int] | None = None) -> None:
        self.capture = cv2.VideoCapture(target)
        if not self.capture.isOpened():
            raise ValueError(f"cannot open video source {target!r}")
        self.size = size
        self._index = 0
        self._shape: tuple[int, ...] | None = None
        self.dropped: Counter[str] = Counter()

    def read(self, t: float) -> Frame | None:
        ok, image = self.capture.read()
        if not ok or image is None:
            return None
        why = _frame_problem(image, self._shape)
        if why is not None:
            self.dropped[why] += 1
            if self.dropped[why] == 1:
                log.warning("camera frame dropped (%s): shape %s, dtype %s", why, getattr(image, "shape", None),
                            getattr(image, "dtype", None))
            return None
        self._shape = image.shape
        if self.size is not None and (image.shape[1], image.shape[0]) != tuple(self.size):
            image = cv2.resize(image, tuple(self.size), interpolation=cv2.INTER_AREA)
        frame = Frame(t, image, self._index)
        self._index += 1
        return frame

    def close(self) -> None:
        self.capture.release()
