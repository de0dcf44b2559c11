"""Simulator + mission speed: the patrol rehearsal's realtime factor, and the simulator's alone.

Prints one JSON line:

- ``realtime_factor`` (the headline figure): the patrol rehearsal, simulated seconds per wall
  second. The simulator and the mission tree run lock-step in one thread through encoded MAVLink
  (``sitl.bench.rehearsal.rehearse(trees/patrol.yaml, sitl/scenarios/patrol.yaml, seed)``), so it
  counts physics, the autopilot, telemetry encoding, the mission's link decoding it and the tree's
  ticks. ``tick_ms_median`` is the median wall time of one tree tick in it.
- ``simulator_realtime_factor``: the simulator alone (physics, autopilot and the MAVLink it
  serves), no mission: the same square flown by commanding the autopilot directly, with one port
  attached whose bytes (telemetry at the simulator's default stream rates) are read and dropped.

Each is the best of ``--repeats`` runs (the machine is shared); ``*_all`` lists every run.
Run: .venv/bin/python benchmarks/bench_sitl.py
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
from record import Benchmark, add_record_flag, emit  # noqa: E402

BENCHMARK = Benchmark(
    "sitl", __doc__,
    against="built-in simulator: the patrol (trees/patrol.yaml, sitl/scenarios/patrol.yaml), no camera",
    units={
        "realtime_factor": "simulated s per wall s, the patrol rehearsal (best of the repeats)",
        "what": "what realtime_factor measures",
        "tick_ms_median": "ms, median wall time of one tree tick",
        "sim_time_s": "simulated s of the best run", "wall_time_s": "wall s of the best run",
        "outcome": "how the best run ended",
        "*_all": "every run's figure",
        "simulator_realtime_factor": "simulated s per wall s, the simulator alone (best of the repeats)",
        "simulator_what": "what simulator_realtime_factor measures",
        "simulator_sim_time_s": "simulated s of the simulator-alone square",
    },
    headline=("realtime_factor", "tick_ms_median", "simulator_realtime_factor"),
)
PATROL_SCENARIO = ROOT / "sitl/scenarios/patrol.yaml"
SQUARE_ENU = ((100.0, 0.0, 20.0), (100.0, 100.0, 20.0), (0.0, 100.0, 20.0), (0.0, 0.0, 20.0))
_GUIDED, _RTL = 4, 6  # ArduCopter mode numbers


def simulator_alone(seed: int) -> tuple[float, float]:
    """Fly the patrol square on the simulator with no mission; (sim seconds, wall seconds)."""
    from chaser_bt.vehicle.pipe import byte_pipe
    from sitl.simulator import Simulator
    from sitl.world.scenario import load_scenario

    scenario = load_scenario(PATROL_SCENARIO)
    sim = Simulator(scenario, seed)
    vehicle_end, ground_end = byte_pipe()
    sim.attach(vehicle_end)
    ap = sim.autopilot

    def step_until(done, timeout_s: float) -> None:
        deadline = sim.time_s + timeout_s
        while not done() and sim.time_s < deadline:
            sim.step()
            ground_end.read()

    def near(target: tuple[float, float, float]) -> bool:
        return abs(ap.ex - target[0]) < 1.0 and abs(ap.ey - target[1]) < 1.0 and abs(ap.ez - target[2]) < 1.0

    start = time.perf_counter()
    step_until(lambda: ap.prearm_ok, scenario.time_limit_s)
    ap.request_mode(_GUIDED)
    ap.request_arm(True)
    ap.request_takeoff(20.0)
    step_until(lambda: ap.alt_rel() > 19.0, 60.0)
    for corner in SQUARE_ENU:
        ap.set_position_target(corner)
        step_until(lambda: near(corner), 60.0)
    ap.request_mode(_RTL)
    step_until(lambda: not ap.armed, 120.0)
    return sim.time_s, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=3, help="report the best of N runs (the machine is shared)")
    add_record_flag(parser)
    args = parser.parse_args()
    os.environ.setdefault("MAVLINK20", "1")
    from sitl.bench.rehearsal import rehearse

    runs = [rehearse(ROOT / "trees/patrol.yaml", PATROL_SCENARIO, args.seed) for _ in range(args.repeats)]
    best = max(runs, key=lambda r: r.realtime_factor)
    alone = [simulator_alone(args.seed) for _ in range(args.repeats)]
    alone_factors = [round(sim_s / wall_s, 1) for sim_s, wall_s in alone]
    emit({
        "name": "sitl",
        "realtime_factor": best.realtime_factor,
        "what": "patrol rehearsal: simulator + mission tree lock-step over encoded MAVLink, sim s per wall s",
        "tick_ms_median": best.tick_ms_median,
        "sim_time_s": best.sim_time_s,
        "wall_time_s": best.wall_time_s,
        "outcome": best.outcome,
        "realtime_factor_all": [r.realtime_factor for r in runs],
        "simulator_realtime_factor": max(alone_factors),
        "simulator_what": "simulator alone flying the square by direct autopilot commands, telemetry encoded to one port",
        "simulator_sim_time_s": round(alone[0][0], 3),
        "simulator_realtime_factor_all": alone_factors,
    }, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
