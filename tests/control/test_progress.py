"""The stall bound of a movement: hand-worked sequences of distance to go, and of a moving goal."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

import numpy as np

from chaser_bt.control.progress import ClosingWatch, ProgressWatch


def test_steady_approach_never_stalls():
    watch = ProgressWatch(window_s=5.0, min_progress_m=2.0)
    for k in range(100):  # 1 m/s toward a point 100 m away, observed at 10 Hz
        t = 0.1 * k
        watch.observe(t, 100.0 - t)
        assert not watch.stalled(t)


def test_holding_short_of_a_refused_target_stalls_after_the_window():
    watch = ProgressWatch(window_s=5.0, min_progress_m=2.0)
    watch.observe(0.0, 100.0)
    for t in (1.0, 3.0, 5.0):
        watch.observe(t, 99.5)  # hovering over home: the fence refused the target
        assert not watch.stalled(t)
    watch.observe(5.1, 99.0)
    assert watch.stalled(5.1) and math.isclose(watch.since_s(5.1), 5.1)


def test_creeping_counts_once_it_adds_up_to_the_minimum():
    watch = ProgressWatch(window_s=5.0, min_progress_m=2.0)
    watch.observe(0.0, 100.0)
    watch.observe(4.0, 99.0)  # 1 m: not yet progress
    watch.observe(4.9, 97.9)  # 2.1 m below the anchor: progress at 4.9 s
    assert not watch.stalled(9.8) and watch.stalled(10.0)


def test_missing_positions_are_neither_progress_nor_stall_evidence():
    watch = ProgressWatch(window_s=5.0)
    assert not watch.stalled(100.0)  # nothing observed yet
    watch.observe(0.0, math.nan)
    assert not watch.stalled(100.0)


def test_a_zero_window_never_stalls():
    watch = ProgressWatch(window_s=0.0)
    watch.observe(0.0, 10.0)
    assert not watch.stalled(1e6)


@given(st.lists(st.floats(0.0, 1000.0), min_size=1, max_size=60))
def test_a_stall_means_no_drop_of_the_minimum_within_the_window(distances):
    # Brute force: at 1 Hz, stalled at t iff no sample since the last anchor beat it by min_progress_m.
    watch = ProgressWatch(window_s=5.0, min_progress_m=2.0)
    anchor_t, anchor_d = None, math.inf
    for t, d in enumerate(distances):
        watch.observe(float(t), d)
        if anchor_t is None or d < anchor_d - 2.0:
            anchor_t, anchor_d = t, d
        assert watch.stalled(float(t)) == (t - anchor_t > 5.0)


def test_keeping_range_on_a_fleeing_goal_is_progress():
    # The goal runs east at 10 m/s 100 m ahead; the vehicle matches it: the range never falls, yet it
    # flies 10 m/s straight at the goal.
    watch = ClosingWatch(window_s=5.0)
    for k in range(200):
        t = 0.1 * k
        watch.observe(t, [10.0 * t, 0.0, 20.0], [100.0 + 10.0 * t, 0.0, 20.0])
        assert not watch.stalled(t)
    assert abs(watch.closed_m - 199.0) < 1e-9  # 199 steps of 1 m


def test_a_vehicle_held_in_place_stalls_however_the_goal_moves():
    watch = ClosingWatch(window_s=5.0)
    for k in range(52):
        t = 0.1 * k
        watch.observe(t, [0.0, 0.0, 20.0], [100.0, 10.0 * t, 20.0])  # the fence holds it; the cue swings north
    assert watch.closed_m == 0.0 and watch.stalled(5.1) and not watch.stalled(5.0)


def test_flying_away_from_the_goal_is_no_progress():
    watch = ClosingWatch(window_s=5.0)
    for k in range(61):
        t = 0.1 * k
        watch.observe(t, [-5.0 * t, 0.0, 20.0], [100.0, 0.0, 20.0])  # wind pushes it west at 5 m/s
    assert abs(watch.closed_m + 30.0) < 1e-9 and watch.stalled(6.0)


def test_holding_at_the_goal_is_where_it_was_sent():
    watch = ClosingWatch(window_s=5.0, near_m=5.0)
    for k in range(300):
        t = 0.1 * k
        watch.observe(t, [0.0, 0.0, 20.0], [3.0, 0.0, 21.0])  # 3.2 m off the standoff point, hovering
        assert not watch.stalled(t)


def test_positions_unknown_are_skipped():
    watch = ClosingWatch(window_s=5.0)
    watch.observe(0.0, [np.nan, 0.0, 0.0], [100.0, 0.0, 0.0])
    assert not watch.stalled(100.0) and watch.closed_m == 0.0
