"""Calibration (appendix A): noise-free data gives back the pose exactly; the fits pick sensibly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chaser_bt.geo import GeoPoint, LocalFrame
from chaser_bt.radar.calibration import (CalibrationError, bin_tracks, fit_best_track, fit_longest_track,
                                         fit_six_dof, kabsch_pose)
from chaser_bt.radar.geometry import RadarPose, xyz_to_rae
from chaser_bt.radar.recording import CalibrationRecording, calibrate_recording, load_recording, write_recording
from chaser_bt.radar.report import RadarScan, TrackReport

TRUE = RadarPose.from_attitude(np.array([3.0, -4.0, 1.5]), math.radians(35.0), math.radians(8.0), math.radians(-2.0))


def flight(n_tracks: int = 3, seconds: float = 60.0, rate: float = 5.0):
    """A drone circling and climbing in front of TRUE; GPS at the radar's report times, no noise."""
    t = np.arange(0.0, seconds, 1.0 / rate)
    boresight = TRUE.rotation.apply([1.0, 0.0, 0.0]) * np.array([1, 1, 0])
    centre = TRUE.position_enu + 80.0 * boresight / np.linalg.norm(boresight)
    enu = np.stack([centre[0] + 25 * np.cos(0.2 * t), centre[1] + 25 * np.sin(0.2 * t), 20 + 10 * np.sin(0.05 * t)], 1)
    ids = np.repeat(np.arange(1, n_tracks + 1), int(np.ceil(t.size / n_tracks)))[: t.size]
    return t, ids, TRUE.from_enu(enu), enu


def test_kabsch_recovers_a_known_pose_exactly():
    _, _, xyz, enu = flight()
    pose = kabsch_pose(xyz, enu)
    assert np.allclose(pose.position_enu, TRUE.position_enu, atol=1e-6)
    assert (pose.rotation.inv() * TRUE.rotation).magnitude() < 1e-9


def test_six_dof_recovers_a_known_pose_exactly_from_noise_free_data():
    t, ids, xyz, enu = flight()
    res = fit_six_dof(bin_tracks(t, ids, xyz, t, enu))
    assert np.allclose(res.pose.position_enu, TRUE.position_enu, atol=1e-6)
    assert (res.pose.rotation.inv() * TRUE.rotation).magnitude() < 1e-8
    assert res.residual_rms_m < 1e-6 and len(res.track_ids) == 3


def test_three_parameter_fit_recovers_orientation_exactly_with_the_true_position():
    t, ids, xyz, enu = flight()
    tracks = bin_tracks(t, ids, xyz, t, enu)
    y, p, r = TRUE.yaw_pitch_roll
    res = fit_longest_track(tracks, TRUE.position_enu, (y + 0.15, p - 0.05, r + 0.05))
    assert np.allclose(res.yaw_pitch_roll, (y, p, r), atol=1e-8)
    assert res.residual_rms_m < 1e-6


def test_longest_track_and_best_track_choose_differently_when_the_longest_is_bad():
    t, ids, xyz, enu = flight(n_tracks=2)
    xyz = xyz.copy()
    xyz[ids == 1] += np.random.default_rng(0).normal(0, 3.0, (int((ids == 1).sum()), 3))
    # make track 1 the longest by giving track 2 only the last third of its reports
    keep = (ids == 1) | (t > t[ids == 2].max() - 10)
    tracks = bin_tracks(t[keep], ids[keep], xyz[keep], t, enu)
    y, p, r = TRUE.yaw_pitch_roll
    longest = fit_longest_track(tracks, TRUE.position_enu, (y, p, r))
    best = fit_best_track(tracks, TRUE.position_enu, (y, p, r), min_bins=5)
    assert longest.track_ids == (1,) and best.track_ids == (2,)
    assert best.residual_rms_m < 1e-6 < longest.residual_rms_m


