"""A rehearsal as a short animated picture: the camera's frames with the detector's box, beside the overhead track.

Two halves:

- :class:`FrameKeeper` runs inside a rehearsal (:class:`sitl.bench.scoring.RehearsalObserver` offers
  it every camera frame): it keeps a frame every ``every_s`` seconds, downsampled to ``width_px`` and
  JPEG-encoded, with the pipeline's track box, the target's true box and a full-resolution crop
  around the target. Before the first acquisition it holds only the last ``before_s + after_s``
  seconds; at the acquisition it keeps the ``before_s`` seconds before and ``after_s`` after, then
  stops. So a flight never holds more than about ``(before_s + after_s) / every_s`` small frames
  (75 of about 10-20 kB by default), whatever its length; a flight that never acquires keeps its
  last ``before_s + after_s`` seconds. The kept frames travel in the trace
  (:attr:`~chaser_bt.log.trace.FlightTrace.frames`, saved in ``trace.npz``).
- :func:`write_animation` draws them as a GIF (Pillow): per frame the camera image with the boxes,
  the crop around the target, and the overhead track with the ownship and the target at that time,
  at ``fps`` frames per second (5 by default: real time at the default ``every_s``).

``chaser-bt rehearse --report DIR`` writes ``DIR/rehearsal.gif`` (:mod:`sitl.bench.report`).
Only :func:`write_animation` needs matplotlib and Pillow; the keeper needs OpenCV, which a
rehearsal's camera has already loaded.
"""

from __future__ import annotations

import math
from collections import deque
from pathlib import Path
from typing import Sequence

import numpy as np

from chaser_bt.log.trace import CameraSnapshot, FlightTrace

__all__ = ["FrameKeeper", "snapshot", "write_animation", "ANIMATION_DPI"]

Box = tuple[float, float, float, float]

#: Dots per inch of the animation's frames (its figure is 9 x 3.3 inches: 720 x 264 pixels).
ANIMATION_DPI = 80


def snapshot(t: float, image: np.ndarray, track_box: Sequence[float] | None = None,
             truth_box: Sequence[float] | None = None, width_px: int = 320, zoom_max_px: int = 160,
             quality: int = 80) -> CameraSnapshot:
    """One kept frame: ``image`` (BGR, uint8) at most ``width_px`` wide, its boxes scaled to it, and a
    crop of the full-resolution image around the target (the true box, else the track's; at most
    ``zoom_max_px`` on a side, at least 32 px, about three times the box)."""
    import cv2

    h, w = image.shape[:2]
    scale = min(1.0, width_px / float(w))
    small = image if scale >= 1.0 else cv2.resize(image, (max(1, round(w * scale)), max(1, round(h * scale))),
                                                   interpolation=cv2.INTER_AREA)
    jpeg = _encode(small, quality)
    around = truth_box if truth_box is not None else track_box
    zoom_jpeg = zoom_box = None
    if around is not None:
        cx, cy = 0.5 * (around[0] + around[2]), 0.5 * (around[1] + around[3])
        side = float(np.clip(3.0 * max(around[2] - around[0], around[3] - around[1]), 32.0, zoom_max_px))
        x0, y0 = int(np.clip(round(cx - side / 2), 0, max(w - 1, 0))), int(np.clip(round(cy - side / 2), 0, max(h - 1, 0)))
        x1, y1 = int(np.clip(round(cx + side / 2), x0 + 1, w)), int(np.clip(round(cy + side / 2), y0 + 1, h))
        zoom_jpeg = _encode(image[y0:y1, x0:x1], quality)
        zoom_box = (x0 * scale, y0 * scale, x1 * scale, y1 * scale)

    def scaled(box):
        return None if box is None else tuple(float(v) * scale for v in box)

    return CameraSnapshot(float(t), jpeg, scaled(track_box), scaled(truth_box), zoom_jpeg, zoom_box, scale)


def _encode(image: np.ndarray, quality: int) -> np.ndarray:
    import cv2

    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(image), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError("could not encode a camera frame as JPEG")
    return buf.reshape(-1).astype(np.uint8)


class FrameKeeper:
    """Keeps a bounded window of camera frames around the first acquisition (see the module docstring).

    Args:
        every_s: keep a frame at most this often (mission time).
        before_s, after_s: the window about the first acquisition.
        width_px: the kept frames' width (the camera's when smaller).
    """

    def __init__(self, every_s: float = 0.2, before_s: float = 5.0, after_s: float = 10.0, width_px: int = 320) -> None:
        self.every_s, self.before_s, self.after_s, self.width_px = every_s, before_s, after_s, width_px
        self.t_acquired: float | None = None
        self.done = False
        self._kept: deque[CameraSnapshot] = deque()
        self._t_last = -math.inf

    def offer(self, t: float, image: np.ndarray, track_box: Sequence[float] | None = None,
              truth_box: Sequence[float] | None = None, acquired: bool = False) -> bool:
        """A camera frame at mission time ``t``; ``acquired``: the mission's estimate matched the target
        at this tick. Returns whether the frame was kept."""
        if self.done:
            return False
        first = acquired and self.t_acquired is None
        if first:
            self.t_acquired = t
            while self._kept and self._kept[0].t < t - self.before_s:
                self._kept.popleft()
        if self.t_acquired is not None and t > self.t_acquired + self.after_s:
            self.done = True
            return False
        if not first and t - self._t_last < self.every_s - 1e-6:
            return False
        self._kept.append(snapshot(t, image, track_box, truth_box, width_px=self.width_px))
        self._t_last = t
        if self.t_acquired is None:
            while self._kept and self._kept[0].t < t - (self.before_s + self.after_s):
                self._kept.popleft()
        return True

    def snapshots(self) -> list[CameraSnapshot]:
        return list(self._kept)


