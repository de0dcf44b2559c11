"""A fuzz campaign on the wire: the patrol flown while a hostile peer writes into the vehicle's link.

Each case flies the patrol with one kind of hostile input from 60 s on (``sitl/bench/hostile.py``:
random telemetry fields under the vehicle's ids, random bytes, a clone saying "LAND, disarmed", a
home 2,147 km below the sea). Every set-point the mission sends is checked against the default
command envelope from the simulator's true home; the run must end without an exception escaping
the tick and with the aircraft safe (landed, holding, or flown by the autopilot's RTL or
LAND). Prints one JSON line: {"name": "fuzz", "cases", "kinds", "injected", "telemetry_dropped",
"exceptions", "unsafe_commands", "unsafe_ends", "mission_outcomes", "wall_s"}; the goal is 0 for
exceptions, unsafe_commands and unsafe_ends.
Run: .venv/bin/python benchmarks/bench_fuzz.py [--cases N] [--quick]   (--quick: 8 cases, ~1 minute)
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from sitl.bench.hostile import SAFE_END, run_case  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402

BENCHMARK = Benchmark(
    "fuzz", __doc__,
    against="built-in simulator, a hostile peer writing into the vehicle's link (sitl/bench/hostile.py)",
    units={
        "cases": "patrol flights, one hostile kind each", "kinds": "flights per hostile kind",
        "injected": "hostile messages written", "telemetry_dropped": "telemetry the link refused, by reason",
        "exceptions": "exceptions escaping the tick (goal 0)",
        "unsafe_commands": "set-points outside the command envelope (goal 0)",
        "unsafe_ends": "flights not ending safe (goal 0)", "unsafe_end_cases": "[seed, kind, final state] of each",
        "mission_outcomes": "flights per mission outcome", "wall_s": "s of wall time",
    },
    headline=("cases", "exceptions", "unsafe_commands", "unsafe_ends"),
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=40)
    ap.add_argument("--quick", action="store_true", help="8 cases")
    add_record_flag(ap)
    args = ap.parse_args()
    cases = 8 if args.quick else args.cases
    start = time.perf_counter()
    rows = [run_case(seed) for seed in range(1, cases + 1)]
    dropped: Counter[str] = Counter()
    for r in rows:
        dropped.update(r["dropped"])
    unsafe_ends = [r for r in rows if r["final_state"] not in SAFE_END]
    emit({
        "name": "fuzz", "cases": cases, "kinds": dict(Counter(r["kind"] for r in rows)),
        "injected": sum(r["injected"] for r in rows), "telemetry_dropped": dict(dropped),
        "exceptions": sum(r["raised"] for r in rows), "unsafe_commands": sum(len(r["unsafe_commands"]) for r in rows),
        "unsafe_ends": len(unsafe_ends), "unsafe_end_cases": [(r["seed"], r["kind"], r["final_state"]) for r in unsafe_ends],
        "mission_outcomes": dict(Counter(r["mission_outcome"] for r in rows)),
        "wall_s": round(time.perf_counter() - start, 1),
    }, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