def test_binning_averages_both_sensors_over_half_second_windows():
    t = np.array([0.0, 0.2, 0.4, 0.6])
    xyz = np.array([[10.0, 0, 0], [12.0, 0, 0], [14.0, 0, 0], [20.0, 0, 0]])
    gps_t = np.array([0.0, 1.0])
    gps = np.array([[0.0, 0, 0], [10.0, 0, 0]])
    (tb,) = bin_tracks(t, np.ones(4, int), xyz, gps_t, gps, min_bins=1)
    assert np.allclose(tb.t, [0.25, 0.75])
    assert np.allclose(tb.radar_xyz[:, 0], [12.0, 20.0]) and np.allclose(tb.gps_enu[:, 0], [2.0, 6.0])


def test_no_usable_track_is_a_clear_error():
    with pytest.raises(CalibrationError):
        fit_six_dof([])


def test_recording_round_trip_and_calibration_from_file(tmp_path):
    origin = GeoPoint(42.5445, -71.6105, 80.0)
    frame = LocalFrame(origin)
    t, ids, xyz, enu = flight()
    r, az, el = xyz_to_rae(xyz)
    scans = tuple(RadarScan(float(ti), k + 1, (TrackReport(int(i), float(a), float(b), float(c)),))
                  for k, (ti, i, a, b, c) in enumerate(zip(t, ids, r, az, el)))
    lla = np.array([[g.lat_deg, g.lon_deg, g.alt_m] for g in (frame.to_geodetic(p) for p in enu)])
    rec = CalibrationRecording(origin, (math.radians(30.0), 0.0, 0.0), scans, t, lla)
    path = tmp_path / "cal.jsonl"
    write_recording(path, rec)
    back = load_recording(path)
    assert len(back.scans) == len(scans) and np.allclose(back.gps_lla, lla)
    res, where = calibrate_recording(back, "six")
    assert np.linalg.norm(res.pose.position_enu - TRUE.position_enu) < 1e-3  # frame = guess = origin
    assert np.degrees((res.pose.rotation.inv() * TRUE.rotation).magnitude()) < 1e-4
    truth = frame.to_geodetic(TRUE.position_enu)
    assert abs(where.lat_deg - truth.lat_deg) < 1e-8 and abs(where.alt_m - truth.alt_m) < 1e-3


def _clutter(t: np.ndarray, n: int, first_id: int, rng: np.random.Generator):
    """``n`` tracks of straight-line clutter over the whole flight, unrelated to the drone."""
    ts, ids, xyz = [], [], []
    for k in range(n):
        start, vel = rng.uniform([40, -60, 5], [200, 60, 60]), rng.uniform(-3, 3, 3)
        ts.append(t)
        ids.append(np.full(t.size, first_id + k))
        xyz.append(start + vel * t[:, None])
    return np.concatenate(ts), np.concatenate(ids), np.concatenate(xyz)


def test_six_dof_finds_the_drone_when_its_track_is_cut_short_and_clutter_tracks_are_longer():
    # The drone's flight is cut into 12 tracks of 12-13 bins (drops, id swaps); ten clutter tracks
    # last the whole minute, so every one of the ten longest tracks is clutter.
    t, ids, xyz, enu = flight(n_tracks=12)
    ct, cid, cxyz = _clutter(t, 10, 100, np.random.default_rng(3))
    tracks = bin_tracks(np.r_[t, ct], np.r_[ids, cid], np.r_[xyz, cxyz], t, enu)
    assert all(tb.track_id >= 100 for tb in tracks[:10])
    res = fit_six_dof(tracks)
    assert sorted(res.track_ids) == list(range(1, 13))
    assert np.allclose(res.pose.position_enu, TRUE.position_enu, atol=1e-4)
    assert res.residual_rms_m < 1e-4


def test_six_dof_refuses_a_recording_of_clutter_alone():
    t, _, _, enu = flight()
    ct, cid, cxyz = _clutter(t, 6, 100, np.random.default_rng(4))
    with pytest.raises(CalibrationError):
        fit_six_dof(bin_tracks(ct, cid, cxyz, t, enu))
