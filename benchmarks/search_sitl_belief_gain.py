"""Belief gain over time in the full simulator (the paper's search-only SITL test, section 4.4):
RHC for h = 1..5 and gamma 0.5 / 0.9 against max-belief, each flown by the real mission tree
(sitl/bench/search_trial.py: MAVLink simulator, MissionRunner, radar silenced within 200 m, camera
detection off).

Prints one JSON line {"name": "search_sitl_belief_gain", "seeds": n, "search_s": s, "configs": {label:
{"mean_gain", "detected_30s", "detected_60s", "detected_end", "first_in_view_s_median", "in_view_frac",
"tick_ms_median", "tick_ms_p95"}}} and writes docs/img/search_sitl_belief_gain.png.
Run: .venv/bin/python benchmarks/search_sitl_belief_gain.py [--quick] [--seeds N] [--workers N]
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from sitl.bench.search_trial import SearchConfig, SearchTrial, run_trial

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from record import Benchmark, add_record_flag, emit  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
BIN_S = 1.0
BENCHMARK = Benchmark(
    "search_sitl_belief_gain", __doc__,
    against="built-in simulator: the paper's search-only test flown by the mission tree over MAVLink "
            "(sitl/bench/search_trial.py), camera detection off",
    units={
        "seeds": "runs per configuration", "search_s": "s of search per run",
        "configs": "per planner configuration",
        "runs": "runs that searched the whole time", "mean_gain": "mean belief gain per look",
        "detected_*": "mean cumulative detection probability by then (30 s, 60 s, the end), by the belief",
        "first_in_view_s_median": "s, median time until the target is first in the camera's view",
        "in_view_never": "runs in which it never was", "in_view_frac": "share of ticks with the target in view",
        "tick_ms_median": "ms, median tick wall time", "tick_ms_p95": "ms, p95 tick wall time",
    },
    headline=("configs.max-belief.detected_end", "configs.max-belief.tick_ms_p95"),
)


def configs(quick: bool) -> list[SearchConfig]:
    out = [SearchConfig("max")]
    for gamma in (0.5, 0.9):
        for h in ((1, 3, 5) if quick else range(1, 6)):
            out.append(SearchConfig("rhc", h, gamma))
    return out


def _run(job: tuple[SearchConfig, int, float]) -> SearchTrial:
    cfg, seed, search_s = job
    trial = run_trial(cfg, seed, search_s=search_s)
    trial.states = []
    return trial


def binned(trial: SearchTrial, values: list[float], search_s: float) -> np.ndarray:
    """Mean of ``values`` per BIN_S of search time (NaN where a bin has no tick)."""
    t = np.asarray(trial.t)
    edges = np.arange(0.0, search_s + BIN_S, BIN_S)
    idx = np.digitize(t, edges) - 1
    v = np.asarray(values, dtype=float)
    out = np.full(len(edges) - 1, np.nan)
    for b in range(len(out)):
        sel = idx == b
        if sel.any():
            out[b] = v[sel].mean()
    return out


def at_time(trial: SearchTrial, t_s: float) -> float:
    """The cumulative detection probability at ``t_s`` s of search (last value before it)."""
    t = np.asarray(trial.t)
    i = np.searchsorted(t, t_s, side="right") - 1
    return float(trial.detected[i]) if i >= 0 else 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--search-s", type=float, default=120.0)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--quick", action="store_true", help="2 seeds, 60 s, h = 1, 3, 5")
    add_record_flag(parser)
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    seeds, search_s = (2, 60.0) if args.quick else (args.seeds, args.search_s)
    cfgs = configs(args.quick)
    jobs = [(c, s, search_s) for c in cfgs for s in range(seeds)]
    if args.workers > 1:
        with ProcessPoolExecutor(args.workers) as pool:
            trials = list(pool.map(_run, jobs))
    else:
        trials = [_run(j) for j in jobs]

    out: dict = {"name": "search_sitl_belief_gain", "seeds": seeds, "search_s": search_s, "configs": {}}
    gain_series, det_series = {}, {}
    for cfg in cfgs:
        runs = [tr for tr in trials if tr.config == cfg]
        done = [tr for tr in runs if tr.t and tr.t[-1] >= search_s - 1.0]
        if len(done) < len(runs):
            logging.warning("%s: %d of %d runs did not search for %.0f s: %s", cfg.label, len(runs) - len(done), len(runs),
                            search_s, [tr.outcome for tr in runs if tr not in done])
        gain_series[cfg.label] = np.nanmean([binned(tr, tr.gain, search_s) for tr in done], axis=0)
        det_series[cfg.label] = np.nanmean([binned(tr, tr.detected, search_s) for tr in done], axis=0)
        first = [tr.first_in_view_s for tr in done]
        ticks = np.concatenate([tr.tick_ms for tr in done])
        out["configs"][cfg.label] = {
            "runs": len(done),
            "mean_gain": round(float(np.mean([np.mean(tr.gain) for tr in done])), 5),
            "detected_30s": round(float(np.mean([at_time(tr, 30.0) for tr in done])), 4),
            "detected_60s": round(float(np.mean([at_time(tr, 60.0) for tr in done])), 4),
            "detected_end": round(float(np.mean([tr.detected[-1] for tr in done])), 4),
            "first_in_view_s_median": None if any(f is None for f in first) else round(float(np.median(first)), 1),
            "in_view_never": sum(f is None for f in first),
            "in_view_frac": round(float(np.mean([np.mean(tr.in_view) for tr in done])), 4),
            "tick_ms_median": round(float(np.nanmedian(ticks)), 2),
            "tick_ms_p95": round(float(np.nanpercentile(ticks, 95)), 2),
        }
    emit(out, BENCHMARK, args.record, ensure_ascii=False)
    plot(gain_series, det_series, seeds, search_s, ROOT / "docs/img/search_sitl_belief_gain.png")


def plot(gain_series: dict, det_series: dict, seeds: int, search_s: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    t = np.arange(0.0, search_s, BIN_S) + BIN_S / 2
    colors = plt.get_cmap("viridis")(np.linspace(0, 0.9, 5))
    for label, g in gain_series.items():
        if label == "max-belief":
            style = dict(color="k", lw=2.5)
        else:
            h = int(label.split("h=")[1].split()[0])
            style = dict(color=colors[h - 1], lw=1.2, ls="-" if "γ=0.9" in label else "--")
        smooth = np.convolve(np.nan_to_num(g), np.ones(5) / 5, mode="same")
        ax.plot(t, smooth, label=label, **style)
        ax2.plot(t, det_series[label], label=label, **style)
    ax.set_xlabel("time since the search started (s)")
    ax.set_ylabel("belief gain per look (5 s running mean)")
    ax.set_title(f"Belief gain in SITL, camera detection off, mean of {seeds} seeds")
    ax2.set_xlabel("time since the search started (s)")
    ax2.set_ylabel("cumulative detection probability (belief)")
    ax2.set_title("Probability the search would have found the target")
    for a in (ax, ax2):
        a.grid(alpha=0.3)
    ax2.legend(fontsize=7, ncol=2, loc="lower right")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
