"""Frames of a recorded video by index, through ``cv2.VideoCapture`` (CVAT video tasks: the export
labels ``frame_000000`` ... and may leave the pixels in the video).

Frames are read forwards (seeking is not frame-exact for every codec); asking for an earlier frame
reopens the file. A task made with a start frame or a frame step maps export frame k to video
frame ``start + k * step``.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from chaser_bt.vision.footage.cvat import FootageError

__all__ = ["VideoFrames"]


class VideoFrames:
    """Random access (forwards is cheap) to the BGR frames of ``path``.

    Args:
        path: a video file OpenCV can decode.
        start: the video frame the export's frame 0 is.
        step: video frames between the export's consecutive frames.

    Raises:
        FootageError: the file is missing, does not open as a video, or yields no frame.
    """

    def __init__(self, path: str | Path, start: int = 0, step: int = 1) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise FootageError(f"video not found: {self.path}")
        if start < 0 or step < 1:
            raise FootageError(f"{self.path}: start must be >= 0 and step >= 1, got {start}, {step}")
        self.start, self.step = start, step
        self._open()
        first = self._next()
        if first is None:
            self.close()
            raise FootageError(f"{self.path}: no frame could be decoded (corrupt or not a video)")
        self.size = (first.shape[1], first.shape[0])
        self._last: tuple[int, np.ndarray] = (0, first)
        #: Frames the container declares (0 when it does not say); the true end is where decoding stops.
        self.declared_frames = max(int(self._capture.get(cv2.CAP_PROP_FRAME_COUNT)), 0)

    def _open(self) -> None:
        self._capture = cv2.VideoCapture(str(self.path))
        if not self._capture.isOpened():
            raise FootageError(f"{self.path}: cannot open as a video")
        self._pos = 0  # index of the frame the next read returns

    def _next(self) -> np.ndarray | None:
        ok, image = self._capture.read()
        if not ok or image is None:
            return None
        self._pos += 1
        return image

    def frame(self, index: int) -> np.ndarray | None:
        """The export's frame ``index`` (video frame ``start + index * step``), or None past the video's end."""
        v = self.start + index * self.step
        if v == self._last[0]:
            return self._last[1]
        if v < self._pos:
            self._capture.release()
            self._open()
        while self._pos < v:
            if not self._capture.grab():
                return None
            self._pos += 1
        image = self._next()
        if image is not None:
            self._last = (v, image)
        return image

    def close(self) -> None:
        self._capture.release()

    def __enter__(self) -> "VideoFrames":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
