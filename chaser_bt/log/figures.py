"""The paper's figures from flight traces: overhead tracks, relative geometry, belief maps, campaign CDFs.

Every function takes :class:`~chaser_bt.log.trace.FlightTrace` objects (or, for campaign summaries,
the per-run report rows) and returns a matplotlib ``Figure`` drawn with the non-interactive Agg
backend; :func:`save_figure` writes a PNG and frees it. The same functions serve a rehearsal's
report, a campaign's report and ``chaser-bt plot LOG`` on a recorded flight.

- :func:`plot_overhead` — ownship tracks coloured by mission phase, target tracks dashed, events
  marked (the paper's overhead views, figures 5 and 8).
- :func:`plot_relative_geometry` — target azimuth, elevation and range relative to the ownship
  against the desired values, with the camera's limits and the detection intervals shaded
  (figures 7 and 9, section 4).
- :func:`plot_belief_snapshots` — the search belief maps (section 2.3).
- :func:`plot_metric_cdfs` — a campaign's spread of the DESIGN §7 figures (docs/design.md) with the paper's values
  marked.

Lines and markers carry a ``gid`` (``ownship/<run>/<phase>``, ``target/<run>``, ``event/<run>/<name>``,
``azimuth/<run>`` ...) so that tests and callers can find the data they drew.
"""

from __future__ import annotations

import math
from typing import Collection, Mapping, Sequence

import matplotlib

matplotlib.use("Agg")  # before pyplot: figures are files, never windows

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from chaser_bt.log.trace import FlightTrace  # noqa: E402
from chaser_bt.vision.camera import CameraModel  # noqa: E402

__all__ = [
    "METRIC_LABELS",
    "PAPER_VALUES",
    "QUIET_EVENTS",
    "phase_segments",
    "plot_overhead",
    "plot_relative_geometry",
    "plot_belief_snapshots",
    "plot_metric_cdfs",
    "save_figure",
]

#: The paper's measured values of the DESIGN §7 figures (section 4: 15.48 s to airborne, 4.95 s to
#: acquisition, target in the FOV 91 % of the flight, detections on 66 % of frames, radar
#: association in 91.7 % of 1 s windows).
PAPER_VALUES: dict[str, float] = {
    "t_airborne_s": 15.48,
    "t_acquire_s": 4.95,
    "target_in_fov_frac": 0.91,
    "detection_frac": 0.66,
    "radar_assoc_frac": 0.917,
}

#: Events the overhead plot leaves unmarked by default (the phase colours and the mode already say them).
QUIET_EVENTS: frozenset[str] = frozenset({"phase", "mode"})

#: Axis labels of the report keys, with units.
METRIC_LABELS: dict[str, str] = {
    "t_airborne_s": "radar validation to take-off altitude (s)",
    "t_acquire_s": "take-off altitude to first acquisition (s)",
    "target_in_fov_frac": "share of flight with the target in the FOV",
    "detection_frac": "share of frames with a true detection",
    "radar_assoc_frac": "share of 1 s windows with the ownship's track",
    "wrong_assoc_frac": "share of windows with a wrong track",
}

#: How the relative-geometry plot names the target's position, by the trace's ``target_source``.
_TARGET_SOURCE_LABEL = {"truth": "true", "telemetry": "from the intruder's telemetry",
                        "estimate": "from the camera's estimate", "cue": "from the radar cue"}

_DEFAULT_CAMERA = CameraModel()
_CDF_KEYS = ("t_airborne_s", "t_acquire_s", "target_in_fov_frac", "detection_frac", "radar_assoc_frac")


def save_figure(fig: Figure, path, dpi: int = 110) -> None:
    """Write ``fig`` as a PNG at ``path`` and close it (figures hold memory until closed)."""
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def phase_segments(phases: Sequence[str]) -> list[tuple[str, int, int]]:
    """Maximal runs of equal phase labels as ``(phase, start, stop)`` with ``stop`` exclusive.

    ``["a", "a", "b"]`` gives ``[("a", 0, 2), ("b", 2, 3)]``.
    """
    segments: list[tuple[str, int, int]] = []
    start = 0
    for i in range(1, len(phases) + 1):
        if i == len(phases) or phases[i] != phases[start]:
            segments.append((phases[start], start, i))
            start = i
    return segments


def _phase_colours(traces: Sequence[FlightTrace]) -> dict[str, tuple]:
    names: list[str] = []
    for tr in traces:
        for p in tr.phase:
            if p not in names:
                names.append(p)
    cmap = plt.get_cmap("tab10")
    palette = [cmap(i) for i in range(10) if i != 3]  # red (3) is the target's
    return {name: palette[i % len(palette)] for i, name in enumerate(names)}


