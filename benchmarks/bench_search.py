"""Search speed: planning time of the exact RHC on the paper's grid for h = 1..5, belief update
time, and time to acquire (RHC h=5 vs max-belief, open airspace, camera on).

Prints one JSON line: {"name": "search", "grid": [41, 41, 11], "plan_ms": {"1": ..., "5": ...}
(median over planning states taken from kinematic searches), "plan_ms_p95": {...}, "plan_ms_max":
{...}, "plan_cpu_ms" / "plan_cpu_ms_max" (process CPU time: the cost on an unshared machine),
"plan_nodes" / "plan_nodes_max" (nodes the branch and bound expanded),
the same with "_sitl" over beliefs and poses of the search-only scenario flown in the full
simulator (sitl/bench/search_trial.py), "belief_update_ms": ...,
"seeds": n, "t_acquire_s_rhc_median": ..., "t_acquire_s_maxbelief_median": ...}. Times are
single-process wall and CPU time on this machine; the planner's compiled kernels are warmed up first.
Run: .venv/bin/python benchmarks/bench_search.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from search_experiment import fly  # noqa: E402

from chaser_bt.cue import TargetCue  # noqa: E402
from chaser_bt.search import (BeliefGrid, GaussianDynamics, GridSpec, MaxBeliefPlanner, RecedingHorizonPlanner,  # noqa: E402
                              SearchSession, SensorModel, level_attitude)
from chaser_bt.vision import CameraModel  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402

BENCHMARK = Benchmark(
    "search", __doc__,
    against="the planner on this machine's CPU, over beliefs from kinematic searches and from searches flown in the "
            "built-in simulator (_sitl); time to acquire from kinematic searches (benchmarks/search_experiment.py)",
    units={
        "grid": "belief grid cells [x, y, z]",
        "plan_ms*": "ms of wall time per exact RHC plan, by horizon h (median; _p95, _max)",
        "plan_cpu_ms*": "ms of process CPU time per plan, by horizon h (median; _max): the cost on an unshared machine",
        "plan_nodes*": "nodes the branch and bound expanded per plan, by horizon h (median; _max)",
        "planning_states": "planning states from kinematic searches", "planning_states_sitl": "planning states from the simulator",
        "belief_update_ms": "ms per belief update (dynamics and observation)",
        "seeds": "searches per planner for the time to acquire",
        "t_acquire_s_*_median": "s from the radar's loss to acquisition, median (180 s when never acquired)",
        "acquired_frac_*": "share of searches that acquired within 180 s",
    },
    headline=("plan_ms.5", "plan_cpu_ms.5", "plan_ms_sitl.5", "t_acquire_s_rhc_median", "t_acquire_s_maxbelief_median"),
)


def planning_states(n_runs: int):
    """(belief, position, yaw) at each re-plan of short max-belief searches: realistic beliefs and poses."""
    spec = GridSpec.around((0.0, 0.0, 0.0))
    sensor = SensorModel(CameraModel(), spec)
    states = []
    for seed in range(n_runs):
        rng = np.random.default_rng(seed)
        fix = np.array([rng.uniform(-200, 200), rng.uniform(-200, 200), rng.uniform(40, 100)])
        belief = BeliefGrid.from_cue(spec, TargetCue(0.0, fix, np.diag([8.0, 8.0, 5.0]) ** 2))
        ang = rng.uniform(-math.pi, math.pi)
        pos = fix + np.array([200 * math.cos(ang), 200 * math.sin(ang), 0.0])
        session = SearchSession(belief, GaussianDynamics(), sensor, MaxBeliefPlanner(spec), 0.0)
        yaw = ang + math.pi
        for k in range(1, 61):  # 60 s, a state every 6 s
            snap = session.update(float(k), pos, level_attitude(yaw), yaw)
            step = snap.target_enu - pos
            dist = float(np.linalg.norm(step))
            if dist > 1e-6:
                pos = pos + step / dist * min(dist, 12.0)
                yaw = math.atan2(step[1], step[0])
            if k % 6 == 0:
                states.append((belief.p.copy(), pos.copy(), yaw))
    return spec, sensor, states


def sitl_states(seeds: int, search_s: float):
    """(sensor, belief, position, yaw) every 6 s of max-belief searches flown in the full simulator
    (the paper's grid around the radar's surveyed position, so one grid per seed)."""
    from sitl.bench.search_trial import SearchConfig, run_trial

    states = []
    for seed in range(seeds):
        trial = run_trial(SearchConfig("max"), seed, search_s=search_s, keep_states_every_s=6.0)
        sensor = SensorModel(CameraModel(), trial.states[0].spec)
        states += [(sensor, s.belief, s.position_enu, s.yaw_enu_rad) for s in trial.states]
    return states


def plan_times(states, h: int) -> tuple[list[float], list[float], list[int]]:
    """Wall and process CPU time (ms) of the exact planner on each (sensor, belief, position, yaw), and the
    nodes its branch and bound expanded.

    CPU time is what the plan costs when the machine is not shared; wall time is what it costs now."""
    planners = {id(st[0]): RecedingHorizonPlanner(st[0], h, 0.9) for st in states}
    planners[id(states[0][0])].plan(*states[0][1:])  # compile / load the kernels outside the timing
    wall, cpu, nodes = [], [], []
    for sensor, p, pos, yaw in states:
        planner = planners[id(sensor)]
        t0, c0 = time.perf_counter(), time.process_time()
        plan = planner.plan(p, pos, yaw)
        wall.append(1e3 * (time.perf_counter() - t0))
        cpu.append(1e3 * (time.process_time() - c0))
        nodes.append(plan.nodes)
    return wall, cpu, nodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer planning states and seeds")
    add_record_flag(parser)
    args = parser.parse_args()
    spec, sensor, states = planning_states(2 if args.quick else 6)
    sitl = sitl_states(1 if args.quick else 2, 60.0)
    figures: dict[str, dict[str, float]] = {}

    def put(name: str, h: int, value: float) -> None:
        figures.setdefault(name, {})[str(h)] = round(float(value), 2)

    for h in range(1, 6):
        for suffix, sts in (("", [(sensor, *st) for st in states]), ("_sitl", sitl)):
            wall, cpu, nodes = plan_times(sts, h)
            put(f"plan_ms{suffix}", h, np.median(wall))
            put(f"plan_ms{suffix}_p95", h, np.percentile(wall, 95))
            put(f"plan_ms{suffix}_max", h, np.max(wall))
            put(f"plan_cpu_ms{suffix}", h, np.median(cpu))
            put(f"plan_cpu_ms{suffix}_max", h, np.max(cpu))
            put(f"plan_nodes{suffix}", h, np.median(nodes))
            put(f"plan_nodes{suffix}_max", h, np.max(nodes))

    belief = BeliefGrid.from_cue(spec, TargetCue(0.0, np.array([50.0, 50.0, 60.0]), np.eye(3) * 400.0))
    dyn = GaussianDynamics()
    t0 = time.perf_counter()
    for i in range(50):
        dyn.step(belief, 0.2)
        sensor.observe(belief, np.array([0.0, -100.0, 60.0]), level_attitude(0.1 * i))
    update_ms = 1e3 * (time.perf_counter() - t0) / 50

    seeds = 8 if args.quick else 30
    rhc = [fly("rhc", "open", s, horizon=5, gamma=0.9).t_acquire_s for s in range(seeds)]
    mx = [fly("max", "open", s).t_acquire_s for s in range(seeds)]
    censor = lambda xs: [180.0 if x is None else x for x in xs]  # noqa: E731
    emit({
        "name": "search", "grid": list(spec.shape), **figures,
        "planning_states": len(states), "planning_states_sitl": len(sitl), "belief_update_ms": round(update_ms, 3),
        "seeds": seeds,
        "t_acquire_s_rhc_median": float(np.median(censor(rhc))), "t_acquire_s_maxbelief_median": float(np.median(censor(mx))),
        "acquired_frac_rhc": round(float(np.mean([x is not None for x in rhc])), 3),
        "acquired_frac_maxbelief": round(float(np.mean([x is not None for x in mx])), 3),
    }, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
