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