def plot_overhead(traces: Sequence[FlightTrace], title: str = "", skip_events: Collection[str] = QUIET_EVENTS) -> Figure:
    """Overhead (east, north) tracks of the ownship, coloured by phase, and of the target, dashed.

    Events are marked with a dot on the ownship's track (and named, one label per place, when there
    is a single trace), except those named in ``skip_events`` (phase and mode changes: the colours
    already show them). A search-and-rescue trace also shows the people (``meta["people_enu"]``)
    and the find (``meta["find_enu"]``).
    A trace without phase labels draws its ownship track in one colour.
    """
    fig, ax = plt.subplots(figsize=(7.5, 7.0), layout="constrained")
    colours = _phase_colours(traces)
    labelled: set[str] = set()
    alpha = 1.0 if len(traces) == 1 else max(0.25, 1.0 / math.sqrt(len(traces)))
    for k, tr in enumerate(traces):
        if not len(tr):
            continue
        xy = tr.ownship_enu[:, :2]
        phases = tr.phase if len(tr.phase) == len(tr) else ["flight"] * len(tr)
        for phase, i0, i1 in phase_segments(phases):
            # Carry each segment one sample into the next so the track has no gaps.
            seg = xy[i0:min(i1 + 1, len(tr))]
            visible = len(seg) > 1 and float(np.ptp(seg, axis=0).max()) > 0.0  # a phase spent in one place draws nothing
            label = phase if phase not in labelled and visible else None
            if visible:
                labelled.add(phase)
            (line,) = ax.plot(seg[:, 0], seg[:, 1], color=colours.get(phase, "C0"), lw=1.6, alpha=alpha, label=label)
            line.set_gid(f"ownship/{k}/{phase}")
        target = tr.target_enu[:, :2]
        if np.isfinite(target).any():
            label = "target" if "target" not in labelled else None
            labelled.add("target")
            (line,) = ax.plot(target[:, 0], target[:, 1], color="tab:red", ls="--", lw=1.2, alpha=alpha, label=label)
            line.set_gid(f"target/{k}")
        places: list[tuple[np.ndarray, list[str]]] = []  # events drawn at one place share one label
        span = max(float(np.ptp(xy, axis=0).max()), 1.0)
        for ev in tr.events:
            if ev.name in skip_events:
                continue
            i = int(np.clip(np.searchsorted(tr.t, ev.t), 0, len(tr) - 1))
            label = "events" if "events" not in labelled else None
            labelled.add("events")
            (mark,) = ax.plot([xy[i, 0]], [xy[i, 1]], "o", ms=5, color="black", alpha=alpha, label=label)
            mark.set_gid(f"event/{k}/{ev.name}")
            near = next((names for at, names in places if np.hypot(*(at - xy[i])) < 0.02 * span), None)
            if near is None:
                places.append((xy[i].copy(), [ev.name]))
            elif ev.name not in near:
                near.append(ev.name)
        for person in tr.meta.get("people_enu", []):  # a search-and-rescue rehearsal: the truth, and the find
            label = "person (truth)" if "person" not in labelled else None
            labelled.add("person")
            ax.plot([person[0]], [person[1]], "*", ms=13, color="tab:green", mec="black", alpha=alpha, label=label)[0].set_gid(f"person/{k}")
        if tr.meta.get("find_enu") is not None:
            find = tr.meta["find_enu"]
            label = "find" if "find" not in labelled else None
            labelled.add("find")
            ax.plot([find[0]], [find[1]], "P", ms=9, color="tab:purple", alpha=alpha, label=label)[0].set_gid(f"find/{k}")
        if len(traces) == 1:
            for n, (at, names) in enumerate(places):
                ax.annotate(", ".join(names), (at[0], at[1]), textcoords="offset points", fontsize=8,
                            xytext=(6, 6 + 9 * (n % 3)), gid=f"event_label/{n}",
                            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7})
    ax.plot([0.0], [0.0], "k^", ms=8, label="home")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or (f"overhead tracks ({len(traces)} runs)" if len(traces) > 1 else "overhead track"))
    return fig


