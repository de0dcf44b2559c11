"""Camera-on rehearsal speed (issue 19): the chase in its default camera world, real-time factor.

Flies trees/chase.yaml on sitl/scenarios/chase.yaml (the ``any`` camera world: seed 1 is farmland)
``--repeats`` times, each run beside a reference run in the same process: the same flight with every
frame rendered whole (``SensorOptions(whole_frames=True)``, what a rehearsal did before regions of
interest). The machine is shared, so the figure to compare between machines or commits is the ratio
to that reference, measured back to back; the real-time factor is the median of the runs.

Prints one JSON line: {"name": "rehearsal_speed", "realtime_factor_median", "reference_realtime_factor_median",
"speedup_vs_reference", "tick_ms_median", "sim_time_s", "runs": [...], "load_avg_1m"}.
Run: .venv/bin/python benchmarks/bench_rehearsal_speed.py [--seed 1] [--sim-s 300] [--repeats 3] [--no-reference]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--sim-s", type=float, default=300.0, help="simulated seconds per run (the scenario's 300 by default)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-reference", action="store_true", help="skip the whole-frame reference runs")
    args = parser.parse_args()
    os.environ.setdefault("MAVLINK20", "1")
    from sitl.bench.rehearsal import rehearse
    from sitl.bench.sensors import SensorOptions
    from sitl.world.scenario import load_scenario

    scenario = dataclasses.replace(load_scenario(ROOT / "sitl/scenarios/chase.yaml"), time_limit_s=args.sim_s)
    tree = ROOT / "trees/chase.yaml"
    rehearse(tree, dataclasses.replace(scenario, time_limit_s=5.0), args.seed)  # loads, compiles and caches before timing
    runs, refs = [], []
    for _ in range(args.repeats):
        r = rehearse(tree, scenario, args.seed)
        runs.append({"realtime_factor": r.realtime_factor, "wall_time_s": r.wall_time_s, "tick_ms_median": r.tick_ms_median,
                     "outcome": r.outcome, "detection_frac": r.detection_frac})
        if not args.no_reference:
            ref = rehearse(tree, scenario, args.seed, sensors=SensorOptions(whole_frames=True))
            refs.append({"realtime_factor": ref.realtime_factor, "wall_time_s": ref.wall_time_s, "detection_frac": ref.detection_frac})
    rtf = statistics.median(r["realtime_factor"] for r in runs)
    out = {"name": "rehearsal_speed", "seed": args.seed, "sim_time_s": args.sim_s, "realtime_factor_median": rtf,
           "tick_ms_median": statistics.median(r["tick_ms_median"] for r in runs), "runs": runs}
    if refs:
        ref_rtf = statistics.median(r["realtime_factor"] for r in refs)
        out |= {"reference_realtime_factor_median": ref_rtf, "speedup_vs_reference": round(rtf / ref_rtf, 2), "reference_runs": refs}
    out["load_avg_1m"] = round(os.getloadavg()[0], 2)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
