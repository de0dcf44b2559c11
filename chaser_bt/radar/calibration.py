"""Radar calibration from a flight past the radar (paper appendix A): find the radar's pose.

The data: the radar's reports of one drone (radar frame) and that drone's GPS (ENU, in a frame
whose origin is the *guessed* radar position). GPS is interpolated to each report's time, then
both are binned into 0.5 s windows and averaged (the paper's binning), track by track.

Three fits:

* :func:`fit_longest_track` -- the paper's method: the longest track, least-squares yaw, pitch
  and roll with the position held at the handheld-GPS guess;
* :func:`fit_best_track` -- the paper's extension: the same 3-parameter fit on every track, keep
  the one with the lowest residual;
* :func:`fit_six_dof` -- orientation *and* position. The paper's attempt diverged (residuals over
  100 m). Here it converges because (1) it is initialised in closed form (Kabsch/Umeyama:
  ``Rotation.align_vectors`` on the centred point sets) from the track that agrees with most bins
  of all the other tracks (every track is tried: clutter and birds can make the longest tracks),
  so no compass guess is needed at all; (2) the unknowns are scaled: a
  rotation vector about that initial orientation and an ENU offset in metres (not lat/lon degrees
  beside radians), with ``x_scale`` set so a unit step in each moves the residuals about as much;
  (3) it pools every track that agrees with the initial pose, which gives the geometric spread
  (ranges, elevations) that separates a translation from a rotation; and (4) a soft-L1 robust
  loss keeps clutter, birds and mis-binned points from dragging the fit.

Residuals are reported as the 1-sigma (standard deviation) of the fitted-minus-GPS ENU error, per
axis, over the bins the fit used, as the paper reports them.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from chaser_bt.geo import body_to_enu_rotation
from chaser_bt.radar.geometry import RadarPose

__all__ = ["TrackBins", "CalibrationResult", "bin_track", "bin_tracks", "fit_orientation", "fit_longest_track",
           "fit_best_track", "fit_six_dof", "kabsch_pose", "CalibrationError"]


class CalibrationError(ValueError):
    """The data cannot give a fit (too few tracks or bins)."""


@dataclass(frozen=True)
class TrackBins:
    """One track's 0.5 s bins: radar-frame positions and GPS ENU positions, averaged per bin."""

    track_id: int
    t: np.ndarray  # (m,) bin centres
    radar_xyz: np.ndarray  # (m, 3)
    gps_enu: np.ndarray  # (m, 3)
    duration_s: float

    def __len__(self) -> int:
        return int(self.t.size)


@dataclass(frozen=True)
class CalibrationResult:
    """A fitted pose (in the calibration frame), its residuals and what it was fitted on."""

    method: str
    pose: RadarPose
    residual_std_enu: np.ndarray  # (3,) 1-sigma E, N, U residual (m)
    residual_rms_m: float
    track_ids: tuple[int, ...]
    n_bins: int

    @property
    def yaw_pitch_roll(self) -> tuple[float, float, float]:
        return self.pose.yaw_pitch_roll


def bin_track(track_id: int, t: np.ndarray, radar_xyz: np.ndarray, gps_t: np.ndarray, gps_enu: np.ndarray,
              bin_s: float = 0.5, max_gps_gap_s: float = 1.0) -> TrackBins:
    """GPS interpolated to the reports' times, then both averaged over ``bin_s`` windows."""
    t = np.asarray(t, float)
    xyz = np.asarray(radar_xyz, float)
    gps_t = np.asarray(gps_t, float)
    gps_enu = np.asarray(gps_enu, float)
    g = np.stack([np.interp(t, gps_t, gps_enu[:, k]) for k in range(3)], axis=1)
    idx = np.clip(np.searchsorted(gps_t, t), 1, gps_t.size - 1)
    ok = (t >= gps_t[0]) & (t <= gps_t[-1]) & (gps_t[idx] - gps_t[idx - 1] <= max_gps_gap_s)
    t, xyz, g = t[ok], xyz[ok], g[ok]
    if t.size == 0:
        return TrackBins(track_id, np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), 0.0)
    b = np.floor(t / bin_s).astype(np.int64)
    keys, inv = np.unique(b, return_inverse=True)
    n = np.bincount(inv).astype(float)

    def mean(a: np.ndarray) -> np.ndarray:
        return np.stack([np.bincount(inv, a[:, k]) / n for k in range(3)], axis=1)

    return TrackBins(track_id, (keys + 0.5) * bin_s, mean(xyz), mean(g), float(t[-1] - t[0]))


