"""Where the detector looks: a window around the expected target, at native or zoomed scale.

A small target loses most of its pixels when the whole frame is shrunk into the detector's square
input (an S1000 at 30 m is 14 px wide in a 640x480 frame and 9 px at 416). When the pipeline knows
where to look (the track it follows, or a cue from radar or telemetry projected into the image) it
runs the detector on a square window around that point instead, scaled so the expected box is
about ``box_px`` wide in the detector's input: more pixels on the target for the same detector
cost (region-of-interest detection, as in slicing-aided detectors for small objects). Boxes found
in the window map back to frame pixels with :meth:`FocusWindow.to_frame`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["FocusWindow", "focus_window"]


@dataclass(frozen=True)
class FocusWindow:
    """A square window of the frame, ``side_px`` frame pixels from (``x0``, ``y0``), shown to the
    detector at ``zoom`` (detector pixels per frame pixel)."""

    x0: int
    y0: int
    side_px: int
    zoom: float

    @property
    def region(self) -> tuple[int, int, int, int]:
        """The window in frame pixels: (x0, y0, x1, y1)."""
        return (self.x0, self.y0, self.x0 + self.side_px, self.y0 + self.side_px)

    def crop(self, image: np.ndarray) -> np.ndarray:
        """The window, resized to the detector's input (``side_px * zoom`` square)."""
        out = int(round(self.side_px * self.zoom))
        patch = image[self.y0:self.y0 + self.side_px, self.x0:self.x0 + self.side_px]
        if out == self.side_px:
            return np.ascontiguousarray(patch)
        return cv2.resize(patch, (out, out), interpolation=cv2.INTER_LINEAR)

    def to_frame(self, box: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        """A box in the resized window -> the same box in frame pixels."""
        z = self.zoom
        return (self.x0 + box[0] / z, self.y0 + box[1] / z, self.x0 + box[2] / z, self.y0 + box[3] / z)


def focus_window(centre_px: tuple[float, float], expected_box_px: float, frame_size: tuple[int, int], input_px: int = 416,
                 box_px: float = 32.0, min_zoom: float = 1.0, max_zoom: float = 3.0) -> FocusWindow | None:
    """The window around ``centre_px`` for a target expected ``expected_box_px`` wide, or None when
    the centre is off the frame.

    The zoom puts the expected box at ``box_px`` detector pixels, within [``min_zoom``, ``max_zoom``];
    the window (``input_px / zoom`` frame pixels square, never larger than the frame's short side)
    is shifted to lie inside the frame rather than cut by its edge.
    """
    if not min_zoom > 0 or max_zoom < min_zoom:
        raise ValueError(f"need 0 < min_zoom <= max_zoom, got {min_zoom}, {max_zoom}")
    w, h = frame_size
    cx, cy = centre_px
    if not (np.isfinite(cx) and np.isfinite(cy)) or not (0.0 <= cx < w and 0.0 <= cy < h):
        return None
    zoom = float(np.clip(box_px / max(expected_box_px, 1e-3), min_zoom, max_zoom))
    side = int(round(input_px / zoom))
    if side > min(w, h):
        side = int(min(w, h))
    zoom = input_px / side
    x0 = int(round(min(max(cx - side / 2, 0), w - side)))
    y0 = int(round(min(max(cy - side / 2, 0), h - side)))
    return FocusWindow(x0, y0, side, zoom)
