"""Follow quality: share of follow time with the target in the camera FOV (paper: 0.91), one JSON line.

Every seed flies one trajectory kind (rectangle with pauses, circle, figure eight, random waypoints,
evasive Phantom 4), cycling through the kinds, against the built-in simulator: take off, then
``FollowGlobal`` on the intruder's own MAVLink position (telemetry range, as the paper's flight
took range from GPS). Scored from truth by :mod:`sitl.bench.follow_eval` over 150 s of target motion.
Configurations: ``paper`` (the three loops of table 1), ``roll``, ``feed_forward``, ``roll_ff``;
the headline figures are ``roll_ff``'s (the paper's loops are reported beside them).

``in_fov_frac_vision_range``: the same flights with no telemetry at all: the chaser's camera is
rendered (the paper's e-con, tilted down by the set-point elevation, ``--camera`` pixels; the
intruder drawn as an S1000, the paper's flight target), the shipped detector and trackers give the
estimate, and ``CVFollow`` flies on its azimuth, elevation and box-size range
(:data:`VISION_PORTS`: range low-passed along the accurate bearing, derivative terms from the
filtered process variables instead of differenced camera positions, lean held to 15 deg so the
fixed camera keeps the target). Also reported: the vision range error (median over seeds of each
seed's median |estimate - truth|) and the share of samples with a fresh estimate (tracking).
Rendering makes these flights slow: ``--vision-seeds``, ``--vision-duration`` and ``--jobs``.

    .venv/bin/python benchmarks/bench_follow.py [--quick] [--seeds N] [--jobs J] [--vision-only]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sitl.bench.follow_eval import VISION_FOLLOW_PORTS, TRAJECTORY_PARAMS, fly_follow, intruder_scenario  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402

HEADLINE = "roll_ff"  # the controller as we recommend flying it; "paper" is table 1's three loops
CONFIGS = {"paper": "", "roll": "use_roll: true", "feed_forward": "feed_forward: true",
           "roll_ff": "use_roll: true, feed_forward: true"}
VISION_PORTS = VISION_FOLLOW_PORTS
BENCHMARK = Benchmark(
    "follow", __doc__,
    against="built-in simulator: one intruder per seed over five trajectory kinds, scored from its truth "
            "(sitl/bench/follow_eval.py); vision flights with the rendered camera and the shipped detector",
    units={
        "seeds": "seeds of the telemetry-range flights", "follow_s_per_seed": "s of scored follow per seed",
        "headline_config": "the configuration the headline figures are of",
        "in_fov_frac_*": "share of follow time with the target in the camera's field of view (paper 0.91)",
        "in_fov_frac_telemetry_range": "share of follow time in view, telemetry range, median over seeds (paper 0.91)",
        "in_fov_frac_telemetry_range_mean": "the same, mean over seeds",
        "in_fov_frac_telemetry_range_paper_loops": "the same with the paper's three loops (table 1)",
        "in_fov_frac_vision_range": "share of follow time in view, no telemetry: range from the camera, median over seeds",
        "*vision_range_err_m_p50": "m, median over seeds of each seed's median |vision range - truth|",
        "*range_err_m_p50": "m, median slant-range error from the set-point",
        "*elev_err_deg_p50": "deg, median elevation error from the set-point",
        "by_trajectory": "share of follow time in view per trajectory kind (mean over its seeds)",
        "*tracking_frac_median": "share of samples with a fresh camera estimate (median over seeds)",
        "configs": "each controller configuration's telemetry-range figures",
        "vision": "the vision-range flights",
        "wall_s": "s of wall time, all flights",
    },
    headline=("in_fov_frac_telemetry_range", "in_fov_frac_telemetry_range_paper_loops", "in_fov_frac_vision_range",
              "vision_range_err_m_p50"),
)


def fly_one(args: tuple) -> dict:
    """One seed (a worker process's job): the scores that the summary needs."""
    seed, ports, duration_s, source, camera = args
    kind = list(TRAJECTORY_PARAMS)[seed % len(TRAJECTORY_PARAMS)]
    score, _, _ = fly_follow(intruder_scenario(kind), seed, follow_ports=ports, duration_s=duration_s,
                             range_source=source, camera_size=camera)
    run = {"seed": seed, "kind": kind, "source": source, "in_fov": score.in_fov_frac,
           "range_err": score.range_err_p50(40.0), "elev_err": score.elev_err_deg_p50(math.radians(40.0)),
           "vision_range_err": score.vision_range_abs_err_p50, "tracking": score.tracking_frac}
    print(json.dumps(run), file=sys.stderr, flush=True)  # progress: one line per seed as it finishes
    return run


def run_config(ports: str, seeds: int, duration_s: float, *, source: str = "telemetry",
               camera: tuple[int, int] = (640, 480), jobs: int = 1) -> dict:
    jobs_args = [(seed, ports, duration_s, source, camera) for seed in range(seeds)]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as pool:
            runs = list(pool.map(fly_one, jobs_args))
    else:
        runs = [fly_one(a) for a in jobs_args]
    fov = [r["in_fov"] for r in runs]
    by_kind: dict[str, list[float]] = {k: [] for k in TRAJECTORY_PARAMS}
    for r in runs:
        by_kind[r["kind"]].append(r["in_fov"])
    out = {
        "in_fov_frac_median": round(statistics.median(fov), 4),
        "in_fov_frac_mean": round(statistics.fmean(fov), 4),
        "in_fov_frac_min": round(min(fov), 4),
        "range_err_m_p50": round(statistics.median(r["range_err"] for r in runs), 2),
        "elev_err_deg_p50": round(statistics.median(r["elev_err"] for r in runs), 2),
        "by_trajectory": {k: round(statistics.fmean(v), 4) for k, v in by_kind.items() if v},
    }
    if source == "vision":
        errs = [r["vision_range_err"] for r in runs if math.isfinite(r["vision_range_err"])]
        out["vision_range_err_m_p50"] = round(statistics.median(errs), 2) if errs else None
        out["tracking_frac_median"] = round(statistics.median(r["tracking"] for r in runs), 4)
        out["per_seed_in_fov"] = [round(v, 4) for v in fov]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="5 seeds, paper and roll_ff only, 60 s each")
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--jobs", type=int, default=1, help="worker processes")
    ap.add_argument("--vision-seeds", type=int, default=None, help="seeds of the vision flights (default --seeds)")
    ap.add_argument("--vision-duration", type=float, default=None, help="scored follow seconds per vision flight")
    ap.add_argument("--camera", default="640x480", help="rendered camera WIDTHxHEIGHT")
    ap.add_argument("--vision-ports", default=VISION_PORTS,
                    help=f"CVFollow ports of the vision flights (default {VISION_PORTS!r}; '' = CVFollow's defaults)")
    ap.add_argument("--vision-only", action="store_true", help="only the vision-range flights")
    ap.add_argument("--no-vision", action="store_true", help="only the telemetry-range flights")
    add_record_flag(ap)
    args = ap.parse_args()
    seeds, duration, configs = (5, 60.0, ("paper", "roll_ff")) if args.quick else (args.seeds, 150.0, tuple(CONFIGS))
    try:
        camera = tuple(int(v) for v in args.camera.lower().split("x"))
        assert len(camera) == 2 and min(camera) > 0
    except (ValueError, AssertionError):
        ap.error(f"--camera {args.camera!r}: expected WIDTHxHEIGHT, e.g. 640x480")
    t0 = time.perf_counter()
    results = {} if args.vision_only else {name: run_config(CONFIGS[name], seeds, duration, jobs=args.jobs)
                                           for name in configs}
    vision = None
    if not args.no_vision:
        vseeds = args.vision_seeds or seeds
        vdur = args.vision_duration or duration
        vision = {"seeds": vseeds, "follow_s_per_seed": vdur, "camera": list(camera), "ports": args.vision_ports,
                  **run_config(args.vision_ports, vseeds, vdur, source="vision", camera=camera, jobs=args.jobs)}
    head = results.get(HEADLINE, {})
    emit({
        "name": "follow",
        "seeds": seeds if results else None,
        "follow_s_per_seed": duration if results else None,
        "headline_config": HEADLINE,
        "in_fov_frac_telemetry_range": head.get("in_fov_frac_median"),
        "in_fov_frac_telemetry_range_mean": head.get("in_fov_frac_mean"),
        "in_fov_frac_telemetry_range_paper_loops": results.get("paper", {}).get("in_fov_frac_median"),
        "in_fov_frac_vision_range": vision["in_fov_frac_median"] if vision else None,
        "vision_range_err_m_p50": vision["vision_range_err_m_p50"] if vision else None,
        "range_err_m_p50": head.get("range_err_m_p50"),
        "elev_err_deg_p50": head.get("elev_err_deg_p50"),
        "by_trajectory": head.get("by_trajectory"),
        "configs": results,
        "vision": vision,
        "wall_s": round(time.perf_counter() - t0, 1),
    }, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
