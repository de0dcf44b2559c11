"""The paper's figures draw exactly the trace's data: checked against hand-worked geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from matplotlib.legend import Legend

from chaser_bt.log.figures import (
    PAPER_VALUES,
    phase_segments,
    plot_belief_snapshots,
    plot_metric_cdfs,
    plot_overhead,
    plot_relative_geometry,
    save_figure,
)
from chaser_bt.log.trace import BeliefSnapshot, FlightTrace, TraceEvent


def _lines(fig, gid_prefix: str):
    return {ln.get_gid(): ln for ax in fig.axes for ln in ax.get_lines() if (ln.get_gid() or "").startswith(gid_prefix)}


def _square_trace() -> FlightTrace:
    t = np.arange(5) * 0.5
    own = np.array([[0, 0, 0], [0, 0, 10], [10, 0, 20], [10, 10, 20], [0, 10, 20]], float)
    target = np.array([[np.nan] * 3, [50, 0, 20], [50, 5, 20], [50, 10, 20], [50, 15, 20]], float)
    return FlightTrace(
        t=t, ownship_enu=own, ownship_yaw_rad=np.zeros(5), target_enu=target,
        in_fov=np.full(5, np.nan), detected=np.full(5, np.nan),
        mode=["GUIDED"] * 5, phase=["climb", "climb", "cue", "cue", "climb"], tip=[""] * 5,
        events=[TraceEvent(0.5, "airborne"), TraceEvent(1.0, "phase", "cue"), TraceEvent(1.9, "acquired")],
    )


def test_phase_segments_are_maximal_runs():
    assert phase_segments(["a", "a", "b", "b", "a"]) == [("a", 0, 2), ("b", 2, 4), ("a", 4, 5)]
    assert phase_segments(["x"]) == [("x", 0, 1)]
    assert phase_segments([]) == []


def test_overhead_draws_each_phase_segment_joined_to_the_next_and_the_target():
    tr = _square_trace()
    fig = plot_overhead([tr])
    ax = fig.axes[0]
    own = [ln for ln in ax.get_lines() if (ln.get_gid() or "").startswith("ownship/0/")]
    # Segments [0, 2), [2, 4), [4, 5), each carried one sample into the next.
    assert [ln.get_gid() for ln in own] == ["ownship/0/climb", "ownship/0/cue", "ownship/0/climb"]
    np.testing.assert_array_equal(np.column_stack(own[0].get_data()), tr.ownship_enu[0:3, :2])
    np.testing.assert_array_equal(np.column_stack(own[1].get_data()), tr.ownship_enu[2:5, :2])
    np.testing.assert_array_equal(np.column_stack(own[2].get_data()), tr.ownship_enu[4:5, :2])
    assert own[0].get_color() == own[2].get_color() != own[1].get_color()  # one colour per phase
    target = _lines(fig, "target/")["target/0"]
    np.testing.assert_array_equal(np.column_stack(target.get_data()), tr.target_enu[:, :2])
    # Events sit on the ownship sample at (or just after) their time: 0.5 s -> sample 1, 1.9 s -> sample 4.
    events = _lines(fig, "event/")
    assert set(events) == {"event/0/airborne", "event/0/acquired"}  # phase changes are the colours, not marks
    assert np.column_stack(events["event/0/airborne"].get_data()).tolist() == [[0.0, 0.0]]
    assert np.column_stack(events["event/0/acquired"].get_data()).tolist() == [[0.0, 10.0]]
    assert sorted(t.get_text() for t in ax.texts) == ["acquired", "airborne"]  # named for a single trace


def test_overhead_of_many_traces_draws_one_in_phases_and_the_others_grey():
    fig = plot_overhead([_square_trace(), _square_trace(), _square_trace()], highlight=2)
    assert set(_lines(fig, "target/")) == {"target/2"}  # the highlighted run's target only
    others = _lines(fig, "ownship/")
    assert {"ownship/0/other", "ownship/1/other", "ownship/2/climb", "ownship/2/cue"} == set(others)
    np.testing.assert_array_equal(np.column_stack(others["ownship/0/other"].get_data()), _square_trace().ownship_enu[:, :2])
    assert set(_lines(fig, "event/")) == {"event/2/airborne", "event/2/acquired"}  # only its events, named
    assert sorted(t.get_text() for t in fig.axes[0].texts) == ["acquired", "airborne"]


def test_relative_geometry_matches_hand_worked_angles_and_ranges():
    # Ownship at 20 m, yaw 90 deg (north). Targets: 10 m north and 10 m below -> az 0, el +45, r 14.14;
    # 10 m east at the same height -> az -90 (to the right of a north heading), el 0, r 10; unknown -> NaN.
    own = np.array([[0, 0, 20]] * 3, float)
    target = np.array([[0, 10, 10], [10, 0, 20], [np.nan] * 3], float)
    tr = FlightTrace(t=np.array([10.0, 10.2, 10.4]), ownship_enu=own, ownship_yaw_rad=np.full(3, math.pi / 2),
                     target_enu=target, in_fov=np.ones(3), detected=np.array([1.0, 0.0, np.nan]),
                     desired_range_m=40.0, desired_elevation_rad=math.radians(40.0),
                     events=[TraceEvent(10.2, "acquired")])
    fig = plot_relative_geometry([tr])
    lines = _lines(fig, "")
    az, el, r = (lines[f"{n}/0"].get_ydata() for n in ("azimuth", "elevation", "range"))
    np.testing.assert_allclose(az[:2], [0.0, -90.0], atol=1e-9)
    np.testing.assert_allclose(el[:2], [45.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(r[:2], [math.sqrt(200.0), 10.0])
    assert np.isnan(az[2]) and np.isnan(r[2])
    np.testing.assert_allclose(lines["azimuth/0"].get_xdata(), [10.0, 10.2, 10.4])
    assert lines["desired/range"].get_ydata()[0] == 40.0
    assert lines["desired/elevation"].get_ydata()[0] == pytest.approx(40.0)
    assert lines["desired/azimuth"].get_ydata()[0] == 0.0
    # Aligned on acquisition: time runs from the event; a trace without it is left out.
    other = FlightTrace(t=np.array([0.0]), ownship_enu=np.zeros((1, 3)), ownship_yaw_rad=np.zeros(1),
                        target_enu=np.ones((1, 3)), in_fov=np.ones(1), detected=np.ones(1))
    fig = plot_relative_geometry([tr, other], align_event="acquired")
    lines = _lines(fig, "azimuth/")
    assert set(lines) == {"azimuth/0"}
    np.testing.assert_allclose(lines["azimuth/0"].get_xdata(), [-0.2, 0.0, 0.2], atol=1e-12)


def test_belief_snapshots_show_the_mass_with_x_along_columns():
    x, y = np.array([0.0, 10.0, 20.0]), np.array([0.0, 10.0])
    mass = np.array([[0.1, 0.0], [0.2, 0.3], [0.0, 0.4]])  # mass[i, j] over (x_i, y_j)
    snaps = [BeliefSnapshot(float(k), x, y, mass * (k + 1)) for k in range(8)]
    tr = FlightTrace(t=np.arange(8.0), ownship_enu=np.zeros((8, 3)), ownship_yaw_rad=np.zeros(8),
                     target_enu=np.full((8, 3), np.nan), in_fov=np.full(8, np.nan), detected=np.full(8, np.nan),
                     beliefs=snaps)
    fig = plot_belief_snapshots(tr, max_panels=3)
    images = [im for ax in fig.axes for im in ax.get_images()]
    # Three snapshots evenly chosen: indices 0, 4 (3.5 rounds to even), 7.
    assert [im.get_gid() for im in images] == ["belief/0", "belief/4", "belief/7"]
    np.testing.assert_allclose(images[2].get_array(), mass.T / mass.sum())  # normalised: one scale for logs and reports
    assert fig.axes[0].get_title() == "t = 0.0 s"  # mass 1.0
    assert [ax.get_title() for ax in fig.axes if ax.get_images()][2] == "t = 7.0 s, belief mass 8"
    assert images[0].get_extent() == [-5.0, 25.0, -5.0, 15.0]


def test_cdfs_step_through_each_value_and_mark_the_paper():
    rows = [{"t_acquire_s": 3.0}, {"t_acquire_s": 1.0}, {"t_acquire_s": 2.0}, {"t_acquire_s": None}, {}]
    fig = plot_metric_cdfs(rows, keys=("t_acquire_s", "detection_frac"))
    lines = _lines(fig, "")
    cdf = lines["cdf/t_acquire_s"]
    np.testing.assert_allclose(cdf.get_xdata(), [1.0, 1.0, 2.0, 3.0])
    np.testing.assert_allclose(cdf.get_ydata(), [0.0, 1 / 3, 2 / 3, 1.0])
    assert lines["paper/t_acquire_s"].get_xdata()[0] == PAPER_VALUES["t_acquire_s"] == 4.95
    assert "cdf/detection_frac" not in lines and "paper/detection_frac" not in lines  # no run has it: no panel
    assert fig.get_suptitle().endswith("no data (no run has a value): detection_frac")  # ... and the figure says so


def test_save_figure_writes_a_png(tmp_path):
    path = tmp_path / "o.png"
    save_figure(plot_overhead([_square_trace()]), path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _axes_are_labelled(fig) -> None:
    for ax in fig.axes:
        if not ax.axison or ax.get_label() == "<colorbar>":
            continue
        assert ax.get_ylabel(), f"{ax.get_title()}: no y label"
    bottoms = [ax for ax in fig.axes if ax.axison and ax.get_label() != "<colorbar>" and ax.get_xlabel()]
    assert bottoms, "no x label"


def test_overhead_renders_with_labelled_axes_and_one_label_per_place(tmp_path):
    tr = _square_trace()
    tr.events.extend([TraceEvent(0.0, "armed"), TraceEvent(0.0, "takeoff")])  # at home, where "airborne" is too
    fig = plot_overhead([tr])
    _axes_are_labelled(fig)
    labels = [t.get_text() for t in fig.axes[0].texts]
    assert labels == ["airborne, armed, takeoff", "acquired"]
    save_figure(fig, tmp_path / "o.png")


def test_overhead_legend_names_only_the_phases_drawn():
    tr = _square_trace()
    tr.phase[-1] = "land"  # one sample at the end: nothing to draw
    legends = {lg.get_title().get_text(): [t.get_text() for t in lg.get_texts()] for lg in plot_overhead([tr]).findobj(Legend)}
    assert legends["mission phase"] == ["climb", "cue"]
    assert "events (named)" in legends["also drawn"] and "home" in legends["also drawn"]


def test_relative_geometry_renders_labelled_and_names_the_target_source(tmp_path):
    tr = _square_trace()
    tr.target_source = "telemetry"
    fig = plot_relative_geometry([tr])
    _axes_are_labelled(fig)
    legend = next(lg for lg in fig.findobj(Legend) if lg.get_title().get_text() == "run")
    assert [t.get_text() for t in legend.get_texts()] == ["run the run: from the intruder's telemetry position"]
    save_figure(fig, tmp_path / "g.png")


def test_belief_snapshots_render_labelled_with_a_colour_bar_label(tmp_path):
    x, y = np.array([0.0, 10.0]), np.array([0.0, 10.0])
    tr = FlightTrace(t=np.arange(2.0), ownship_enu=np.zeros((2, 3)), ownship_yaw_rad=np.zeros(2),
                     target_enu=np.full((2, 3), np.nan), in_fov=np.full(2, np.nan), detected=np.full(2, np.nan),
                     beliefs=[BeliefSnapshot(0.0, x, y, np.full((2, 2), 0.25))])
    fig = plot_belief_snapshots(tr)
    _axes_are_labelled(fig)
    assert any(ax.get_ylabel() == "share of the belief per cell" for ax in fig.axes if ax.get_label() == "<colorbar>")
    save_figure(fig, tmp_path / "b.png")


def test_cdfs_render_with_axis_labels_in_words_and_units(tmp_path):
    fig = plot_metric_cdfs([{"t_acquire_s": 3.0}, {"t_acquire_s": 1.0}], keys=("t_acquire_s",))
    _axes_are_labelled(fig)
    assert fig.axes[0].get_xlabel() == "take-off altitude to first acquisition (s)"
    save_figure(fig, tmp_path / "c.png")


def test_overhead_of_a_search_and_rescue_trace_draws_the_person_and_the_find():
    tr = _square_trace()
    tr.meta.update(people_enu=[[30.0, 40.0, 0.0]], find_enu=[30.5, 39.0, 0.0])
    lines = _lines(plot_overhead([tr]), "")
    assert list(lines["person/0"].get_xydata()[0]) == [30.0, 40.0]
    assert list(lines["find/0"].get_xydata()[0]) == [30.5, 39.0]
