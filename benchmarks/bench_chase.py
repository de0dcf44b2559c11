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
import json
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

CHASE = (ROOT / "trees/chase.yaml", ROOT / "sitl/scenarios/chase.yaml")
SAR = (ROOT / "trees/sar.yaml", ROOT / "sitl/scenarios/sar.yaml")
HARD = ROOT / "sitl/scenarios/hard"
KEYS = ("t_airborne_s", "t_acquire_s", "target_in_fov_frac", "detection_frac", "radar_assoc_frac")


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
    print(json.dumps(line))


if __name__ == "__main__":
    main()
