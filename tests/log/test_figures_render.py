"""Every picture a user sees, rendered from small hand-made traces and checked as a reader would:
files written, panels there, every axis labelled with its unit, every legend titled and off the
data, one run readable among 50, phases (never flight modes) coloured, the paper's follow geometry
beside the tree's; and the rehearsal's animation: frames kept in a bounded window, the GIF's frames
and size."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.legend import Legend
from PIL import Image

from chaser_bt.log.animation import ANIMATION_DPI, FrameKeeper, animation_figure, snapshot, write_animation
from chaser_bt.log.figures import (
    PHASE_COLOURS,
    has_phases,
    phase_colour,
    plot_belief_snapshots,
    plot_metric_cdfs,
    plot_overhead,
    plot_relative_geometry,
    save_figure,
    select_run,
)
from chaser_bt.log.trace import BeliefSnapshot, CameraSnapshot, FlightTrace, TraceEvent

UNIT = re.compile(r"\((?:[^()]*\b)?(s|m|deg|0-1)\b[^()]*\)")  # "(s)", "(m, log scale)", "(deg, + left)", "(0-1)"
PHASES = ["wait"] * 10 + ["launch"] * 20 + ["fly_to_cue"] * 30 + ["follow"] * 40  # 100 ticks at 1 Hz


def _chase(seed: int = 0, n: int = 100, acquire_at: float | None = 60.0) -> FlightTrace:
    """A chase at 1 Hz: waits at home, climbs, flies north to a target circling 300 m out, follows it
    from about 24 m at 20 deg below; scored in-FOV and detections from the launch on."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    target = np.column_stack([20 * np.cos(t / 15), 300 + 20 * np.sin(t / 15), np.full(n, 10.0)])
    own = np.zeros((n, 3))
    for i in range(n):
        if i < 10:
            own[i] = [0, 0, 0]
        elif i < 30:
            own[i] = [0, 0, (i - 10) * 1.5]
        elif i < 60:
            own[i] = [0, (i - 30) * 9.0, 30.0]
        else:
            own[i] = target[i] - np.array([0, 22.5, -8.2]) + rng.normal(0, 1.0, 3)
    yaw = np.full(n, math.pi / 2)
    in_fov = np.where(t >= 10, 1.0, np.nan)
    detected = np.where(t >= 60, (rng.random(n) > 0.3).astype(float), np.where(t >= 10, 0.0, np.nan))
    events = [TraceEvent(29.0, "airborne"), TraceEvent(10.0, "phase", "launch"), TraceEvent(12.0, "mode", "GUIDED"),
              TraceEvent(40.0, "custody", "track 7")]
    if acquire_at is not None:
        events.append(TraceEvent(acquire_at + seed % 5, "acquired"))
    return FlightTrace(t=t, ownship_enu=own, ownship_yaw_rad=yaw, target_enu=target, in_fov=in_fov, detected=detected,
                       mode=["STABILIZE"] * 10 + ["GUIDED"] * (n - 10), phase=list(PHASES[:n]), tip=[""] * n,
                       events=sorted(events, key=lambda e: e.t), desired_range_m=24.0,
                       desired_elevation_rad=math.radians(20.0), meta={"scenario": "chase", "seed": seed})


def _legends(fig) -> list[Legend]:
    return list(fig.findobj(Legend))