def _intervals(mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True in ``mask`` as ``(start, stop)`` index pairs, ``stop`` exclusive."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist()))


def plot_relative_geometry(
    traces: Sequence[FlightTrace],
    align_event: str | None = None,
    camera: CameraModel = _DEFAULT_CAMERA,
    title: str = "",
) -> Figure:
    """Target azimuth, elevation (deg) and range (m) relative to the ownship against time (figures 7 and 9).

    Solid: the relative position (the truth in a rehearsal; from the intruder's telemetry or the
    camera in a flight log, as the trace's ``target_source`` says); red dashed: the desired one (azimuth 0, the trace's
    ``desired_elevation_rad`` and ``desired_range_m`` where set); green band: the camera's limits
    with the aircraft level (half the FOV about the boresight, which is tilted ``camera.tilt_rad``
    down; range up to ``camera.max_range_m``, the range the search's sensor model assumes); cyan:
    intervals with a true detection (the pipeline's box on the target's true box; single trace).

    ``align_event``: plot time from that event of each trace (e.g. ``"acquired"``) instead of
    mission time; traces without the event are left out.
    """
    fig, axes = plt.subplots(3, 1, figsize=(9.0, 7.5), sharex=True, layout="constrained")
    ax_az, ax_el, ax_r = axes
    single = len(traces) == 1
    alpha = 1.0 if single else max(0.25, 1.0 / math.sqrt(len(traces)))
    drawn = 0
    desired_range, desired_el = math.nan, math.nan
    for k, tr in enumerate(traces):
        if not len(tr):
            continue
        t0 = 0.0
        if align_event is not None:
            ev = tr.first_event(align_event)
            if ev is None:
                continue
            t0 = ev.t
        t = tr.t - t0
        for ax, name, values in (
            (ax_az, "azimuth", np.degrees(tr.azimuth_rad)),
            (ax_el, "elevation", np.degrees(tr.elevation_rad)),
            (ax_r, "range", tr.slant_range_m),
        ):
            label = _TARGET_SOURCE_LABEL.get(tr.target_source, f"from {tr.target_source}") if drawn == 0 else None
            (line,) = ax.plot(t, values, color="tab:blue", lw=1.2, alpha=alpha, label=label)
            line.set_gid(f"{name}/{k}")
        if single:
            for n, (i0, i1) in enumerate(_intervals(np.nan_to_num(tr.detected, nan=0.0) > 0.5)):
                for ax in axes:
                    ax.axvspan(t[i0], t[min(i1, len(t) - 1)], color="cyan", alpha=0.25, lw=0,
                               label="detections" if n == 0 else None)
        desired_range = tr.desired_range_m if math.isfinite(tr.desired_range_m) else desired_range
        desired_el = tr.desired_elevation_rad if math.isfinite(tr.desired_elevation_rad) else desired_el
        drawn += 1
    half_h, half_v, tilt = math.degrees(camera.hfov_rad / 2), math.degrees(camera.vfov_rad / 2), math.degrees(camera.tilt_rad)
    ax_az.axhspan(-half_h, half_h, color="green", alpha=0.08, label="camera FOV")
    ax_el.axhspan(tilt - half_v, tilt + half_v, color="green", alpha=0.08, label="camera FOV")
    # The camera model's range is what the search assumes it sees (its sensor model), not the detector's
    # limit: with the cue's focus window the detector can match the target well beyond it.
    ax_r.axhspan(camera.min_range_m, camera.max_range_m, color="green", alpha=0.08, label="search's sensor range")
    ax_az.axhline(0.0, color="red", ls="--", lw=1.5, label="desired").set_gid("desired/azimuth")
    if math.isfinite(desired_el):
        ax_el.axhline(math.degrees(desired_el), color="red", ls="--", lw=1.5, label="desired").set_gid("desired/elevation")
    if math.isfinite(desired_range):
        ax_r.axhline(desired_range, color="red", ls="--", lw=1.5, label="desired").set_gid("desired/range")
    ax_az.set_ylabel("azimuth (deg)")
    ax_el.set_ylabel("elevation (deg)\n(+ target below)")
    ax_r.set_ylabel("range (m)")
    ax_r.set_xlabel(f"time from {align_event} (s)" if align_event else "mission time (s)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    ax_az.set_title(title or f"target relative to the ownship ({drawn} run{'s' if drawn != 1 else ''})")
    return fig


def plot_belief_snapshots(trace: FlightTrace, max_panels: int = 6, title: str = "") -> Figure:
    """The search belief (summed over altitude) at up to ``max_panels`` snapshots, evenly chosen.

    Each panel shows the belief normalised to sum 1 (image ``belief/<i>``; the title gives the mass
    when it is not 1), the ownship's track up to that time and its position then, and the target's
    position then when known.
    """
    snaps = trace.beliefs
    if len(snaps) > max_panels:
        pick = np.unique(np.linspace(0, len(snaps) - 1, max_panels).round().astype(int))
        snaps = [snaps[i] for i in pick]
    n = max(len(snaps), 1)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.0 * cols, 3.8 * rows), squeeze=False, layout="constrained")
    for ax in axes.flat[len(snaps):]:
        ax.axis("off")
    if not snaps:
        axes[0, 0].text(0.5, 0.5, "no belief snapshots in this trace", ha="center", va="center")
    for ax, snap in zip(axes.flat, snaps):
        dx = float(snap.x_m[1] - snap.x_m[0]) if len(snap.x_m) > 1 else 1.0
        dy = float(snap.y_m[1] - snap.y_m[0]) if len(snap.y_m) > 1 else 1.0
        extent = (snap.x_m[0] - dx / 2, snap.x_m[-1] + dx / 2, snap.y_m[0] - dy / 2, snap.y_m[-1] + dy / 2)
        # mass[i, j] is over (x_i, y_j): imshow wants rows = y.
        # Shown normalised, so a log (the planner's belief, which loses mass with every look that
        # sees nothing) and a rehearsal report (normalised) draw on one scale; the title gives the mass.
        mass = np.asarray(snap.mass, float)
        total = float(mass.sum())
        img = ax.imshow((mass / total if total > 0 else mass).T, origin="lower", extent=extent, cmap="viridis", aspect="equal")
        img.set_gid(f"belief/{snap.t:g}")
        fig.colorbar(img, ax=ax, shrink=0.8).set_label("share of the belief per cell", fontsize=8)
        if len(trace):
            i = int(np.clip(np.searchsorted(trace.t, snap.t, side="right") - 1, 0, len(trace) - 1))
            ax.plot(trace.ownship_enu[: i + 1, 0], trace.ownship_enu[: i + 1, 1], color="white", lw=1.0, label="ownship track")
            ax.plot([trace.ownship_enu[i, 0]], [trace.ownship_enu[i, 1]], "w^", ms=7, label="ownship now")[0].set_gid("ownship_now")
            if np.isfinite(trace.target_enu[i, :2]).all():
                ax.plot([trace.target_enu[i, 0]], [trace.target_enu[i, 1]], "x", color="tab:orange", ms=8, mew=2,
                        label="target now")[0].set_gid("target_now")
            ax.legend(loc="upper right", fontsize=6, facecolor="0.85")
        ax.set_title(f"t = {snap.t:.1f} s" + (f", belief mass {total:.3g}" if abs(total - 1.0) > 1e-3 else ""), fontsize=9)
        ax.set_xlabel("east (m)", fontsize=8)
        ax.set_ylabel("north (m)", fontsize=8)
    fig.suptitle(title or "search belief")
    return fig


