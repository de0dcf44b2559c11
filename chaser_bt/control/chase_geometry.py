"""Where to follow from: the paper's chase-position analysis (section 3.2, figure 4).

For a fixed camera tilted down by the elevation angle (the target sits at the image centre), a
chase position is a slant range R and an elevation el above the target. The paper asks three
questions of each position, for a DJI Phantom 4 target (20 m/s horizontal, 6 m/s up, 5 m/s down):

1. pixels on target, ``sqrt(bbox_w * bbox_h)``: the box is the target's width across, and its
   height seen from above, ``h cos(el) + d sin(el)`` (more of the top shows from higher up);
2. time to react to a vertical dash before the target crosses the horizon line:
   ``R sin(el) / v_up`` (it must climb the whole relative height);
3. time to react to a horizontal dash before the target leaves the vertical FOV. Running at the
   chaser it leaves the bottom edge (depression ``el + a``, ``a`` half the vertical FOV); away, the
   top edge (``el - a``, never if ``el <= a``). By the sine rule the shorter is
   ``R sin(a) / (v_h max(sin(el + a), sin(el - a)))``.

The recommendation (:func:`recommend`) searches a grid (5 m, 5 deg by default):

- feasible: at least ``min_pixels`` on target (detection), the whole frame below the horizon
  (``el >= a``: a consistent ground background, the paper's centre panel), and a forward camera
  that does not look behind the aircraft (``el + a <= 90 deg``);
- best: the largest worst-case reaction time ``min(t_vertical, t_horizontal)`` (the paper's
  right panel). Both times grow with R, so the range is the largest the pixels allow; the
  horizontal time falls with elevation inside the feasible band, so the elevation is the lowest
  with a clean background.

With the e-con camera of the paper (95 x 73 deg, 1920 x 1080), a Phantom 4 box with propellers
(0.49 x 0.49 x 0.2 m) and a 9-pixel minimum this gives 40 m and 40 deg, the paper's choice. The
paper states neither its pixel requirement nor its box; with 10 pixels the answer is 35 m, 40 deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ChaseInputs", "ChaseRecommendation", "pixels_on_target", "time_to_horizon",
           "time_to_leave_vertical_fov", "recommend", "trade_off_figure"]


@dataclass(frozen=True)
class ChaseInputs:
    """Camera, target and target speeds; the grid searched (SI units, radians)."""

    hfov_rad: float = math.radians(95.0)
    vfov_rad: float = math.radians(73.0)
    width_px: int = 1920
    height_px: int = 1080
    target_width_m: float = 0.49  # Phantom 4: 0.35 m motor diagonal -> ~0.25 m across + a 0.24 m propeller
    target_depth_m: float = 0.49
    target_height_m: float = 0.2  # 0.196 m
    speed_h_mps: float = 20.0
    speed_up_mps: float = 6.0
    speed_down_mps: float = 5.0
    min_pixels: float = 9.0
    ranges_m: tuple[float, ...] = tuple(float(r) for r in range(10, 105, 5))
    elevations_rad: tuple[float, ...] = tuple(math.radians(e) for e in range(0, 95, 5))

    @property
    def focal_px(self) -> tuple[float, float]:
        return (0.5 * self.width_px / math.tan(0.5 * self.hfov_rad), 0.5 * self.height_px / math.tan(0.5 * self.vfov_rad))


def pixels_on_target(inputs: ChaseInputs, range_m, elevation_rad) -> np.ndarray:
    """Critical-dimension pixels ``sqrt(w h)`` of the target's box at (R, el) (broadcasts)."""
    fx, fy = inputs.focal_px
    r = np.asarray(range_m, float)
    el = np.asarray(elevation_rad, float)
    w = inputs.target_width_m * fx / r
    h = (inputs.target_height_m * np.cos(el) + inputs.target_depth_m * np.sin(el)) * fy / r
    return np.sqrt(w * h)


def time_to_horizon(inputs: ChaseInputs, range_m, elevation_rad) -> np.ndarray:
    """Seconds until a target climbing at full speed reaches the chaser's height (the horizon line)."""
    return np.asarray(range_m, float) * np.sin(np.asarray(elevation_rad, float)) / inputs.speed_up_mps


def time_to_leave_vertical_fov(inputs: ChaseInputs, range_m, elevation_rad) -> np.ndarray:
    """Seconds until a target dashing horizontally (towards or away) leaves the vertical FOV."""
    a = 0.5 * inputs.vfov_rad
    el = np.asarray(elevation_rad, float)
    worst = np.maximum(np.sin(el + a), np.sin(el - a))
    return np.asarray(range_m, float) * math.sin(a) / (inputs.speed_h_mps * worst)


