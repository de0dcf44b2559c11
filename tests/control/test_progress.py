"""The stall bound of a movement: hand-worked sequences of distance to go."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from chaser_bt.control.progress import ProgressWatch


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
