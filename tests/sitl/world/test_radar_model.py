"""The simulated ground radar: coverage, noise, the paper's failure modes, switching off."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from chaser_bt.geo import GeoPoint, LocalFrame
from chaser_bt.radar.geometry import xyz_to_rae
from sitl.world.radar import GroundRadar, RadarClutter, RadarConfig, RadarFailureRates
from sitl.world.targets import CirclePath, WaypointPath, downrange_and_back_points

ORIGIN = GeoPoint(42.5445, -71.6105, 80.0)
BASE = RadarConfig(ORIGIN, pd=1.0, rate_hz=5.0)


def radar(cfg=BASE, seed=0) -> GroundRadar:
    return GroundRadar(cfg, LocalFrame(ORIGIN), np.random.default_rng(seed))


def still(*points):
    return {f"o{i}": (np.asarray(p, float), np.zeros(3)) for i, p in enumerate(points)}


def test_coverage_is_the_120_by_80_degree_field_of_view_within_range():
    r = radar()  # boresight north, level
    assert r.in_coverage(np.array([0.0, 100.0, 0.0]))
    assert r.in_coverage(np.array([100 * math.sin(math.radians(59)), 100 * math.cos(math.radians(59)), 0]))
    assert not r.in_coverage(np.array([100 * math.sin(math.radians(61)), 100 * math.cos(math.radians(61)), 0]))
    assert not r.in_coverage(np.array([0.0, 100.0, 100 * math.tan(math.radians(41))]))
    assert not r.in_coverage(np.array([0.0, -100.0, 0.0]))
    assert not r.in_coverage(np.array([0.0, 1500.0, 0.0]))


def test_measurement_noise_has_the_configured_spread():
    r = radar(replace(BASE, sigma_range_m=2.0, sigma_az_rad=math.radians(1.0), sigma_el_rad=math.radians(2.0)))
    truth = xyz_to_rae(r.pose.from_enu(np.array([50.0, 200.0, 30.0])))
    reps = [r.scan(k * 0.2, still([50.0, 200.0, 30.0]))[0].tracks[0] for k in range(4000)]
    rae = np.array([(x.range_m, x.az_rad, x.el_rad) for x in reps])
    assert np.allclose(rae.mean(axis=0), truth, atol=[0.1, 1e-3, 2e-3])
    assert np.allclose(rae.std(axis=0), [2.0, math.radians(1.0), math.radians(2.0)], rtol=0.05)


def test_track_id_is_stable_without_failures_and_changes_after_a_drop():
    r = radar()
    ids = {r.scan(k * 0.2, still([0, 100, 10]))[0].tracks[0].track_id for k in range(50)}
    assert len(ids) == 1
    r = radar(replace(BASE, failures=RadarFailureRates(drop_per_s=1.0, drop_gap_s=0.4)))
    ids = [s.tracks[0].track_id if s.tracks else None for s, _ in (r.scan(k * 0.2, still([0, 100, 10])) for k in range(100))]
    assert len({i for i in ids if i is not None}) > 5 and None in ids  # new ids, after a gap


def test_close_pass_swaps_ids_when_swap_probability_is_one():
    cfg = replace(BASE, failures=RadarFailureRates(swap_prob=1.0, swap_distance_m=10.0))
    r = radar(cfg)
    a = WaypointPath(((-50.0, 150.0, 20.0), (50.0, 150.0, 20.0)), 5.0)
    b = WaypointPath(((50.0, 150.0, 22.0), (-50.0, 150.0, 22.0)), 5.0)
    first = last = None
    for k in range(100):
        t = k * 0.2
        _, truth = r.scan(t, {"a": (a.position_enu(t), a.velocity_enu(t)), "b": (b.position_enu(t), b.velocity_enu(t))})
        lab = {v: i for i, v in truth.labels.items()}
        first = first or lab
        last = lab
    assert first["a"] == last["b"] and first["b"] == last["a"]


def test_duplicates_run_beside_the_object_and_expire():
    cfg = replace(BASE, failures=RadarFailureRates(duplicate_per_s=0.5, duplicate_duration_s=2.0))
    r = radar(cfg)
    counts = [len(r.scan(k * 0.2, still([0, 100, 10]))[0].tracks) for k in range(200)]
    assert max(counts) >= 2 and min(counts[100:]) >= 1
    assert all(truth == "o0" for truth in r.scan(40.0, still([0, 100, 10]))[1].labels.values())


def test_clutter_and_birds_are_low_confidence_tracks():
    r = radar(replace(BASE, clutter=RadarClutter(false_tracks_per_s=2.0, birds_per_s=1.0)))
    confs = {}
    for k in range(100):
        scan, truth = r.scan(k * 0.2, {})
        for tr in scan.tracks:
            confs.setdefault(truth.labels[tr.track_id].split("-")[0], []).append(tr.confidence)
    assert set(confs) == {"clutter", "bird"}
    assert max(confs["clutter"]) <= 0.3 and max(confs["bird"]) <= 0.6


def test_radar_switches_off_at_the_scripted_time():
    r = radar(replace(BASE, off_at_s=1.0))
    assert r.scan(0.8, still([0, 100, 10])) is not None
    assert r.scan(1.0, still([0, 100, 10])) is None


def test_target_paths():
    c = CirclePath((0.0, 0.0, 10.0), 10.0, 5.0)
    assert np.allclose(c.position_enu(0.0), [10, 0, 10]) and np.allclose(c.velocity_enu(0.0), [0, 5, 0])
    assert np.allclose(c.position_enu(2 * math.pi * 10 / 5 / 4), [0, 10, 10])
    pts = downrange_and_back_points((0.0, 0.0, 5.0), math.pi / 2, 100.0, turn_radius_m=5.0)
    w = WaypointPath(tuple(pts), 10.0)
    assert np.allclose(w.position_enu(10.0), [0, 100, 5]) and np.allclose(w.velocity_enu(5.0), [0, 10, 0])
    assert np.allclose(w.position_enu(1e6), [-10, 0, 5]) and np.allclose(w.velocity_enu(1e6), 0)