def bin_tracks(report_t: np.ndarray, report_id: np.ndarray, radar_xyz: np.ndarray, gps_t: np.ndarray,
               gps_enu: np.ndarray, bin_s: float = 0.5, min_bins: int = 4) -> list[TrackBins]:
    """:func:`bin_track` for every track id with at least ``min_bins`` bins, longest first."""
    report_id = np.asarray(report_id)
    out = []
    for tid in np.unique(report_id):
        sel = report_id == tid
        tb = bin_track(int(tid), np.asarray(report_t)[sel], np.asarray(radar_xyz)[sel], gps_t, gps_enu, bin_s)
        if len(tb) >= min_bins:
            out.append(tb)
    return sorted(out, key=lambda tb: (-tb.duration_s, tb.track_id))


def _result(method: str, pose: RadarPose, bins: list[TrackBins]) -> CalibrationResult:
    xyz = np.concatenate([b.radar_xyz for b in bins])
    gps = np.concatenate([b.gps_enu for b in bins])
    r = pose.to_enu(xyz) - gps
    return CalibrationResult(method, pose, r.std(axis=0), float(np.sqrt((r**2).sum(axis=1).mean())),
                             tuple(b.track_id for b in bins), int(len(xyz)))


def _ypr_rotation(ypr: np.ndarray) -> Rotation:
    return body_to_enu_rotation(ypr[2], ypr[1], ypr[0])


def fit_orientation(bins: TrackBins, position_enu: np.ndarray, initial_ypr: tuple[float, float, float]) -> RadarPose:
    """Least-squares yaw, pitch, roll with the radar held at ``position_enu`` (the paper's fit)."""
    p = np.asarray(position_enu, float)

    def residuals(ypr: np.ndarray) -> np.ndarray:
        return (_ypr_rotation(ypr).apply(bins.radar_xyz) + p - bins.gps_enu).ravel()

    sol = least_squares(residuals, np.asarray(initial_ypr, float), method="lm" if len(bins) >= 2 else "trf")
    return RadarPose(p, _ypr_rotation(sol.x))


def fit_longest_track(tracks: list[TrackBins], position_enu: np.ndarray,
                      initial_ypr: tuple[float, float, float]) -> CalibrationResult:
    """The paper's calibration: the longest track, 3-parameter orientation fit."""
    if not tracks:
        raise CalibrationError("no track long enough to fit")
    longest = max(tracks, key=lambda tb: (tb.duration_s, len(tb)))
    return _result("longest-track", fit_orientation(longest, position_enu, initial_ypr), [longest])


def fit_best_track(tracks: list[TrackBins], position_enu: np.ndarray,
                   initial_ypr: tuple[float, float, float], min_bins: int = 20) -> CalibrationResult:
    """The paper's extension: fit every track (with ``min_bins`` bins or more), keep the lowest residual."""
    usable = [tb for tb in tracks if len(tb) >= min_bins] or tracks
    if not usable:
        raise CalibrationError("no track long enough to fit")
    fits = [_result("best-track", fit_orientation(tb, position_enu, initial_ypr), [tb]) for tb in usable]
    return min(fits, key=lambda r: (r.residual_rms_m, r.track_ids))


