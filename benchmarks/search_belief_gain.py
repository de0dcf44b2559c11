"""Belief gain over time, camera detection off (the paper's SITL figure, section 4.4): RHC for
h = 1..5 and several gamma against max-belief, open airspace, random-walk target.

Prints one JSON line {"name": "search_belief_gain", per configuration: mean belief gain per look
over the run and the mean cumulative detection probability at the end} and writes
docs/img/search_belief_gain.png. Run: .venv/bin/python benchmarks/search_belief_gain.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from search_experiment import DT, fly  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
BENCHMARK = Benchmark(
    "search_belief_gain", __doc__,
    against="kinematic searches (benchmarks/search_experiment.py): the planners and belief of chaser_bt.search, "
            "a kinematic chaser and target",
    units={
        "seeds": "searches per configuration", "duration_s": "s per search",
        "mean_gain": "mean belief gain per look over the run",
        "p_detect_cumulative": "mean cumulative detection probability at the end, by the belief",
    },
    headline=("max-belief.mean_gain", "RHC h=5 g=0.9.mean_gain", "max-belief.p_detect_cumulative",
              "RHC h=5 g=0.9.p_detect_cumulative"),
)


def configs():
    yield "max-belief", ("max", 1, 0.9)
    for gamma in (0.5, 0.9):
        for h in range(1, 6):
            yield f"RHC h={h} g={gamma}", ("rhc", h, gamma)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--duration", type=float, default=120.0)
    parser.add_argument("--quick", action="store_true")
    add_record_flag(parser)
    args = parser.parse_args()
    seeds, duration = (2, 60.0) if args.quick else (args.seeds, args.duration)
    out: dict = {"name": "search_belief_gain", "seeds": seeds, "duration_s": duration}
    series = {}
    for label, (kind, h, gamma) in configs():
        runs = np.array([fly(kind, "open", s, horizon=h, gamma=gamma, camera_on=False, duration_s=duration).gains for s in range(seeds)])
        series[label] = runs.mean(axis=0)
        cum = 1.0 - np.prod(1.0 - runs, axis=1)  # P(detected at least once), by the belief
        out[label] = {"mean_gain": round(float(runs.mean()), 5), "p_detect_cumulative": round(float(cum.mean()), 4)}
    emit(out, BENCHMARK, args.record)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.5))
    t = np.arange(len(next(iter(series.values())))) * DT
    for label, g in series.items():
        style = dict(color="k", lw=2.5) if label == "max-belief" else dict(lw=1, ls="-" if "0.9" in label else "--")
        ax.plot(t, np.convolve(g, np.ones(10) / 10, mode="same"), label=label, **style)
    ax.set_xlabel("time since the radar lost the target (s)")
    ax.set_ylabel("belief gain per look (5 s running mean)")
    ax.set_title(f"Belief gain, camera detection off, mean of {seeds} seeds")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    (ROOT / "docs/img").mkdir(parents=True, exist_ok=True)
    fig.savefig(ROOT / "docs/img/search_belief_gain.png", dpi=110)


if __name__ == "__main__":
    main()
