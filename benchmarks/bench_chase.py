"""The chase mission over many seeds: success rate and the paper's figures, the SAR find rate, and the hard set.

Prints one JSON line: {"name": "chase", "seeds": n, "success_frac", "t_airborne_s_median",
"t_acquire_s_median", "target_in_fov_frac_median", "detection_frac_median", "radar_assoc_frac_median",
"sar_found_frac", "campaign_runs_per_min", ...} from a campaign (:mod:`sitl.bench.campaign`) of
trees/chase.yaml on sitl/scenarios/chase.yaml, and one of trees/sar.yaml on sitl/scenarios/sar.yaml
for ``sar_found_frac`` (null with ``sar_reason`` when either file is missing or ``--no-sar``).

Success is :class:`sitl.bench.campaign.SuccessRule`: the run ends well (landed, following or completed),
vision acquired the intruder and kept it in the camera's FOV for at least 20 s after acquisition.
``campaign_runs_per_min``: runs flown per wall-clock minute by the chase campaign with ``--workers``
processes (a fresh output folder, so every run is flown).

``--hard`` also flies the chase on every scenario of ``sitl/scenarios/hard/`` (several intruders, fast
and evasive ones, long radar gaps, wind and birds, a far first sighting) and adds ``hard``: per
scenario, the success share and the medians of ``custody_frac``, ``target_in_fov_frac`` and
``detection_frac``, and the target switches summed over its runs (the targets: success >= 0.9,
custody >= 0.95, no switch, in view >= 0.90, detection above the paper's 0.66).

Run: .venv/bin/python benchmarks/bench_chase.py [--quick] [--seeds 1-50] [--workers 2] [--out DIR] [--hard]
(``--quick``: seeds 1-4, each run capped at 120 s of simulated time).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from record import Benchmark, add_record_flag, emit  # noqa: E402

CHASE = (ROOT / "trees/chase.yaml", ROOT / "sitl/scenarios/chase.yaml")
SAR = (ROOT / "trees/sar.yaml", ROOT / "sitl/scenarios/sar.yaml")
HARD = ROOT / "sitl/scenarios/hard"
KEYS = ("t_airborne_s", "t_acquire_s", "target_in_fov_frac", "detection_frac", "radar_assoc_frac")
BENCHMARK = Benchmark(
    "chase", __doc__,
    against="built-in simulator: rehearsal campaigns with radar, rendered camera and shipped detector "
            "(sitl/scenarios/chase.yaml, sar.yaml, hard/)",
    units={
        "seeds": "seeds per scenario",
        "success_frac": "share of runs that succeed (ended well, acquired, >= 20 s in view after acquisition)",
        "t_airborne_s_*": "s, first validated radar track to take-off altitude (paper 15.48; sitl/bench/scoring.py)",
        "t_acquire_s_*": "s, airborne to the first estimate within 10 m or 3 deg of the intruder (paper 4.95)",
        "target_in_fov_frac_*": "share of autonomous ticks, acquisition to end of follow, with the intruder in the "
                                "camera's frustum (paper 0.91)",
        "detection_frac_*": "share of camera frames in that span whose box matches the intruder (paper 0.66)",
        "radar_assoc_frac_*": "share of 1 s windows in which the correlator held the chaser's own track (paper 0.917)",
        "*_p25_p75": "quartiles over runs [p25, p75]",
        "*_median": "median over runs",
        "sar_found_frac": "share of search-and-rescue runs that found the person",
        "sar_reason": "why sar_found_frac is null",
        "campaign_runs_per_min": "chase runs flown per wall-clock minute",
        "workers": "campaign worker processes",
        "quick": "runs capped at 120 s simulated",
        "hard.*.runs": "runs", "hard.*.success_frac": "share of runs that succeed (target >= 0.9)",
        "hard.*.custody_frac_median": "share of time the designated target is held (target >= 0.95)",
        "hard.*.target_switches": "target switches, summed over runs (target 0)",
        "hard.*.target_in_fov_frac_median": "share of follow time in view (target >= 0.90)",
        "hard.*.detection_frac_median": "share of in-view frames detected (target > 0.66)",
    },
    headline=("success_frac", "t_acquire_s_median", "target_in_fov_frac_median", "detection_frac_median",
              "sar_found_frac", "campaign_runs_per_min"),
)


def _campaign(tree: Path, scenario: Path, seeds: list[int], out: Path, args):
    from sitl.bench.campaign import CampaignConfig, find_scenarios, run_campaign

    config = CampaignConfig(tree=tree, scenarios=find_scenarios(scenario), seeds=seeds, out_dir=out, workers=args.workers,
                            camera=not args.no_camera, quick=args.quick)
    start = time.perf_counter()
    last = [start]
    result = run_campaign(config, on_result=lambda done, total, row: last.__setitem__(0, time.perf_counter()))
    return result, last[0] - start  # flying only: up to the last run stored, not the report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="seeds 1-4, runs capped at 120 s simulated")
    parser.add_argument("--seeds", help="seed list (default 1-50, or 1-4 with --quick)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--out", type=Path, help="keep the campaigns here (default: a temporary folder)")
    parser.add_argument("--no-camera", action="store_true")
    parser.add_argument("--no-sar", action="store_true", help="skip the search-and-rescue campaign")
    parser.add_argument("--hard", action="store_true", help="also the hard-scenario campaign (sitl/scenarios/hard/)")
    add_record_flag(parser)
    args = parser.parse_args()
    os.environ.setdefault("MAVLINK20", "1")
    logging.basicConfig(level=logging.WARNING)
    from sitl.bench.campaign import parse_seeds

    seeds = parse_seeds(args.seeds or ("1-4" if args.quick else "1-50"))
    with tempfile.TemporaryDirectory(prefix="bench_chase_") as tmp:
        out = args.out or Path(tmp)
        chase, wall = _campaign(*CHASE, seeds, out / "chase", args)
        agg = chase.aggregates
        line = {"name": "chase", "seeds": len(seeds), "success_frac": agg["success_frac"]}
        for key in KEYS:
            line[f"{key}_median"] = agg["metrics"][key]["median"]
        for key in KEYS:
            m = agg["metrics"][key]
            line[f"{key}_p25_p75"] = None if m["median"] is None else [m["p25"], m["p75"]]
        line["sar_found_frac"] = None
        if args.no_sar:
            line["sar_reason"] = "--no-sar"
        elif not all(p.is_file() for p in SAR):
            line["sar_reason"] = f"missing {', '.join(str(p.relative_to(ROOT)) for p in SAR if not p.is_file())}"
        else:
            sar, _ = _campaign(*SAR, seeds, out / "sar", args)
            line["sar_found_frac"] = sar.aggregates.get("sar_found_frac")
            if line["sar_found_frac"] is None:
                line["sar_reason"] = "no run reported sar_found"
        if args.hard:
            hard, _ = _campaign(CHASE[0], HARD, seeds, out / "hard", args)
            line["hard"] = {Path(name).stem: {
                "runs": e["runs"], "success_frac": e["success_frac"], "custody_frac_median": e["custody_frac_median"],
                "target_switches": e["target_switches"], "target_in_fov_frac_median": e["target_in_fov_frac_median"],
                "detection_frac_median": e["detection_frac_median"]} for name, e in hard.aggregates["by_scenario"].items()}
        line["campaign_runs_per_min"] = round(chase.executed / (wall / 60.0), 2) if chase.executed else None
        line["workers"] = args.workers
        line["outcomes"] = agg["outcomes"]
        line["quick"] = args.quick
    emit(line, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