def kabsch_pose(radar_xyz: np.ndarray, gps_enu: np.ndarray) -> RadarPose:
    """Closed-form rigid pose mapping radar-frame points onto ENU points (Kabsch/Umeyama)."""
    xyz, enu = np.asarray(radar_xyz, float), np.asarray(gps_enu, float)
    cx, ce = xyz.mean(axis=0), enu.mean(axis=0)
    rot, _ = Rotation.align_vectors(enu - ce, xyz - cx)
    return RadarPose(ce - rot.apply(cx), rot)


def _inliers(pose: RadarPose, tracks: list[TrackBins], gate_m: float) -> list[TrackBins]:
    """Tracks whose median bin error under ``pose`` is inside ``gate_m``."""
    return [tb for tb in tracks
            if np.median(np.linalg.norm(pose.to_enu(tb.radar_xyz) - tb.gps_enu, axis=1)) < gate_m]


def fit_six_dof(tracks: list[TrackBins], *, min_bins: int = 10, gate_m: float = 8.0, robust_scale_m: float = 2.0,
                max_residual_m: float = 25.0) -> CalibrationResult:
    """Orientation and position: closed-form initialisation, scaled parameters, pooled tracks, robust loss.

    Every usable track seeds a closed-form pose; the one the most bins of all tracks agree with
    starts the fit. Seeding from every track, not only the longest, matters where clutter and birds
    make long tracks and the drone's own is cut into short ones by drops and id swaps. A fit no track
    agrees with (or whose residual exceeds ``max_residual_m``) is a :class:`CalibrationError`, not a pose.
    """
    usable = [tb for tb in tracks if len(tb) >= min_bins]
    if not usable:
        raise CalibrationError(f"no track with {min_bins} or more bins")
    best_pose, best_support = None, 0
    for tb in sorted(usable, key=lambda tb: (-len(tb), tb.track_id)):
        with warnings.catch_warnings():  # a straight track's rotation is ill-defined; its support says so
            warnings.filterwarnings("ignore", "Optimal rotation is not uniquely", UserWarning)
            pose = kabsch_pose(tb.radar_xyz, tb.gps_enu)
        support = sum(len(x) for x in _inliers(pose, usable, gate_m))
        if support > best_support:
            best_pose, best_support = pose, support
    if best_pose is None:
        raise CalibrationError(f"no track's pose agrees with any track within {gate_m:g} m "
                               f"({len(usable)} tracks of {min_bins} or more bins): not a flight past the radar")
    pose = best_pose
    for _ in range(3):  # refit on the agreeing tracks, re-select with the better pose
        chosen = _inliers(pose, usable, gate_m) or [max(usable, key=len)]
        pose = _refine(pose, chosen, robust_scale_m)
    chosen = _inliers(pose, usable, gate_m)
    if not chosen:
        raise CalibrationError(f"the fitted pose agrees with no track within {gate_m:g} m")
    result = _result("six-dof", pose, chosen)
    if result.residual_rms_m > max_residual_m:
        raise CalibrationError(f"residual {result.residual_rms_m:.1f} m rms exceeds {max_residual_m:g} m")
    return result


def _refine(init: RadarPose, tracks: list[TrackBins], robust_scale_m: float) -> RadarPose:
    xyz = np.concatenate([tb.radar_xyz for tb in tracks])
    gps = np.concatenate([tb.gps_enu for tb in tracks])
    lever = max(float(np.median(np.linalg.norm(xyz, axis=1))), 1.0)

    def pose_of(x: np.ndarray) -> RadarPose:
        return RadarPose(init.position_enu + x[3:], Rotation.from_rotvec(x[:3]) * init.rotation)

    def residuals(x: np.ndarray) -> np.ndarray:
        return (pose_of(x).to_enu(xyz) - gps).ravel()

    # A rotation of 1/lever rad moves a point at the typical range by about 1 m, as 1 m of offset does.
    sol = least_squares(residuals, np.zeros(6), x_scale=np.r_[np.full(3, 1.0 / lever), np.ones(3)],
                        loss="soft_l1", f_scale=robust_scale_m, method="trf")
    return pose_of(sol.x)

