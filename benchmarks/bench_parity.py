"""ArduCopter against the built-in autopilot: the chase and search-and-rescue campaigns on both, same seeds.

The same trees (trees/chase.yaml, trees/sar.yaml), scenarios (sitl/scenarios/chase.yaml, sar.yaml) and seeds
flown twice, once by the built-in simulator's autopilot and once by ArduPilot's own ArduCopter SITL inside the
same world (docs/ardupilot.md). Prints one JSON line: per figure, each autopilot's median, the ratio
ArduCopter / built-in, and the paired Wilcoxon signed-rank p-value over the seeds (is the difference seed by
seed more than chance?); the chase's success and the SAR's find share on each. The parity target: every
chase median within 10 % of the built-in's, SAR found >= 0.9 on ArduCopter.

Needs the ArduCopter SITL (``$CHASER_BT_ARDUPILOT`` or ``--ardupilot DIR``; docs/ardupilot.md says how to build
it); without one it prints ``{"name": "parity", "skipped": "..."}`` and exits 0. ArduCopter runs are not
reproducible to the tick (its serial ports run on its own timer): repeat a run and seeds move a little.

Run: .venv/bin/python benchmarks/bench_parity.py [--chase-seeds 1-20] [--sar-seeds 1-10] [--workers 2] [--out DIR]
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from record import Benchmark, add_record_flag, emit  # noqa: E402

CHASE = (ROOT / "trees/chase.yaml", ROOT / "sitl/scenarios/chase.yaml")
SAR = (ROOT / "trees/sar.yaml", ROOT / "sitl/scenarios/sar.yaml")
CHASE_KEYS = ("t_airborne_s", "t_acquire_s", "target_in_fov_frac", "detection_frac", "radar_assoc_frac")
SAR_KEYS = ("sar_t_find_s", "sar_find_error_m")
AUTOPILOTS = ("builtin", "ardupilot")
BENCHMARK = Benchmark(
    "parity", __doc__,
    against="ArduCopter SITL (ArduPilot's own code, built from its public source) against the built-in simulator's "
            "autopilot, in the same world (radar, rendered camera, shipped detectors)",
    units={
        "chase_seeds": "seeds of the chase campaign", "sar_seeds": "seeds of the SAR campaign",
        "*.builtin": "median over the built-in's runs", "*.ardupilot": "median over ArduCopter's runs",
        "*.ratio": "ArduCopter's median / the built-in's (target: within 0.9-1.1 for the chase)",
        "*.wilcoxon_p": "paired Wilcoxon signed-rank p over the seeds both flew (small: a real difference)",
        "*.paired_seeds": "seeds both autopilots flew with a value",
        "chase_success.*": "share of chase runs that succeed", "sar_found.*": "share of SAR runs that found the person",
        "t_airborne_s.*": "s, validated radar track to take-off altitude", "t_acquire_s.*": "s, airborne to acquisition",
        "target_in_fov_frac.*": "share of follow ticks with the intruder in view",
        "detection_frac.*": "share of frames in that span with a true detection",
        "radar_assoc_frac.*": "share of 1 s windows with the chaser's own track held",
        "sar_t_find_s.*": "s, launch to the first find", "sar_find_error_m.*": "m, find to the person",
        "ardupilot_version": "the SITL's version line", "workers": "campaign worker processes",
        "skipped": "why nothing was flown",
    },
    headline=("t_acquire_s.ratio", "target_in_fov_frac.ratio", "detection_frac.ratio", "sar_found.ardupilot",
              "sar_t_find_s.ratio"),
)


def _campaign(files: tuple[Path, Path], seeds: list[int], autopilot: str, out: Path, args):
    from sitl.bench.campaign import CampaignConfig, find_scenarios, run_campaign

    tree, scenario = files
    config = CampaignConfig(tree=tree, scenarios=find_scenarios(scenario), seeds=seeds, out_dir=out,
                            workers=args.workers, autopilot=autopilot, ardupilot=args.ardupilot)
    return run_campaign(config)


def _compare(rows: dict[str, list[dict]], key: str) -> dict:
    """Each autopilot's median of ``key``, the ratio, and the paired test over the seeds both have."""
    from scipy.stats import wilcoxon

    by_seed = {ap: {r["seed"]: r.get(key) for r in rows[ap] if r.get(key) is not None} for ap in AUTOPILOTS}
    med = {ap: (statistics.median(v.values()) if v else None) for ap, v in by_seed.items()}
    both = sorted(set(by_seed["builtin"]) & set(by_seed["ardupilot"]))
    diffs = [by_seed["ardupilot"][s] - by_seed["builtin"][s] for s in both]
    p = float(wilcoxon(diffs).pvalue) if len(both) >= 5 and any(diffs) else None
    ratio = None if med["builtin"] in (None, 0) or med["ardupilot"] is None else med["ardupilot"] / med["builtin"]
    return {**med, "ratio": None if ratio is None else round(ratio, 3), "wilcoxon_p": None if p is None else round(p, 4),
            "paired_seeds": len(both)}


def _version(folder: Path) -> str | None:
    """What the SITL folder says it is: its BUILD_INFO.txt's first line ("arducopter: ArduCopter V4.8.0-dev ..."), if any."""
    info = folder / "BUILD_INFO.txt"
    return info.read_text(errors="replace").splitlines()[0][:200] if info.is_file() else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--chase-seeds", default="1-20", help="chase seeds (default 1-20)")
    parser.add_argument("--sar-seeds", default="1-10", help="search-and-rescue seeds (default 1-10)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="campaign worker processes")
    parser.add_argument("--ardupilot", type=Path, help="folder with arducopter (default $CHASER_BT_ARDUPILOT)")
    parser.add_argument("--out", type=Path, help="keep the campaigns here (default: a temporary folder)")
    add_record_flag(parser)
    args = parser.parse_args()
    os.environ.setdefault("MAVLINK20", "1")
    logging.basicConfig(level=logging.WARNING)
    from sitl.ardupilot.process import ArduPilotMissing, find_ardupilot
    from sitl.bench.campaign import parse_seeds

    try:
        folder = find_ardupilot(args.ardupilot)
    except ArduPilotMissing as exc:
        emit({"name": "parity", "skipped": str(exc)}, BENCHMARK, False)
        return
    chase_seeds, sar_seeds = parse_seeds(args.chase_seeds), parse_seeds(args.sar_seeds)
    line: dict = {"name": "parity", "chase_seeds": len(chase_seeds), "sar_seeds": len(sar_seeds),
                  "ardupilot_version": _version(folder)}
    with tempfile.TemporaryDirectory(prefix="bench_parity_") as tmp:
        out = args.out or Path(tmp)
        chase = {ap: _campaign(CHASE, chase_seeds, ap, out / ap / "chase", args) for ap in AUTOPILOTS}
        sar = {ap: _campaign(SAR, sar_seeds, ap, out / ap / "sar", args) for ap in AUTOPILOTS}
    line["chase_success"] = {ap: chase[ap].aggregates["success_frac"] for ap in AUTOPILOTS}
    for key in CHASE_KEYS:
        line[key] = _compare({ap: chase[ap].rows for ap in AUTOPILOTS}, key)
    line["sar_found"] = {ap: sar[ap].aggregates.get("sar_found_frac") for ap in AUTOPILOTS}
    for key in SAR_KEYS:
        line[key] = _compare({ap: sar[ap].rows for ap in AUTOPILOTS}, key)
    line["workers"] = args.workers
    emit(line, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