# --- drawing ------------------------------------------------------------------------------------


def _rgb(bgr: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(bgr[..., ::-1])


def _set_rect(rect, box: Box | None, dx: float = 0.0, dy: float = 0.0, kx: float = 1.0, ky: float = 1.0) -> None:
    if box is None:
        rect.set_visible(False)
        return
    rect.set_visible(True)
    rect.set_xy(((box[0] - dx) * kx, (box[1] - dy) * ky))
    rect.set_width((box[2] - box[0]) * kx)
    rect.set_height((box[3] - box[1]) * ky)


def animation_figure(trace: FlightTrace, title: str = ""):
    """The animation's figure and a function ``draw(i)`` that shows kept frame ``i`` (for tests and
    :func:`write_animation`; ``draw.animated`` lists the artists that change from frame to frame).
    Axes: ``camera``, ``zoom``, ``overhead`` (their labels)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from chaser_bt.log.figures import phase_colour, phase_name

    frames = trace.frames
    if not frames:
        raise ValueError("the trace kept no camera frames: nothing to animate")
    first = frames[0].image_bgr()
    h, w = first.shape[:2]
    fig = plt.figure(figsize=(9.0, 3.3), dpi=ANIMATION_DPI)
    # Fixed positions (figure fractions), the same for every frame: camera 4:3, zoom and overhead square.
    ax_cam = fig.add_axes((0.01, 0.24, 0.4, 0.62), label="camera")
    ax_zoom = fig.add_axes((0.425, 0.3, 0.17, 0.5), label="zoom")
    ax_top = fig.add_axes((0.69, 0.3, 0.3, 0.56), label="overhead")
    for ax in (ax_cam, ax_zoom):
        ax.set_xticks([])
        ax.set_yticks([])
    img = ax_cam.imshow(_rgb(first), extent=(0, w, h, 0), interpolation="nearest")
    ax_cam.set_xlim(0, w)
    ax_cam.set_ylim(h, 0)
    ax_cam.set_title(f"camera ({w} px wide of {round(w / frames[0].scale)}); flat colour: not read out", fontsize=8)
    track_rect = ax_cam.add_patch(Rectangle((0, 0), 1, 1, fill=False, ec="yellow", lw=1.5, label="detector's box"))
    truth_rect = ax_cam.add_patch(Rectangle((0, 0), 1, 1, fill=False, ec="lime", lw=1.0, ls="--", label="true box"))
    zoom_rect = ax_cam.add_patch(Rectangle((0, 0), 1, 1, fill=False, ec="deepskyblue", lw=0.9, ls=":", label="zoomed area"))
    zoom_img = ax_zoom.imshow(np.zeros((2, 2, 3), np.uint8), extent=(0, 1, 1, 0), interpolation="nearest")
    ax_zoom.set_xlim(0, 1)
    ax_zoom.set_ylim(1, 0)
    zoom_track = ax_zoom.add_patch(Rectangle((0, 0), 1, 1, fill=False, ec="yellow", lw=1.5))
    zoom_truth = ax_zoom.add_patch(Rectangle((0, 0), 1, 1, fill=False, ec="lime", lw=1.0, ls="--"))
    zoom_text = ax_zoom.text(0.5, 0.5, "no box:\ntarget not in view", ha="center", va="center", fontsize=8,
                             transform=ax_zoom.transAxes)
    ax_zoom.set_title("around the target,\nfull resolution", fontsize=8)
    fig.legend(handles=[track_rect, truth_rect, zoom_rect], loc="lower left", bbox_to_anchor=(0.01, 0.0), ncol=3,
               fontsize=7, title="boxes", title_fontsize=7, facecolor="0.9", frameon=True)

    # Overhead: the whole flight faint, the animated window in its phase colours, positions now.
    own, target = trace.ownship_enu, trace.target_enu
    t0, t1 = frames[0].t, frames[-1].t
    window = (trace.t >= t0 - 1e-9) & (trace.t <= t1 + 1e-9)
    top_handles = ax_top.plot(own[:, 0], own[:, 1], color="0.7", lw=0.8, label="whole flight")
    points = [own[window, :2]]
    if np.isfinite(target[window, :2]).any():
        tw = target[window, :2]
        top_handles += ax_top.plot(tw[:, 0], tw[:, 1], color="tab:red", ls="--", lw=0.8, alpha=0.6, label="target (X: now)")
        points.append(tw[np.isfinite(tw).all(axis=1)])
    trail, = ax_top.plot([], [], color="tab:blue", lw=1.8, label="ownship, phase colour")
    top_handles.append(trail)
    own_now, = ax_top.plot([], [], "^", color="tab:blue", ms=7, mec="black", mew=0.5)
    target_now, = ax_top.plot([], [], "X", color="tab:red", ms=7, mec="black", mew=0.5)
    pts = np.concatenate(points) if points else np.zeros((0, 2))
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts):
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre, half = 0.5 * (lo + hi), 0.5 * max(float((hi - lo).max()), 20.0) * 1.15
        ax_top.set_xlim(centre[0] - half, centre[0] + half)
        ax_top.set_ylim(centre[1] - half, centre[1] + half)
    ax_top.set_aspect("equal", adjustable="box")
    ax_top.set_xlabel("east (m)", fontsize=8)
    ax_top.set_ylabel("north (m)", fontsize=8)
    ax_top.tick_params(labelsize=7)
    ax_top.grid(True, alpha=0.3)
    fig.legend(handles=top_handles, loc="lower right",
               bbox_to_anchor=(0.99, 0.0), ncol=3, fontsize=7, title="overhead", title_fontsize=7, facecolor="0.9")
    acquired = trace.first_event("acquired")
    head = title or " / ".join(str(trace.meta.get(k, "")) for k in ("tree", "scenario") if trace.meta.get(k))
    suptitle = fig.suptitle("", fontsize=9, y=0.985)

    def draw(i: int) -> None:
        snap = frames[i]
        image = first if i == 0 else snap.image_bgr()
        img.set_data(_rgb(image))
        _set_rect(track_rect, snap.track_box)
        _set_rect(truth_rect, snap.truth_box)
        _set_rect(zoom_rect, snap.zoom_box)
        crop = snap.zoom_bgr()
        if crop is not None and snap.zoom_box is not None:
            # The crop fills the panel (fixed limits 0-1, so nothing but the artists changes from frame to frame).
            zx0, zy0, zx1, zy1 = snap.zoom_box
            zoom_img.set_data(_rgb(crop))
            _set_rect(zoom_track, snap.track_box, zx0, zy0, 1.0 / max(zx1 - zx0, 1e-9), 1.0 / max(zy1 - zy0, 1e-9))
            _set_rect(zoom_truth, snap.truth_box, zx0, zy0, 1.0 / max(zx1 - zx0, 1e-9), 1.0 / max(zy1 - zy0, 1e-9))
            zoom_img.set_visible(True)
            zoom_text.set_visible(False)
        else:
            zoom_img.set_visible(False)
            zoom_track.set_visible(False)
            zoom_truth.set_visible(False)
            zoom_text.set_visible(True)
        k = int(np.clip(np.searchsorted(trace.t, snap.t, side="right") - 1, 0, len(trace) - 1)) if len(trace) else 0
        if len(trace):
            j = int(np.searchsorted(trace.t, t0 - 1e-9))
            trail.set_data(own[j:k + 1, 0], own[j:k + 1, 1])
            phase = trace.phase[k] if len(trace.phase) == len(trace) else ""
            trail.set_color(phase_colour(phase))
            own_now.set_data([own[k, 0]], [own[k, 1]])
            own_now.set_color(phase_colour(phase))
            if np.isfinite(target[k, :2]).all():
                target_now.set_data([target[k, 0]], [target[k, 1]])
                target_now.set_visible(True)
            else:
                target_now.set_visible(False)
            ax_top.set_title(f"phase: {phase_name(phase)}", fontsize=8)
        since = "" if acquired is None else f", {snap.t - acquired.t:+.1f} s from acquisition"
        suptitle.set_text(f"{head}: mission time {snap.t:5.1f} s{since}" if head else f"mission time {snap.t:5.1f} s{since}")

    draw(0)
    draw.animated = [img, track_rect, truth_rect, zoom_rect, zoom_img, zoom_track, zoom_truth, zoom_text, trail, own_now,
                     target_now, ax_top.title, suptitle]
    return fig, draw


def write_animation(trace: FlightTrace, path: str | Path, fps: float = 5.0, title: str = "") -> Path:
    """Write the trace's kept frames as an animated GIF at ``path`` (one GIF frame per kept frame, looping).

    Raises:
        ValueError: the trace kept no frames.
    """
    import matplotlib.pyplot as plt
    from PIL import Image

    fig, draw = animation_figure(trace, title=title)
    images = []
    try:
        # Blitting: the axes, labels and legends drawn once; per frame only what moves.
        for artist in draw.animated:
            artist.set_animated(True)
        fig.canvas.draw()
        background = fig.canvas.copy_from_bbox(fig.bbox)
        for i in range(len(trace.frames)):
            draw(i)
            fig.canvas.restore_region(background)
            for artist in draw.animated:
                fig.draw_artist(artist)
            rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3]
            # Octree, 256 colours, no dither: the plot colours stay true and the file small (about 20 kB a frame).
            images.append(Image.fromarray(rgb).quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE))
    finally:
        plt.close(fig)
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=int(round(1000.0 / fps)), loop=0,
                   optimize=False, disposal=1)
    tmp.replace(path)
    return path
