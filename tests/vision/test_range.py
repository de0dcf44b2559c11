"""Range from box size (the paper's attempt) and the Kalman range filter."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chaser_bt.vision.range import TARGET_SPAN_M, RangeFilter, range_from_box
from sitl.world.camera.models import TARGET_MODELS


def test_range_from_a_centred_box_is_span_over_twice_the_half_angle_tangent():
    # fx = 100 px, box 20 px wide centred: half angle atan(0.1), range = 1 / (2 * 0.1) = 5 m.
    assert math.isclose(range_from_box((90.0, 0.0, 110.0, 5.0), 1.0, 100.0, 100.0), 5.0, rel_tol=1e-12)


def test_known_spans_cover_every_rendered_kind_and_lie_near_the_model_size():
    for kind, model in TARGET_MODELS.items():
        if kind == "person":  # standing (shoulders) to lying (full length): the median view lies between
            assert model.span_m < TARGET_SPAN_M[kind] < model.height_m
            continue
        assert 0.8 * model.span_m < TARGET_SPAN_M[kind] < 1.1 * model.span_m


def test_filter_beats_single_box_ranges_on_a_noisy_constant_range():
    rng = np.random.default_rng(1)
    f = RangeFilter(box_rel_std=0.15)
    raw, est = [], []
    for k in range(300):
        t = 0.1 * k
        f.predict(t, np.zeros(3), np.array([1.0, 0, 0]))
        z = 20.0 * (1 + rng.normal(0, 0.15))
        f.update_known(t, z, std_m=3.0)
        raw.append(abs(z - 20) / 20)
        if k > 30:
            est.append(abs(f.range_m - 20) / 20)
    assert np.median(est) < 0.4 * np.median(raw[30:])


def test_prediction_uses_ownship_closing_speed():
    f = RangeFilter()
    f.update_known(0.0, 30.0, std_m=0.1)
    f.predict(0.0, np.zeros(3), np.array([1.0, 0.0, 0.0]))
    f.predict(2.0, np.array([3.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]))  # flying at the target at 3 m/s
    assert f.range_m == pytest.approx(24.0, abs=1e-9)


def test_outlier_is_gated_and_a_persistent_change_restarts_the_filter():
    f = RangeFilter(box_rel_std=0.05)
    for k in range(10):
        f.update_known(0.1 * k, 10.0, std_m=0.2)
    assert not f.update_known(1.1, 40.0, std_m=0.2)
    assert f.range_m == pytest.approx(10.0, abs=0.1)
    for k in range(5):
        f.update_known(1.2 + 0.1 * k, 40.0, std_m=0.2)
    assert f.range_m == pytest.approx(40.0, abs=0.5)



def _dash(seed: int, radar: bool) -> np.ndarray:
    """A hovering target 40 m away dashes at the (hovering) camera at 8 m/s from t = 1 s. Box ranges
    with 12 % error at 10 Hz and, with ``radar``, the radar's radial speed (0.5 m/s error, told as 1).
    The range error (estimate - truth) each frame."""
    rng, f, bearing, errors = np.random.default_rng(seed), RangeFilter(), np.array([1.0, 0.0, 0.0]), []
    for k in range(40):
        t = 0.1 * k
        true = 40.0 - 8.0 * max(0.0, t - 1.0)
        f.predict(t, np.zeros(3), bearing)
        f.update_known(t, true * (1.0 + rng.normal(0.0, 0.12)), std_m=0.12 * true)
        if radar:
            f.update_radial_speed((-8.0 if t >= 1.0 else 0.0) + rng.normal(0.0, 0.5), 1.0)
        errors.append(f.range_m - true)
    return np.array(errors)


def test_the_radars_radial_speed_keeps_the_range_on_a_target_dashing_at_the_camera():
    """Box sizes alone learn the dash's speed slowly (the filter's target speed is a random walk), so the
    range reads long while the target closes: the chaser would not back off in time. With the radar's
    speed along the bearing the lag is gone. Mean error over 50 noisy runs, 0.5 s into the dash on."""
    boxes = np.mean([_dash(seed, False) for seed in range(50)], axis=0)[15:]
    both = np.mean([_dash(seed, True) for seed in range(50)], axis=0)[15:]
    assert boxes.mean() > 1.2  # long, as a lag reads it
    assert abs(both.mean()) < 0.45 * boxes.mean()


def test_a_radial_speed_alone_starts_nothing():
    f = RangeFilter()
    f.update_radial_speed(-5.0, 1.0)
    assert math.isnan(f.range_m)


def _far(radar: bool, wide: float) -> float:
    """A target 150 m away whose boxes are drawn ``wide`` times too wide (a few pixels: the detector's
    box is wider than the target), 12 % noise at 10 Hz, and with ``radar`` its radar range (6 m error)
    each frame. The estimate after 5 s."""
    rng, f, bearing = np.random.default_rng(3), RangeFilter(), np.array([1.0, 0.0, 0.0])
    for k in range(50):
        t = 0.1 * k
        f.predict(t, np.zeros(3), bearing)
        box = 150.0 / wide * (1.0 + rng.normal(0.0, 0.12))
        f.update_known(t, box, std_m=0.12 * box)
        if radar:
            f.fuse_range(150.0 + rng.normal(0.0, 6.0), 6.0)
    return f.range_m


def test_the_radars_range_corrects_a_distant_targets_short_box_range():
    assert _far(False, 1.5) == pytest.approx(100.0, rel=0.1)  # the boxes' bias, uncorrected
    assert _far(True, 1.5) == pytest.approx(150.0, rel=0.1)
    # Boxes reading it at 40 % of its range, confidently: a gate on their own error would drop the radar.
    assert _far(False, 2.5) == pytest.approx(60.0, rel=0.1)
    assert _far(True, 2.5) == pytest.approx(150.0, rel=0.15)


def test_a_radar_range_of_another_object_is_dropped_and_never_restarts_the_filter():
    """The radar's report may be of the designated target while the camera's box is on something else
    near the bearing, ten times nearer; its range then neither pulls the estimate nor replaces the boxes."""
    f = RangeFilter()
    for k in range(20):
        f.predict(0.1 * k, np.zeros(3), np.array([1.0, 0.0, 0.0]))
        f.update_known(0.1 * k, 30.0, std_m=3.0)
        assert not f.fuse_range(300.0, 5.0)
    assert f.range_m == pytest.approx(30.0, abs=0.5)
