"""Ground radar: the paper's correlation test and calibration flight, Algorithm 1 beside ours.

Prints one JSON line: {"name": "radar", "seeds": n, "alg1_assoc_frac", "alg1_wrong_frac",
"ours_assoc_frac", "ours_wrong_frac", "calib3_resid_m": [e, n, u], "calib_best_resid_m",
"calib6_resid_m", "calib6_pose_err": {"pos_m", "yaw_deg"}, "correlator_x_realtime", ...}.
Fractions are over all seeds' 1 s windows (docs/radar.md says how they are scored); residuals
and pose errors are medians over the calibration seeds.
Run: .venv/bin/python benchmarks/bench_radar.py [--quick]   (--quick: 5 seeds, under a minute)
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from chaser_bt.radar.correlator import make_correlator  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402
from chaser_bt.radar.recording import calibrate_recording  # noqa: E402
from sitl.bench.radar_trials import (calibration_test_flight, correlation_test_flight, handheld_guess,  # noqa: E402
                                score_correlator, to_recording)

BENCHMARK = Benchmark(
    "radar", __doc__,
    against="built-in simulator: the paper's correlation test and calibration flights, simulated "
            "(sitl/bench/radar_trials.py)",
    units={
        "seeds": "correlation-test seeds (500 s of flight each)",
        "alg1_assoc_frac": "share of 1 s windows in coverage associated with the ownship's track, the paper's Algorithm 1",
        "alg1_wrong_frac": "share of 1 s windows associated with another track, Algorithm 1",
        "ours_assoc_frac": "share of 1 s windows associated with the ownship's track, the gated correlator",
        "ours_wrong_frac": "share of 1 s windows associated with another track, the gated correlator",
        "ours_min_seed_assoc_frac": "the gated correlator's worst seed",
        "*_x_realtime": "flight seconds scored per wall second (5 Hz scans)",
        "flight_s": "simulated seconds of correlation-test flight, all seeds",
        "calib3_resid_m": "m, residual std [e, n, u], the paper's 3-parameter fit on the longest track (median of seeds)",
        "calib_best_resid_m": "m, residual std [e, n, u], the 3-parameter fit on the best track (median of seeds)",
        "calib6_resid_m": "m, residual std [e, n, u], the 6-parameter fit (median of seeds)",
        "*_pose_err": "the fitted radar pose against the truth (median of seeds)",
        "pos_m": "m, position error",
        "yaw_deg": "deg, yaw error",
        "calib_seeds": "calibration-flight seeds",
        "calib_tracks_median": "radar track ids per calibration flight (median)",
    },
    headline=("ours_assoc_frac", "ours_wrong_frac", "alg1_assoc_frac", "calib6_pose_err.pos_m", "correlator_x_realtime"),
)


def correlation(seeds: int) -> dict:
    tot = {k: [0, 0, 0, 0.0] for k in ("alg1", "gated")}  # windows, right, wrong, wall
    flight_s = 0.0
    per_seed = {k: [] for k in tot}
    for seed in range(seeds):
        f = correlation_test_flight(seed)
        flight_s += f.duration_s
        for name in tot:
            s = score_correlator(f, make_correlator(name))
            t = tot[name]
            t[0] += s.windows
            t[1] += round(s.assoc_frac * s.windows)
            t[2] += round(s.wrong_frac * s.windows)
            t[3] += s.wall_s
            per_seed[name].append(round(float(s.assoc_frac), 3))
    a, o = tot["alg1"], tot["gated"]
    return {"alg1_assoc_frac": a[1] / a[0], "alg1_wrong_frac": a[2] / a[0], "ours_assoc_frac": o[1] / o[0],
            "ours_wrong_frac": o[2] / o[0], "ours_min_seed_assoc_frac": min(per_seed["gated"]),
            "alg1_x_realtime": flight_s / a[3], "correlator_x_realtime": flight_s / o[3], "flight_s": flight_s}


def calibration(seeds: int) -> dict:
    rows = {"longest": [], "best": [], "six": []}
    pose_err = {m: [] for m in rows}
    tracks = []
    for seed in range(seeds):
        f = calibration_test_flight(seed)
        rec = to_recording(f, handheld_guess(f, seed))
        tracks.append(len({r.track_id for s in rec.scans for r in s.tracks}))
        truth = f.frame.to_geodetic(f.true_pose.position_enu)
        ty = f.true_pose.yaw_pitch_roll[0]
        for m in rows:
            res, where = calibrate_recording(rec, m)
            rows[m].append(res.residual_std_enu)
            d = np.linalg.norm(f.frame.point_to_enu(where) - f.frame.point_to_enu(truth))
            dy = math.degrees((res.yaw_pitch_roll[0] - ty + math.pi) % (2 * math.pi) - math.pi)
            pose_err[m].append((d, abs(dy)))

    def med(m: str) -> list[float]:
        return [round(float(v), 3) for v in np.median(np.array(rows[m]), axis=0)]

    def err(m: str) -> dict:
        e = np.median(np.array(pose_err[m]), axis=0)
        return {"pos_m": round(float(e[0]), 3), "yaw_deg": round(float(e[1]), 3)}

    return {"calib3_resid_m": med("longest"), "calib_best_resid_m": med("best"), "calib6_resid_m": med("six"),
            "calib6_pose_err": err("six"), "calib3_pose_err": err("longest"), "calib_best_pose_err": err("best"),
            "calib_seeds": seeds, "calib_tracks_median": float(np.median(tracks))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5 correlation seeds, 3 calibration seeds")
    parser.add_argument("--seeds", type=int, default=None, help="correlation seeds (default 20, quick 5)")
    add_record_flag(parser)
    args = parser.parse_args()
    seeds = args.seeds or (5 if args.quick else 20)
    out = {"name": "radar", "seeds": seeds}
    out.update(correlation(seeds))
    out.update(calibration(3 if args.quick else 10))
    emit({k: (round(v, 4) if isinstance(v, float) else v) for k, v in out.items()}, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
