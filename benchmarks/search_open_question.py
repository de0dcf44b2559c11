"""The paper's open question (sections 4.4 and 5): with no-go regions and a velocity-aware or
road-bound target, does RHC beat max-belief? Time to acquire with the camera on, >= 30 seeds.

Prints one JSON line {"name": "search_open_question", per scenario and planner: median / mean
time to acquire, share acquired, and the paired Wilcoxon p-value of RHC vs max-belief} and writes
docs/img/search_open_question.png (share of searches not yet acquired over time).
Run: .venv/bin/python benchmarks/search_open_question.py [--seeds 30] [--quick]
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from search_experiment import fly  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = {
    "open": "open airspace, random-walk target, Gaussian dynamics (the paper's case)",
    "buildings": "4 buildings as no-go, velocity-holding target, velocity-aware dynamics",
    "road": "road grid (target on roads only), road-constrained dynamics",
}
PLANNERS = {"maxbelief": ("max", 0, 0.0), "rhc_h3": ("rhc", 3, 0.9), "rhc_h5": ("rhc", 5, 0.9)}
BENCHMARK = Benchmark(
    "search_open_question", __doc__,
    against="kinematic searches (benchmarks/search_experiment.py) in open airspace, among buildings and on roads",
    units={
        "seeds": "searches per scenario and planner", "duration_s": "s per search",
        "t_acquire_median_s": "s, median time to acquire (duration when never acquired)",
        "t_acquire_mean_s": "s, mean time to acquire (duration when never acquired)",
        "acquired_frac": "share of searches that acquired",
        "median_diff_s": "s, median of RHC's time less max-belief's, paired by seed",
        "rhc_faster_frac": "share of seeds RHC acquired sooner", "rhc_slower_frac": "share of seeds RHC acquired later",
        "wilcoxon_p": "paired Wilcoxon signed-rank p-value, RHC against max-belief",
    },
    headline=("open.rhc_h5_vs_maxbelief.median_diff_s", "buildings.rhc_h5_vs_maxbelief.median_diff_s",
              "road.rhc_h5_vs_maxbelief.median_diff_s", "road.rhc_h5_vs_maxbelief.wilcoxon_p"),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--duration", type=float, default=180.0)
    parser.add_argument("--quick", action="store_true", help="6 seeds, 90 s (a smoke run, not the answer)")
    parser.add_argument("--workers", type=int, default=2, help="processes (runs are independent)")
    add_record_flag(parser)
    args = parser.parse_args()
    seeds, duration = (6, 90.0) if args.quick else (args.seeds, args.duration)
    from scipy.stats import wilcoxon

    results: dict = {"name": "search_open_question", "seeds": seeds, "duration_s": duration}
    curves = {}
    jobs = [(scen, label, s, duration) for scen in SCENARIOS for label in PLANNERS for s in range(seeds)]
    with multiprocessing.Pool(args.workers) as pool:
        done = dict(zip(jobs, pool.map(_one, jobs, chunksize=1)))
    for scen in SCENARIOS:
        times = {}
        for label in PLANNERS:
            t = [done[(scen, label, s, duration)] for s in range(seeds)]
            times[label] = np.array([duration if x is None else x for x in t])
            acquired = np.array([x is not None for x in t])
            results[f"{scen}.{label}"] = {
                "t_acquire_median_s": float(np.median(times[label])),
                "t_acquire_mean_s": round(float(times[label].mean()), 2),
                "acquired_frac": round(float(acquired.mean()), 3),
            }
            curves[(scen, label)] = times[label]
        for label in ("rhc_h3", "rhc_h5"):
            d = times[label] - times["maxbelief"]
            p = float(wilcoxon(times[label], times["maxbelief"]).pvalue) if np.any(d != 0) else 1.0
            results[f"{scen}.{label}_vs_maxbelief"] = {
                "median_diff_s": float(np.median(d)), "rhc_faster_frac": round(float((d < 0).mean()), 3),
                "rhc_slower_frac": round(float((d > 0).mean()), 3), "wilcoxon_p": round(p, 4)}
    emit(results, BENCHMARK, args.record)
    plot(curves, duration, seeds, ROOT / "docs/img/search_open_question.png")


def _one(job) -> float | None:
    scen, label, seed, duration = job
    kind, h, gamma = PLANNERS[label]
    return fly(kind, scen, seed, horizon=max(h, 1), gamma=gamma, duration_s=duration).t_acquire_s


def plot(curves, duration, seeds, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(SCENARIOS), figsize=(15, 4.2), sharey=True)
    grid = np.linspace(0, duration, 200)[:-1]  # a censored run (never acquired) stays "not acquired" to the end
    for ax, scen in zip(axes, SCENARIOS):
        for label in PLANNERS:
            t = curves[(scen, label)]
            ax.step(grid, [(t > g).mean() for g in grid], where="post", label=label)
        ax.set_title(f"{scen}: {SCENARIOS[scen]}", fontsize=8)
        ax.set_xlabel("time since radar lost the target (s)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"share not yet acquired ({seeds} seeds)")
    axes[0].legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