def plot_metric_cdfs(
    rows: Sequence[Mapping],
    keys: Sequence[str] = _CDF_KEYS,
    paper: Mapping[str, float] = PAPER_VALUES,
    title: str = "",
) -> Figure:
    """Empirical CDFs of report keys over a campaign's runs, the paper's value as a red dashed line.

    ``rows`` are per-run report dicts; runs where a key is None (did not apply, e.g. never
    acquired) are left out of that key's curve, and the panel says how many of all runs it holds.
    The curve ``cdf/<key>`` steps to ``i/n`` at the ``i``-th smallest value.
    """
    keys = list(keys)
    cols = min(len(keys), 3)
    nrows = math.ceil(len(keys) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.4 * nrows), squeeze=False, layout="constrained")
    for ax in axes.flat[len(keys):]:
        ax.axis("off")
    for ax, key in zip(axes.flat, keys):
        values = np.sort([float(r[key]) for r in rows if r.get(key) is not None and math.isfinite(float(r[key]))])
        n = len(values)
        if n:
            x = np.concatenate([[values[0]], values])
            y = np.arange(n + 1) / n
            (line,) = ax.step(x, y, where="post", color="tab:blue", label=f"runs ({n}/{len(rows)})")
            line.set_gid(f"cdf/{key}")
            ax.axvline(float(np.median(values)), color="tab:blue", ls=":", lw=1.0, label=f"median {np.median(values):.3g}")
        else:
            ax.text(0.5, 0.5, "no run has this value", ha="center", va="center", transform=ax.transAxes)
        if key in paper:
            ax.axvline(paper[key], color="red", ls="--", lw=1.5, label=f"paper {paper[key]:g}").set_gid(f"paper/{key}")
        if key.endswith("_frac"):
            ax.set_xlim(-0.02, 1.02)
        ax.set_xlabel(METRIC_LABELS.get(key, key))
        ax.set_ylabel("fraction of runs")
        ax.set_ylim(0.0, 1.02)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=7, framealpha=0.6)
    fig.suptitle(title or f"campaign: {len(rows)} runs")
    return fig