def _check_reader_friendly(fig, outside: bool = True) -> None:
    """Every data axes: y label with a unit; some x label with a unit; every legend titled and, with
    ``outside``, clear of every data axes."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    data_axes = [ax for ax in fig.axes if ax.axison and ax.get_label() != "<colorbar>"]
    assert data_axes
    for ax in data_axes:
        assert ax.get_ylabel(), f"{ax.get_title()!r}: no y label"
    xlabels = [ax.get_xlabel() for ax in data_axes if ax.get_xlabel()]
    assert xlabels and all(UNIT.search(x) for x in xlabels), xlabels
    legends = _legends(fig)
    assert legends
    for lg in legends:
        assert lg.get_title().get_text(), f"untitled legend: {[t.get_text() for t in lg.get_texts()]}"
        if outside:
            box = lg.get_window_extent(renderer)
            for ax in data_axes:
                assert not box.overlaps(ax.get_window_extent(renderer)), f"legend {lg.get_title().get_text()!r} over the data"


def _labels(fig) -> list[str]:
    return [t.get_text() for lg in _legends(fig) for t in lg.get_texts()]


# -- overhead ----------------------------------------------------------------------------------


def test_overhead_of_one_rehearsal_colours_phases_and_keeps_the_legend_off_the_map(tmp_path):
    fig = plot_overhead([_chase()])
    _check_reader_friendly(fig)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "east of home (m)" and ax.get_ylabel() == "north of home (m)"
    titles = {lg.get_title().get_text(): [t.get_text() for t in lg.get_texts()] for lg in _legends(fig)}
    assert titles["mission phase"] == ["fly_to_cue", "follow"]  # wait and the launch's straight climb: no track seen from above
    assert titles["also drawn"] == ["target (true)", "events (named)", "home"]
    for phase in ("fly_to_cue", "follow"):
        line = next(ln for ln in ax.get_lines() if ln.get_gid() == f"ownship/0/{phase}")
        assert to_rgba(line.get_color()) == to_rgba(PHASE_COLOURS[phase])
    # custody changes, phase and mode changes are not marked; the rest are, and named
    assert sorted(t.get_text() for t in ax.texts) == ["acquired", "airborne"]
    save_figure(fig, tmp_path / "overhead.png")
    assert (tmp_path / "overhead.png").stat().st_size > 10_000


def test_overhead_of_50_runs_draws_one_run_strong_and_49_thin_grey_lines(tmp_path):
    traces = [_chase(seed) for seed in range(50)]
    fig = plot_overhead(traces, highlight=7, highlight_why="median acquisition time")
    _check_reader_friendly(fig)
    ax = fig.axes[0]
    grey = [ln for ln in ax.get_lines() if (ln.get_gid() or "").endswith("/other")]
    assert len(grey) == 49 and all(ln.get_linewidth() < 1.0 and ln.get_alpha() <= 0.3 for ln in grey)
    strong = [ln for ln in ax.get_lines() if re.fullmatch(r"ownship/7/\w+", ln.get_gid() or "")]
    assert {ln.get_gid() for ln in strong} == {"ownship/7/wait", "ownship/7/launch", "ownship/7/fly_to_cue", "ownship/7/follow"}
    assert all(ln.get_linewidth() >= 2.0 for ln in strong)
    assert [ln.get_gid() for ln in ax.get_lines() if (ln.get_gid() or "").startswith(("target/", "event/"))] == [
        "target/7", "event/7/airborne", "event/7/acquired"]  # only the highlighted run's target and events
    titles = [lg.get_title().get_text() for lg in _legends(fig)]
    assert "mission phase, run chase seed 7\n(median acquisition time)" in titles
    assert "other runs' tracks (49)" in _labels(fig)
    save_figure(fig, tmp_path / "overhead50.png")


def test_overhead_default_highlight_is_the_median_run_by_acquisition():
    traces = [_chase(seed, acquire_at=a) for seed, a in ((0, 80.0), (5, 40.0), (10, 60.0), (15, None))]
    fig = plot_overhead(traces)  # acquisitions at 80, 40, 60 s (seed % 5 == 0): median 60 s is run 2
    assert "ownship/2/follow" in {ln.get_gid() for ln in fig.axes[0].get_lines()}
    assert select_run([80.0, None, 40.0, 60.0, float("nan")]) == 3
    assert select_run([None, float("nan")]) is None


def test_a_log_without_mission_phases_is_not_coloured_by_flight_mode():
    tr = _chase()
    tr.phase = list(tr.mode)  # what a log of a tree that never writes /mission/phase carries
    tr.events = [e for e in tr.events if e.name != "phase"]
    assert not has_phases(tr) and has_phases(_chase())
    fig = plot_overhead([tr])
    own = [ln for ln in fig.axes[0].get_lines() if (ln.get_gid() or "").startswith("ownship/")]
    assert [ln.get_gid() for ln in own] == ["ownship/0/flight"]  # one colour, not STABILIZE / GUIDED
    assert "ownship (no mission phases recorded)" in _labels(fig)
    assert not any(lbl in ("GUIDED", "STABILIZE") for lbl in _labels(fig))
    assert "mode GUIDED, airborne" in [t.get_text() for t in fig.axes[0].texts]  # mode changes become events (both at home)
    # With phases, the colours follow the phases even where the mode stays the same.
    fig = plot_overhead([_chase()])
    colours = {ln.get_gid(): ln.get_color() for ln in fig.axes[0].get_lines() if (ln.get_gid() or "").startswith("ownship/")}
    assert colours["ownship/0/fly_to_cue"] != colours["ownship/0/follow"]  # both GUIDED
    assert phase_colour("safety:geofence") == phase_colour("safety:battery") != phase_colour("follow")


# -- relative geometry ----------------------------------------------------------------------------


def test_relative_geometry_of_one_run_relates_the_tree_to_the_paper_with_units_and_titled_legends(tmp_path):
    fig = plot_relative_geometry([_chase()])
    _check_reader_friendly(fig)
    ax_az, ax_el, ax_r, ax_strip = fig.axes
    assert "(deg" in ax_az.get_ylabel() and "(deg" in ax_el.get_ylabel() and "(m" in ax_r.get_ylabel()
    assert ax_strip.get_xlabel() == "mission time (s)"
    labels = _labels(fig)
    for wanted in ("desired by the tree: 24 m", "paper's set-point: 40 m", "paper's follow envelope: 30-50 m",
                   "desired by the tree: 20 deg", "paper's set-point: 40 deg", "paper's follow envelope: 30-50 deg"):
        assert wanted in labels, wanted
    assert not any("sensor range" in lbl for lbl in labels)  # the old, wrong band is gone
    # The envelope bands span 30-50 (deg, m) and are hatched, not tinted: no colour the legend lacks.
    for ax, gid in ((ax_el, "envelope/elevation"), (ax_r, "envelope/range")):
        band = next(p for p in ax.patches if p.get_gid() == gid)
        ys = band.get_path().transformed(band.get_patch_transform()).vertices[:, 1]
        assert (ys.min(), ys.max()) == pytest.approx((30.0, 50.0))
        assert band.get_hatch() and band.get_facecolor()[3] == 0.0
    lines = {ln.get_gid(): ln for ax in fig.axes for ln in ax.get_lines()}
    assert lines["desired/range"].get_ydata()[0] == 24.0 and lines["paper/range"].get_ydata()[0] == 40.0
    assert lines["desired/elevation"].get_ydata()[0] == pytest.approx(20.0) and lines["paper/elevation"].get_ydata()[0] == 40.0
    assert ax_r.get_yscale() == "log"
    # No full-height shading: the detections live in the strip, with the phases.
    assert not any(c.get_gid() and c.get_gid().startswith("detection") for ax in fig.axes for c in ax.collections)
    strip = {c.get_gid() for c in ax_strip.collections}
    assert {"strip/phase/wait", "strip/phase/launch", "strip/phase/fly_to_cue", "strip/phase/follow",
            "strip/target in FOV/yes", "strip/true detection/yes", "strip/true detection/no"} <= strip
    assert {"wait", "follow", "in FOV / detected: yes"} <= set(labels)
    save_figure(fig, tmp_path / "geometry.png")


def test_relative_geometry_of_50_runs_shows_one_run_the_median_and_the_middle_half(tmp_path):
    traces = [_chase(seed) for seed in range(50)]
    fig = plot_relative_geometry(traces, align_event="acquired", highlight=3, highlight_why="median acquisition time")
    _check_reader_friendly(fig)
    ax_az, ax_el, ax_r, ax_strip = fig.axes
    assert ax_strip.get_xlabel() == "time from the first acquisition (s)"
    lines = {ln.get_gid(): ln for ax in fig.axes for ln in ax.get_lines()}
    assert lines["range/3"].get_linewidth() >= 1.5 and lines["range/3"].get_color() == "tab:blue"
    grey = [ln for gid, ln in lines.items() if gid.startswith("range/") and gid != "range/3"]
    assert len(grey) == 49 and all(ln.get_alpha() <= 0.3 and ln.get_linewidth() < 1.0 for ln in grey)
    # The median over the runs at each time: with every run following 22.5 m behind and 8.2 m above
    # (1 m noise), the median range after the acquisition is about sqrt(22.5^2 + 8.2^2) = 23.9 m.
    median = lines["median/range"]
    after = np.asarray(median.get_xdata()) > 5.0
    assert np.nanmedian(np.asarray(median.get_ydata())[after]) == pytest.approx(23.9, abs=1.0)
    assert {c.get_gid() for c in ax_r.collections} >= {"iqr/range"}
    runs = next(lg for lg in _legends(fig) if lg.get_title().get_text() == "runs")
    assert [t.get_text() for t in runs.get_texts()] == [
        "run chase seed 3 (median acquisition time): true position", "the 49 other runs",
        "median of the 50 runs", "middle half of the runs (25-75 %)"]
    save_figure(fig, tmp_path / "geometry50.png")


def test_relative_geometry_of_a_log_says_what_was_not_scored():
    tr = _chase()
    tr.in_fov = np.full(len(tr), np.nan)
    tr.detected = np.full(len(tr), np.nan)
    tr.target_source = "telemetry"
    fig = plot_relative_geometry([tr])
    texts = [t.get_text() for t in fig.axes[3].texts]
    assert "target in FOV: not scored (needs the truth)" in texts and "true detection: not scored (needs the truth)" in texts


# -- CDFs and belief ------------------------------------------------------------------------------


def test_cdfs_of_a_patrol_say_no_data_instead_of_five_empty_panels(tmp_path):
    rows = [{"t_airborne_s": None, "t_acquire_s": None, "target_in_fov_frac": None, "detection_frac": None,
             "radar_assoc_frac": None}] * 10
    fig = plot_metric_cdfs(rows)
    assert len(fig.axes) == 1 and not fig.axes[0].axison and not fig.axes[0].get_lines()
    text = fig.axes[0].texts[0].get_text()
    assert text.startswith("no data: none of the 10 runs has a value") and "t_acquire_s" in text
    save_figure(fig, tmp_path / "cdfs.png")


def test_cdfs_draw_only_the_panels_with_data_each_with_a_titled_legend(tmp_path):
    rows = [{"t_airborne_s": 11.0 + k, "t_acquire_s": 3.0 * k, "detection_frac": None} for k in range(5)]
    fig = plot_metric_cdfs(rows)
    drawn = [ax for ax in fig.axes if ax.axison]
    assert len(drawn) == 2
    _check_reader_friendly(fig, outside=False)
    assert [lg.get_title().get_text() for lg in _legends(fig)] == ["t_airborne_s", "t_acquire_s"]
    assert "no data (no run has a value): target_in_fov_frac, detection_frac, radar_assoc_frac" in fig.get_suptitle()
    save_figure(fig, tmp_path / "cdfs.png")


def test_belief_maps_have_one_titled_legend_off_the_maps(tmp_path):
    x, y = np.array([0.0, 10.0]), np.array([0.0, 10.0])
    tr = _chase()
    tr.beliefs = [BeliefSnapshot(float(k), x, y, np.full((2, 2), 0.25)) for k in (10, 50)]
    fig = plot_belief_snapshots(tr)
    _check_reader_friendly(fig)
    assert [lg.get_title().get_text() for lg in _legends(fig)] == ["on each map"]
    save_figure(fig, tmp_path / "belief.png")


# -- the animation ----------------------------------------------------------------------------------


def _frame(k: int, w: int = 640, h: int = 480) -> np.ndarray:
    image = np.full((h, w, 3), 90, np.uint8)
    image[200:220, 300 + k:330 + k] = (20, 20, 200)  # a red target moving right (BGR)
    return image


def test_the_keeper_holds_a_bounded_window_around_the_first_acquisition():
    keeper = FrameKeeper(every_s=0.2, before_s=2.0, after_s=3.0, width_px=160)
    kept = [keeper.offer(0.1 * i, _frame(i), (300 + i, 200, 330 + i, 220), (301 + i, 201, 329 + i, 219),
                         acquired=(i >= 100)) for i in range(200)]  # 10 Hz for 20 s, acquired at 10 s
    frames = keeper.snapshots()
    times = [f.t for f in frames]
    assert times[0] == pytest.approx(8.0) and times[-1] == pytest.approx(13.0)  # 2 s before, 3 s after
    assert np.allclose(np.diff(times), 0.2)  # every other frame: 5 per second
    assert len(frames) == 26 and sum(kept) < 200 and keeper.done
    f = frames[10]  # at 10.0 s: the acquisition
    assert f.image_bgr().shape == (120, 160, 3) and f.scale == 0.25
    assert f.track_box == pytest.approx((100.0, 50.0, 107.5, 55.0))  # (400, 200, 430, 220) scaled by 1/4
    assert f.zoom_bgr().shape[0] >= 32 and f.zoom_box is not None
    # Never acquired: the last before_s + after_s seconds.
    keeper = FrameKeeper(every_s=0.5, before_s=2.0, after_s=3.0)
    for i in range(100):
        keeper.offer(0.1 * i, _frame(0))
    assert [f.t for f in keeper.snapshots()][0] == pytest.approx(4.5) and len(keeper.snapshots()) == 11  # 4.5, 5.0 ... 9.5 s


def test_kept_frames_survive_save_and_load_and_old_traces_load_without_them(tmp_path):
    tr = _chase()
    tr.frames = [snapshot(60.0, _frame(0), (300, 200, 330, 220), None), snapshot(60.2, _frame(2), None, None)]
    loaded = FlightTrace.load(tr.save(tmp_path / "t.npz"))
    assert [f.t for f in loaded.frames] == [60.0, 60.2]
    assert loaded.frames[0].track_box == tr.frames[0].track_box and loaded.frames[0].truth_box is None
    assert loaded.frames[1].zoom_jpeg is None and loaded.frames[1].zoom_box is None
    np.testing.assert_array_equal(loaded.frames[0].image_bgr(), tr.frames[0].image_bgr())
    np.testing.assert_array_equal(loaded.frames[0].zoom_bgr(), tr.frames[0].zoom_bgr())
    # A trace written before frames were kept: its .npz has no frames_* arrays; it loads with none.
    old = _chase()
    with np.load(old.save(tmp_path / "old.npz")) as z:
        assert not any(k.startswith("frames") for k in z.files)
    assert FlightTrace.load(tmp_path / "old.npz").frames == []


def _animated_trace(n_frames: int = 12) -> FlightTrace:
    tr = _chase()
    tr.frames = [snapshot(55.0 + 0.2 * i, _frame(3 * i), (300 + 3 * i, 200, 330 + 3 * i, 220),
                          (301 + 3 * i, 201, 329 + 3 * i, 219) if i % 4 else None) for i in range(n_frames)]
    tr.frames[5] = CameraSnapshot(56.0, tr.frames[5].jpeg, None, None, None, None, tr.frames[5].scale)  # nothing seen
    return tr


def test_animation_figure_shows_the_camera_the_zoom_and_the_overhead():
    tr = _animated_trace()
    fig, draw = animation_figure(tr, title="Chase / chase / seed 0")
    assert [ax.get_label() for ax in fig.axes] == ["camera", "zoom", "overhead"]
    top = fig.axes[2]
    assert top.get_xlabel() == "east (m)" and top.get_ylabel() == "north (m)"
    assert sorted(lg.get_title().get_text() for lg in _legends(fig)) == ["boxes", "overhead"]
    draw(2)
    assert "mission time  55.4 s, -4.6 s from acquisition" in fig._suptitle.get_text()  # acquired at 60 s
    assert top.get_title() == "phase: fly_to_cue"
    zoom_text = fig.axes[1].texts[0]
    assert not zoom_text.get_visible()
    draw(5)  # no box at all: the zoom says so
    assert zoom_text.get_visible()


def test_write_animation_writes_a_small_gif_with_one_frame_per_kept_frame(tmp_path):
    tr = _animated_trace(12)
    path = write_animation(tr, tmp_path / "rehearsal.gif", fps=5)
    with Image.open(path) as gif:
        assert gif.format == "GIF" and gif.n_frames == 12
        assert gif.size == (round(9.0 * ANIMATION_DPI), round(3.3 * ANIMATION_DPI)) == (720, 264)
        assert gif.info["duration"] == 200 and gif.info.get("loop") == 0
    assert path.stat().st_size < 12 * 60_000
    with pytest.raises(ValueError, match="no camera frames"):
        write_animation(_chase(), tmp_path / "none.gif")


def test_the_rehearsal_report_writes_the_animation_and_shows_it_first(tmp_path):
    from sitl.bench.report import write_rehearsal_report

    tr = _animated_trace(6)
    report = {"outcome": "following", "tree": "Chase", "scenario": "chase", "seed": 0, "message": "following"}
    files = write_rehearsal_report(report, tmp_path / "r", trace=tr)
    assert files["animation"] == tmp_path / "r" / "rehearsal.gif"
    with Image.open(files["animation"]) as gif:
        assert gif.n_frames == 6
    md = files["markdown"].read_text()
    assert md.index("(rehearsal.gif)") < md.index("(overhead.png)")
    assert len(FlightTrace.load(files["trace"]).frames) == 6  # kept with the trace: the GIF can be drawn again


# -- a campaign's pictures --------------------------------------------------------------------------


def test_a_campaign_report_highlights_the_median_run_and_draws_a_failed_one(tmp_path):
    from sitl.bench.campaign import CampaignConfig, write_campaign_report

    out = tmp_path / "c"
    rows = []
    for seed in range(6):
        tr = _chase(seed)
        path = out / "runs" / "chase" / f"seed_{seed:04d}.npz"
        path.parent.mkdir(parents=True, exist_ok=True)
        tr.save(path)
        rows.append({"key": f"chase/seed_{seed:04d}", "seed": seed, "outcome": "following" if seed != 4 else "timeout",
                     "success": seed != 4, "t_acquire_s": [5.0, 1.0, 9.0, 3.0, 7.0, 2.0][seed],
                     "trace_file": str(path.relative_to(out))})
    config = CampaignConfig(tree=Path("trees/chase.yaml"), scenarios=[Path("chase.yaml")], seeds=list(range(6)), out_dir=out)
    agg = {"runs": 6, "success": 5, "success_frac": 5 / 6, "metrics": {}, "outcomes": {"following": 5, "timeout": 1},
           "by_scenario": {}, "false_successes": 0, "unsafe_ends": 0}
    files = write_campaign_report(config, rows, agg)
    assert {"cdfs", "overhead", "overhead_failed", "geometry"} <= set(files)
    md = files["markdown"].read_text()
    # acquisition times 5, 1, 9, 3, 7, 2 s: the (lower) median is 3 s, seed 3
    assert "Overhead track of run chase seed 3 (median acquisition time)" in md
    assert "Overhead track of run chase seed 4, the first that did not succeed (timeout)" in md
    assert json.loads(files["json"].read_text())["rows"][4]["outcome"] == "timeout"
    for name in ("overhead.png", "overhead_failed.png", "relative_geometry.png", "cdfs.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"