@dataclass(frozen=True)
class ChaseRecommendation:
    """The chosen chase position and what it buys."""

    slant_range_m: float
    elevation_rad: float
    pixels: float
    t_vertical_s: float
    t_horizontal_s: float

    @property
    def ground_range_m(self) -> float:
        return self.slant_range_m * math.cos(self.elevation_rad)

    @property
    def rel_height_m(self) -> float:
        return self.slant_range_m * math.sin(self.elevation_rad)

    def as_dict(self) -> dict:
        return {"slant_range_m": self.slant_range_m, "elevation_deg": round(math.degrees(self.elevation_rad), 3),
                "ground_range_m": round(self.ground_range_m, 2), "rel_height_m": round(self.rel_height_m, 2),
                "pixels_on_target": round(self.pixels, 2), "t_vertical_dash_s": round(self.t_vertical_s, 2),
                "t_horizontal_dash_s": round(self.t_horizontal_s, 2)}


def recommend(inputs: ChaseInputs = ChaseInputs()) -> ChaseRecommendation:
    """The grid position with the longest worst-case reaction time among the feasible ones.

    Raises:
        ValueError: no grid position is feasible (too few pixels everywhere, or a vertical FOV so
            wide that no forward-looking elevation keeps the horizon out of the frame).
    """
    a = 0.5 * inputs.vfov_rad
    r, el = np.meshgrid(np.asarray(inputs.ranges_m, float), np.asarray(inputs.elevations_rad, float), indexing="ij")
    px = pixels_on_target(inputs, r, el)
    tv = time_to_horizon(inputs, r, el)
    th = time_to_leave_vertical_fov(inputs, r, el)
    eps = 1e-9
    feasible = (px >= inputs.min_pixels - eps) & (el >= a - eps) & (el + a <= 0.5 * math.pi + eps)
    if not feasible.any():
        raise ValueError("no chase position on the grid gives enough pixels with a clean background; "
                         "lower min_pixels or extend the grid")
    score = np.where(feasible, np.minimum(tv, th), -np.inf)
    i, j = np.unravel_index(int(np.argmax(score)), score.shape)
    return ChaseRecommendation(float(r[i, j]), float(el[i, j]), float(px[i, j]), float(tv[i, j]), float(th[i, j]))


def trade_off_figure(inputs: ChaseInputs = ChaseInputs(), path: str | None = None):
    """The three panels of the paper's figure 4 for ``inputs``; saved to ``path`` when given."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rec = recommend(inputs)
    ranges = np.linspace(10.0, 100.0, 181)
    els = np.radians(np.linspace(0.0, 90.0, 181))
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    for e in (20, 30, 40, 50, 60):
        ax[0].plot(ranges, pixels_on_target(inputs, ranges, math.radians(e)), label=f"{e} deg")
    ax[0].axhline(inputs.min_pixels, color="k", ls="--", lw=1, label=f"required {inputs.min_pixels:g} px")
    ax[0].set(xlabel="slant range (m)", ylabel="pixels on target, sqrt(w h) (px)", title="Pixels on target", ylim=(0, 40))
    for rr in (30, 40, 50):
        ax[1].plot(np.degrees(els), time_to_horizon(inputs, rr, els), label=f"{rr} m")
        ax[2].plot(np.degrees(els), time_to_leave_vertical_fov(inputs, rr, els), label=f"{rr} m")
    a = math.degrees(0.5 * inputs.vfov_rad)
    ax[1].axvspan(0, a, color="0.85", label="horizon in frame")
    ax[1].set(xlabel="elevation below the chaser (deg)", ylabel="time until the target is at the horizon (s)",
              title=f"Climb at {inputs.speed_up_mps:g} m/s: time to horizon")
    ax[2].axvspan(90 - a, 90, color="0.85", label="camera sees behind")
    ax[2].set(xlabel="elevation below the chaser (deg)", ylabel="time until the target leaves the FOV (s)", ylim=(0, 4),
              title=f"Dash at {inputs.speed_h_mps:g} m/s: time to leave vertical FOV")
    ax[0].axvline(rec.slant_range_m, color="r", ls=":", lw=1.5,
                  label=f"choice {rec.slant_range_m:g} m, {math.degrees(rec.elevation_rad):g} deg")
    for k in (1, 2):
        ax[k].axvline(math.degrees(rec.elevation_rad), color="r", ls=":", lw=1.5,
                      label=f"choice {math.degrees(rec.elevation_rad):g} deg")
    for k, heading in enumerate(("elevation below the chaser", "slant range", "slant range")):
        ax[k].legend(fontsize=8, title=heading, title_fontsize=8)
        ax[k].grid(alpha=0.3)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig
