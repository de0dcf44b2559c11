"""The paper's figures from flight traces: overhead tracks, relative geometry, belief maps, campaign CDFs.

Every function takes :class:`~chaser_bt.log.trace.FlightTrace` objects (or, for campaign summaries,
the per-run report rows) and returns a matplotlib ``Figure`` drawn with the non-interactive Agg
backend; :func:`save_figure` writes a PNG and frees it. The same functions serve a rehearsal's
report, a campaign's report and ``chaser-bt plot LOG`` on a recorded flight.

- :func:`plot_overhead` — one run's ownship track coloured by mission phase (the trace's ``phase``:
  wait, launch, fly_to_cue, search, follow, hold, safety:...; never the flight mode), its target
  dashed, its events marked (the paper's overhead views, figures 5 and 8). Given many runs, one
  (``highlight``: by default the median run, :func:`select_run`) is drawn so and the others as
  thin grey tracks behind it: readable at 50 runs.
- :func:`plot_relative_geometry` — target azimuth, elevation and slant range relative to the
  ownship against time (figures 7 and 9, section 4): the highlighted run strong, the others faint
  with their median and interquartile band, against the tree's desired follow geometry, the paper's
  set-point (40 m, 40 deg) and its follow envelope (30-50 m, 30-50 deg) and the camera's FOV edges;
  a strip under them shows the highlighted run's phases, target-in-FOV and true-detection intervals.
- :func:`plot_belief_snapshots` — the search belief maps (section 2.3).
- :func:`plot_metric_cdfs` — a campaign's spread of the DESIGN §7 figures (docs/design.md) with the
  paper's values marked; only figures some run has are drawn (a patrol has no target: "no data").

Every axis is labelled with its unit and every legend has a title, outside the data.
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
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from chaser_bt.log.trace import FlightTrace  # noqa: E402
from chaser_bt.vision.camera import CameraModel  # noqa: E402

__all__ = [
    "METRIC_LABELS",
    "PAPER_VALUES",
    "PAPER_FOLLOW_RANGE_M",
    "PAPER_FOLLOW_ELEVATION_DEG",
    "PAPER_ENVELOPE_RANGE_M",
    "PAPER_ENVELOPE_ELEVATION_DEG",
    "PHASE_COLOURS",
    "QUIET_EVENTS",
    "has_phases",
    "phase_colour",
    "phase_name",
    "phase_segments",
    "run_label",
    "select_run",
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

#: The paper's follow set-point (section 2.5, figure 4: 40 m slant range at 40 deg below) and its
#: follow envelope (section 4: 30-50 m, 30-50 deg), which ``sitl.bench.scoring`` scores as ``envelope_frac``.
PAPER_FOLLOW_RANGE_M = 40.0
PAPER_FOLLOW_ELEVATION_DEG = 40.0
PAPER_ENVELOPE_RANGE_M = (30.0, 50.0)
PAPER_ENVELOPE_ELEVATION_DEG = (30.0, 50.0)

#: Events the overhead plot leaves unmarked by default: the phase colours say the phase changes, a
#: mode change follows a phase's, and custody changes (the radar track carrying the target) come by the dozen.
QUIET_EVENTS: frozenset[str] = frozenset({"phase", "mode", "custody"})

#: Axis labels of the report keys, with units.
METRIC_LABELS: dict[str, str] = {
    "t_airborne_s": "radar validation to take-off altitude (s)",
    "t_acquire_s": "take-off altitude to first acquisition (s)",
    "target_in_fov_frac": "share of flight with the target in the FOV (0-1)",
    "detection_frac": "share of frames with a true detection (0-1)",
    "radar_assoc_frac": "share of 1 s windows with the ownship's track (0-1)",
    "wrong_assoc_frac": "share of windows with a wrong track (0-1)",
}

#: One colour per mission phase, the same in every figure (red is the target's, black the events').
PHASE_COLOURS: dict[str, str] = {
    "": "0.65", "wait": "0.45", "launch": "tab:orange", "fly_to_cue": "tab:green", "search": "tab:purple",
    "follow": "tab:blue", "hold": "tab:brown", "land": "tab:olive", "return": "tab:olive", "check": "tab:cyan",
    "loiter": "tab:pink", "flight": "tab:blue",
}
_SAFETY_COLOUR = "darkmagenta"
_SPARE_COLOURS = ("tab:cyan", "tab:pink", "tab:olive", "goldenrod", "teal", "slategray", "sienna")

#: How the relative-geometry plot names the target's position, by the trace's ``target_source``.
_TARGET_SOURCE_LABEL = {"truth": "true", "telemetry": "from the intruder's telemetry",
                        "estimate": "from the camera's estimate", "cue": "from the radar cue"}

#: How a time axis names the event it counts from.
_EVENT_NOUNS = {"acquired": "the first acquisition", "airborne": "take-off altitude", "radar_validated": "the radar validation"}

_DEFAULT_CAMERA = CameraModel()
_CDF_KEYS = ("t_airborne_s", "t_acquire_s", "target_in_fov_frac", "detection_frac", "radar_assoc_frac")
_LEGEND = {"fontsize": 7, "title_fontsize": 7, "framealpha": 0.9}
_OTHER_RUNS = "0.6"  # the runs drawn faint behind the highlighted one
_YES, _NO = "0.2", "0.85"  # the strip's target-in-FOV and true-detection intervals


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


def phase_colour(phase: str) -> str:
    """The colour of a mission phase in every figure (``safety:...`` phases share one)."""
    if phase in PHASE_COLOURS:
        return PHASE_COLOURS[phase]
    if phase.startswith("safety"):
        return _SAFETY_COLOUR
    return _SPARE_COLOURS[sum(map(ord, phase)) % len(_SPARE_COLOURS)]


def phase_name(phase: str) -> str:
    """A phase as a legend says it (the empty label: before the mission named one)."""
    return phase or "no phase yet"


def has_phases(trace: FlightTrace) -> bool:
    """Whether the trace's ``phase`` column is the mission's phase, not a stand-in.

    A flight log of a tree that never writes ``/mission/phase`` fills it with the flight mode
    (:func:`chaser_bt.log.replay.flight_trace`); a rehearsal of one leaves it empty. Those trees
    have no phases to colour.
    """
    if len(trace.phase) != len(trace) or not any(trace.phase):
        return False
    if any(e.name == "phase" for e in trace.events):
        return True
    return len(trace.mode) != len(trace.phase) or any(p and p != m for p, m in zip(trace.phase, trace.mode))


def run_label(trace: FlightTrace, fallback: str = "") -> str:
    """A run's name for a legend: ``scenario seed N`` from the trace's meta (or ``fallback``)."""
    scenario, seed = trace.meta.get("scenario"), trace.meta.get("seed")
    if scenario is None and seed is None:
        return fallback or str(trace.meta.get("log", "")).rsplit("/", 1)[-1] or "the run"
    return " ".join(str(x) for x in ((scenario or ""), (f"seed {seed}" if seed is not None else "")) if x)


def select_run(values: Sequence[float | None]) -> int | None:
    """The index of the median of ``values`` (the lower one of an even count), None values left out;
    None when no value is finite. What a campaign highlights: its median run."""
    finite = [(float(v), i) for i, v in enumerate(values) if v is not None and math.isfinite(float(v))]
    if not finite:
        return None
    finite.sort()
    return finite[(len(finite) - 1) // 2][1]


def _default_highlight(traces: Sequence[FlightTrace]) -> int:
    """The median run by the time of its first acquisition, else by its length."""
    drawn = [k for k, tr in enumerate(traces) if len(tr)]
    if not drawn:
        return 0
    acquired = [tr.first_event("acquired").t if tr.first_event("acquired") else None for tr in traces]
    k = select_run([acquired[i] for i in drawn])
    if k is None:
        k = select_run([float(traces[i].t[-1] - traces[i].t[0]) for i in drawn])
    return drawn[k if k is not None else 0]


def _outside(ax, handles, title: str, anchor: tuple[float, float] = (1.02, 1.0), loc: str = "upper left",
             **kwargs):
    """A titled legend to the right of ``ax``, off the data; several can be stacked (``add_artist``)."""
    legend = ax.legend(handles=handles, title=title, loc=loc, bbox_to_anchor=anchor, borderaxespad=0.0,
                       **{**_LEGEND, **kwargs})
    legend._legend_box.align = "left"
    ax.add_artist(legend)  # kept when another legend follows; unclipped, so that the layout makes room for it
    legend.set_clip_on(False)
    return legend


def plot_overhead(traces: Sequence[FlightTrace], title: str = "", skip_events: Collection[str] = QUIET_EVENTS,
                  highlight: int | None = None, highlight_why: str = "") -> Figure:
    """Overhead (east, north) track of one run coloured by mission phase, its target dashed; other runs grey.

    The highlighted run (``traces[highlight]``; default the only one, or the median by acquisition
    time, :func:`select_run`) is drawn in its phase colours with events marked by a dot (and named,
    one label per place), except those named in ``skip_events`` (phase and mode changes: the colours
    already show them). Every other run is a thin grey line behind it. A search-and-rescue trace
    also shows the people (``meta["people_enu"]``) and the find (``meta["find_enu"]``).
    A trace without mission phases (:func:`has_phases`) draws its track in one colour, and its mode
    changes are events. Legends (titled: the phases, the rest) stand right of the map.
    ``highlight_why`` says in the legend why that run (e.g. "median acquisition").
    """
    fig, ax = plt.subplots(figsize=(9.0, 7.0), layout="constrained")
    drawn = [k for k, tr in enumerate(traces) if len(tr)]
    if highlight is None:
        highlight = _default_highlight(traces)
    others = [k for k in drawn if k != highlight]
    alpha = float(np.clip(2.0 / math.sqrt(max(len(others), 1)), 0.2, 0.6))
    for k in others:  # behind: every other run, thin and grey
        xy = traces[k].ownship_enu[:, :2]
        (line,) = ax.plot(xy[:, 0], xy[:, 1], color=_OTHER_RUNS, lw=0.7, alpha=alpha, zorder=1)
        line.set_gid(f"ownship/{k}/other")
    phase_handles: dict[str, Line2D] = {}
    extra: list = []
    if highlight in drawn:
        tr = traces[highlight]
        k = highlight
        xy = tr.ownship_enu[:, :2]
        phased = has_phases(tr)
        phases = tr.phase if phased else ["flight"] * len(tr)
        for phase, i0, i1 in phase_segments(phases):
            # Carry each segment one sample into the next so the track has no gaps.
            seg = xy[i0:min(i1 + 1, len(tr))]
            (line,) = ax.plot(seg[:, 0], seg[:, 1], color=phase_colour(phase), lw=2.0, zorder=3)
            line.set_gid(f"ownship/{k}/{phase}")
            visible = len(seg) > 1 and float(np.nanmax(np.ptp(seg, axis=0))) > 0.0  # a phase spent in one place draws nothing
            if visible and phase not in phase_handles:
                name = phase_name(phase) if phased else "ownship (no mission phases recorded)"
                phase_handles[phase] = Line2D([], [], color=phase_colour(phase), lw=2.0, label=name)
        target = tr.target_enu[:, :2]
        if np.isfinite(target).any():
            (line,) = ax.plot(target[:, 0], target[:, 1], color="tab:red", ls="--", lw=1.2, zorder=2)
            line.set_gid(f"target/{k}")
            extra.append(Line2D([], [], color="tab:red", ls="--", lw=1.2,
                                label="target (" + _TARGET_SOURCE_LABEL.get(tr.target_source, tr.target_source) + ")"))
        skip = set(skip_events) if phased else set(skip_events) - {"mode"}
        places: list[tuple[np.ndarray, list[str]]] = []  # events drawn at one place share one label
        span = max(float(np.nanmax(np.ptp(xy, axis=0))), 1.0)
        for ev in tr.events:
            if ev.name in skip:
                continue
            i = int(np.clip(np.searchsorted(tr.t, ev.t), 0, len(tr) - 1))
            (mark,) = ax.plot([xy[i, 0]], [xy[i, 1]], "o", ms=5, color="black", zorder=4)
            mark.set_gid(f"event/{k}/{ev.name}")
            name = ev.name if ev.name != "mode" else f"mode {ev.detail}"
            near = next((names for at, names in places if np.hypot(*(at - xy[i])) < 0.02 * span), None)
            if near is None:
                places.append((xy[i].copy(), [name]))
            elif name not in near:
                near.append(name)
        if places:
            extra.append(Line2D([], [], ls="", marker="o", ms=5, color="black", label="events (named)"))
        for person in tr.meta.get("people_enu", []):  # a search-and-rescue rehearsal: the truth, and the find
            ax.plot([person[0]], [person[1]], "*", ms=13, color="tab:green", mec="black", zorder=4)[0].set_gid(f"person/{k}")
        if tr.meta.get("people_enu"):
            extra.append(Line2D([], [], ls="", marker="*", ms=11, color="tab:green", mec="black", label="person (truth)"))
        if tr.meta.get("find_enu") is not None:
            find = tr.meta["find_enu"]
            ax.plot([find[0]], [find[1]], "P", ms=9, color="tab:purple", zorder=4)[0].set_gid(f"find/{k}")
            extra.append(Line2D([], [], ls="", marker="P", ms=9, color="tab:purple", label="find"))
        for n, (at, names) in enumerate(places):
            ax.annotate(", ".join(names), (at[0], at[1]), textcoords="offset points", fontsize=8,
                        xytext=(8, 6 + 9 * (n % 3)), gid=f"event_label/{n}",
                        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7},
                        arrowprops={"arrowstyle": "-", "lw": 0.5, "color": "0.35", "shrinkA": 0, "shrinkB": 3})
    ax.plot([0.0], [0.0], "k^", ms=8, zorder=4)
    extra.append(Line2D([], [], ls="", marker="^", ms=8, color="black", label="home"))
    if others:
        extra.append(Line2D([], [], color=_OTHER_RUNS, lw=1.0, label=f"other runs' tracks ({len(others)})"))
    ax.set_xlabel("east of home (m)")
    ax.set_ylabel("north of home (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    name = run_label(traces[highlight]) if highlight in drawn else ""
    kind = "mission phase" if highlight in drawn and has_phases(traces[highlight]) else "ownship track"
    heading = kind if not others else f"{kind}, run {name}" + (f"\n({highlight_why})" if highlight_why else "")
    legend = _outside(ax, list(phase_handles.values()) or [Line2D([], [], color="0.5", label="no track")], heading)
    _outside(ax, extra, "also drawn", anchor=(1.02, 0.0), loc="lower left")
    legend.set_gid("legend/phases")
    if title:
        ax.set_title(title)
    elif others:
        ax.set_title(f"overhead: run {name} in colour, {len(others)} other run{'s' if len(others) != 1 else ''} grey")
    else:
        ax.set_title(f"overhead track: {name}" if name else "overhead track")
    return fig


def _intervals(mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True in ``mask`` as ``(start, stop)`` index pairs, ``stop`` exclusive."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist()))


def _held_on_grid(t: np.ndarray, values: np.ndarray, grid: np.ndarray, max_gap_s: float = 1.0) -> np.ndarray:
    """``values`` sampled and held at ``grid`` (NaN before the first sample, after the last, and
    where the last sample is older than ``max_gap_s``); holding, not interpolating, keeps a wrapped
    azimuth honest."""
    out = np.full(len(grid), np.nan)
    if not len(t):
        return out
    i = np.searchsorted(t, grid, side="right") - 1
    ok = (i >= 0) & (grid <= t[-1] + 1e-9)
    ok[ok] &= grid[ok] - t[i[ok]] <= max_gap_s
    out[ok] = values[i[ok]]
    return out


def plot_relative_geometry(
    traces: Sequence[FlightTrace],
    align_event: str | None = None,
    camera: CameraModel = _DEFAULT_CAMERA,
    title: str = "",
    highlight: int | None = None,
    highlight_why: str = "",
) -> Figure:
    """Target azimuth (deg), elevation (deg) and slant range (m) relative to the ownship against time (figures 7 and 9).

    The highlighted run (``traces[highlight]``, default the only one or the median by acquisition
    time) is drawn strong (blue: the truth in a rehearsal; from the intruder's telemetry or the
    camera in a flight log, as its ``target_source`` says); every other run thin and grey, with the
    median over the runs (black) and the band of their middle half (25-75 %, grey) where five or more
    runs have a value. Against them: red dashed, the desired geometry the tree asked for (azimuth 0,
    the trace's ``desired_elevation_rad`` and ``desired_range_m`` where set); black dotted, the
    paper's set-point (40 deg, 40 m); orange hatched, the paper's follow envelope (30-50 deg,
    30-50 m); green dash-dot, the camera's FOV edges with the aircraft level (half the FOV about the
    boresight, which is tilted ``camera.tilt_rad`` down). The range axis is logarithmic (the approach
    from hundreds of metres and the follow at tens both read). A strip at the bottom shows the
    highlighted run's mission phases and, where scored (a rehearsal), when the target was in the
    camera's FOV and when the pipeline's box was on it (a true detection).

    ``align_event``: plot time from that event of each trace (e.g. ``"acquired"``) instead of
    mission time; traces without the event are left out.
    """
    fig, axes = plt.subplots(4, 1, figsize=(10.5, 9.0), sharex=True, layout="constrained",
                             gridspec_kw={"height_ratios": [3, 3, 3, 1.4]})
    ax_az, ax_el, ax_r, ax_strip = axes
    if highlight is None:
        highlight = _default_highlight(traces)
    series: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
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
        series[k] = (tr.t - t0, np.degrees(tr.azimuth_rad), np.degrees(tr.elevation_rad), tr.slant_range_m)
        desired_range = tr.desired_range_m if math.isfinite(tr.desired_range_m) else desired_range
        desired_el = tr.desired_elevation_rad if math.isfinite(tr.desired_elevation_rad) else desired_el
    if highlight not in series and series:
        highlight = next(iter(series))
    others = [k for k in series if k != highlight]
    alpha = float(np.clip(2.0 / math.sqrt(max(len(others), 1)), 0.15, 0.5))
    panels = ((ax_az, "azimuth", 1), (ax_el, "elevation", 2), (ax_r, "range", 3))
    for k in others:
        for ax, name, col in panels:
            (line,) = ax.plot(series[k][0], series[k][col], color=_OTHER_RUNS, lw=0.6, alpha=alpha, zorder=1)
            line.set_gid(f"{name}/{k}")
    run_handles: list = []
    if len(series) >= 5:  # the middle of the runs, on a common time grid
        t_lo = min(float(np.nanmin(s[0])) for s in series.values())
        t_hi = max(float(np.nanmax(s[0])) for s in series.values())
        grid = np.arange(t_lo, t_hi + 0.25, 0.5)
        for ax, name, col in panels:
            stack = np.vstack([_held_on_grid(s[0], s[col], grid) for s in series.values()])
            enough = np.sum(np.isfinite(stack), axis=0) >= 5
            with np.errstate(all="ignore"):
                p25, p50, p75 = (np.where(enough, np.nanpercentile(np.where(enough, stack, 0.0), q, axis=0), np.nan)
                                 for q in (25, 50, 75))
            ax.fill_between(grid, p25, p75, color="0.55", alpha=0.3, lw=0, zorder=1.5).set_gid(f"iqr/{name}")
            ax.plot(grid, p50, color="black", lw=1.1, zorder=2)[0].set_gid(f"median/{name}")
        run_handles += [Line2D([], [], color="black", lw=1.1, label=f"median of the {len(series)} runs"),
                        Patch(facecolor="0.55", alpha=0.3, label="middle half of the runs (25-75 %)")]
    if highlight in series:
        tr = traces[highlight]
        t, *values = series[highlight]
        for (ax, name, _), v in zip(panels, values):
            (line,) = ax.plot(t, v, color="tab:blue", lw=1.5 if others else 1.3, zorder=3)
            line.set_gid(f"{name}/{highlight}")
        source = _TARGET_SOURCE_LABEL.get(tr.target_source, f"from {tr.target_source}")
        what = f"run {run_label(tr)}" + (f" ({highlight_why})" if highlight_why else "")
        run_handles.insert(0, Line2D([], [], color="tab:blue", lw=1.5, label=f"{what}: {source} position"))
    if others:
        run_handles.insert(1, Line2D([], [], color=_OTHER_RUNS, lw=0.8, label=f"the {len(others)} other runs"))

    # References: the tree's set-point, the paper's, the paper's envelope, the camera's FOV edges.
    half_h, half_v, tilt = math.degrees(camera.hfov_rad / 2), math.degrees(camera.vfov_rad / 2), math.degrees(camera.tilt_rad)
    fov = {"color": "tab:green", "ls": "-.", "lw": 1.0, "zorder": 2.5}
    env = {"facecolor": "none", "edgecolor": "tab:orange", "hatch": "///", "lw": 0.0, "alpha": 0.6, "zorder": 0.5}
    paper = {"color": "black", "ls": ":", "lw": 1.6, "zorder": 2.6}
    desired = {"color": "red", "ls": "--", "lw": 1.5, "zorder": 2.7}
    refs: dict = {}
    refs[ax_az] = []
    if math.isfinite(desired_el) or math.isfinite(desired_range):  # a tree that follows: the target dead ahead
        ax_az.axhline(0.0, **desired).set_gid("desired/azimuth")
        refs[ax_az].append(Line2D([], [], **desired, label="desired by the tree: dead ahead (0 deg)"))
    for sign in (-1, 1):
        ax_az.axhline(sign * half_h, **fov).set_gid(f"fov/azimuth/{sign}")
    refs[ax_az].append(Line2D([], [], **fov, label=f"camera FOV edges (+-{half_h:.0f} deg)"))
    ax_el.axhspan(*PAPER_ENVELOPE_ELEVATION_DEG, **env).set_gid("envelope/elevation")
    ax_el.axhline(PAPER_FOLLOW_ELEVATION_DEG, **paper).set_gid("paper/elevation")
    for sign in (-1, 1):
        ax_el.axhline(tilt + sign * half_v, **fov).set_gid(f"fov/elevation/{sign}")
    refs[ax_el] = []
    if math.isfinite(desired_el):
        ax_el.axhline(math.degrees(desired_el), **desired).set_gid("desired/elevation")
        refs[ax_el].append(Line2D([], [], **desired, label=f"desired by the tree: {math.degrees(desired_el):.0f} deg"))
    refs[ax_el] += [Line2D([], [], **paper, label=f"paper's set-point: {PAPER_FOLLOW_ELEVATION_DEG:.0f} deg"),
                    Patch(**{**env, "lw": 0.8},
                          label="paper's follow envelope: {:.0f}-{:.0f} deg".format(*PAPER_ENVELOPE_ELEVATION_DEG)),
                    Line2D([], [], **fov, label=f"camera FOV edges ({tilt - half_v:.0f} to {tilt + half_v:.0f} deg)")]
    ax_r.axhspan(*PAPER_ENVELOPE_RANGE_M, **env).set_gid("envelope/range")
    ax_r.axhline(PAPER_FOLLOW_RANGE_M, **paper).set_gid("paper/range")
    refs[ax_r] = []
    if math.isfinite(desired_range):
        ax_r.axhline(desired_range, **desired).set_gid("desired/range")
        refs[ax_r].append(Line2D([], [], **desired, label=f"desired by the tree: {desired_range:.0f} m"))
    refs[ax_r] += [Line2D([], [], **paper, label=f"paper's set-point: {PAPER_FOLLOW_RANGE_M:.0f} m"),
                   Patch(**{**env, "lw": 0.8}, label="paper's follow envelope: {:.0f}-{:.0f} m".format(*PAPER_ENVELOPE_RANGE_M))]
    ax_r.set_yscale("log")
    finite_r = np.concatenate([s[3][np.isfinite(s[3]) & (s[3] > 0)] for s in series.values()]) if series else np.zeros(0)
    r_lo = min(float(finite_r.min()) if len(finite_r) else 10.0, PAPER_ENVELOPE_RANGE_M[0],
               desired_range if math.isfinite(desired_range) else math.inf)
    r_hi = max(float(finite_r.max()) if len(finite_r) else 100.0, PAPER_ENVELOPE_RANGE_M[1])
    ax_r.set_ylim(max(r_lo / 1.3, 0.5), r_hi * 1.3)
    ticks = [v for v in (1, 2, 5, 10, 20, 30, 50, 100, 200, 500, 1000, 2000, 5000) if ax_r.get_ylim()[0] <= v <= ax_r.get_ylim()[1]]
    ax_r.set_yticks(ticks, [f"{v:g}" for v in ticks])
    ax_r.minorticks_off()
    ax_az.set_ylim(-185, 185)
    ax_az.set_yticks([-180, -90, -half_h, 0, half_h, 90, 180])
    ax_az.set_yticklabels(["-180", "-90", f"{-half_h:.0f}", "0", f"{half_h:.0f}", "90", "180"])
    ax_az.set_ylabel("target azimuth off\nthe nose (deg, + left)")
    ax_el.set_ylabel("target elevation\n(deg, + below the ownship)")
    ax_r.set_ylabel("slant range to\nthe target (m, log scale)")
    if run_handles:
        _outside(ax_az, run_handles, "runs" if others else "run")
    for ax in (ax_az, ax_el, ax_r):
        ax.grid(True, alpha=0.3)
        if ax is ax_az and run_handles:
            _outside(ax, refs[ax], "reference", anchor=(1.02, 0.0), loc="lower left")
        else:
            _outside(ax, refs[ax], "reference")

    # The strip: the highlighted run's phases, target in the FOV, true detections.
    rows = (("phase", 2.0), ("target in FOV", 1.0), ("true detection", 0.0))
    strip_handles: dict[str, Patch] = {}
    if highlight in series:
        tr = traces[highlight]
        t = series[highlight][0]
        ends = np.append(t[1:], t[-1] + (t[-1] - t[-2] if len(t) > 1 else 0.1))
        phased = has_phases(tr)
        phases = tr.phase if phased else ["flight"] * len(tr)
        for phase, i0, i1 in phase_segments(phases):
            ax_strip.broken_barh([(t[i0], ends[i1 - 1] - t[i0])], (1.6, 0.8), color=phase_colour(phase), gid=f"strip/phase/{phase}")
            strip_handles.setdefault(phase, Patch(color=phase_colour(phase),
                                                  label=phase_name(phase) if phased else "no mission phases recorded"))
        for (name, y), values in zip(rows[1:], (tr.in_fov, tr.detected)):
            v = np.asarray(values, float)
            if len(v) != len(t) or not np.isfinite(v).any():
                ax_strip.text(0.5, y + 0.0, f"{name}: not scored (needs the truth)", transform=ax_strip.get_yaxis_transform(),
                              fontsize=7, va="center", ha="left", color="0.35")
                continue
            for flag, colour, word in ((v > 0.5, _YES, "yes"), (v <= 0.5, _NO, "no")):
                spans = [(t[i0], ends[i1 - 1] - t[i0]) for i0, i1 in _intervals(flag & np.isfinite(v))]
                ax_strip.broken_barh(spans, (y - 0.4, 0.8), color=colour, gid=f"strip/{name}/{word}")
    ax_strip.set_ylim(-0.6, 2.6)
    ax_strip.set_yticks([y for _, y in rows])
    ax_strip.set_yticklabels([n for n, _ in rows], fontsize=7)
    ax_strip.set_ylabel("highlighted run" if others else "this run", fontsize=8)
    ax_strip.grid(True, axis="x", alpha=0.3)
    strip_legend = list(strip_handles.values()) + [Patch(color=_YES, label="in FOV / detected: yes"),
                                                   Patch(color=_NO, label="no (blank: not scored)")]
    _outside(ax_strip, strip_legend, "phase; in FOV / detected", ncol=2)
    ax_strip.set_xlabel(f"time from {_EVENT_NOUNS.get(align_event, align_event)} (s)" if align_event else "mission time (s)")
    n = len(series)
    fig.suptitle(title or f"target relative to the ownship ({n} run{'s' if n != 1 else ''})", fontsize=11)
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
        ax.set_title(f"t = {snap.t:.1f} s" + (f", belief mass {total:.3g}" if abs(total - 1.0) > 1e-3 else ""), fontsize=9)
        ax.set_xlabel("east of home (m)", fontsize=8)
        ax.set_ylabel("north of home (m)", fontsize=8)
    if snaps and len(trace):
        handles = [Line2D([], [], color="white", lw=1.0, label="ownship track so far"),
                   Line2D([], [], ls="", marker="^", color="white", mec="black", ms=7, label="ownship then"),
                   Line2D([], [], ls="", marker="x", color="tab:orange", ms=8, mew=2, label="target then (where known)")]
        fig.legend(handles=handles, loc="outside lower center", ncol=3, title="on each map", facecolor="0.8", **_LEGEND)
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
    acquired) are left out of that key's curve, and the legend says how many of all runs it holds.
    Only keys some run has get a panel; with none (a patrol: no target, no radar validation) the
    figure is one panel that says so. The curve ``cdf/<key>`` steps to ``i/n`` at the ``i``-th
    smallest value.
    """
    values_of: dict[str, np.ndarray] = {}
    for key in keys:
        v = [float(r[key]) for r in rows if r.get(key) is not None and math.isfinite(float(r[key]))]
        if v:
            values_of[key] = np.sort(v)
    drawn = [k for k in keys if k in values_of]
    missing = [k for k in keys if k not in values_of]
    if not drawn:
        fig, ax = plt.subplots(figsize=(7.0, 3.0), layout="constrained")
        ax.axis("off")
        ax.text(0.5, 0.5, f"no data: none of the {len(rows)} run{'s' if len(rows) != 1 else ''} has a value for\n"
                + "\n".join(f"{METRIC_LABELS.get(k, k)} [{k}]" for k in keys)
                + "\n(no target to acquire, or no radar validation, in this campaign)",
                ha="center", va="center", transform=ax.transAxes, fontsize=9, gid="no_data")
        fig.suptitle(title or f"campaign: {len(rows)} runs")
        return fig
    cols = min(len(drawn), 3)
    nrows = math.ceil(len(drawn) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.4 * cols, 3.5 * nrows), squeeze=False, layout="constrained")
    for ax in axes.flat[len(drawn):]:
        ax.axis("off")
    for ax, key in zip(axes.flat, drawn):
        values = values_of[key]
        n = len(values)
        x = np.concatenate([[values[0]], values])
        y = np.arange(n + 1) / n
        (line,) = ax.step(x, y, where="post", color="tab:blue", label=f"the runs with a value ({n} of {len(rows)})")
        line.set_gid(f"cdf/{key}")
        ax.axvline(float(np.median(values)), color="tab:blue", ls=":", lw=1.0, label=f"their median: {np.median(values):.3g}")
        if key in paper:
            ax.axvline(paper[key], color="red", ls="--", lw=1.5, label=f"the paper: {paper[key]:g}").set_gid(f"paper/{key}")
        if key.endswith("_frac"):
            ax.set_xlim(-0.02, 1.02)
        ax.set_xlabel(METRIC_LABELS.get(key, key))
        ax.set_ylabel("share of runs at or below (0-1)")
        ax.set_ylim(0.0, 1.02)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.28), title=key, **_LEGEND)
    fig.suptitle((title or f"campaign: {len(rows)} runs")
                 + (f"\nno data (no run has a value): {', '.join(missing)}" if missing else ""))
    return fig
