"""The paper's search-only SITL test (section 4.4) in the full simulator: belief gain over time.

A radar cues the chaser onto a target drone a few hundred metres out (``sitl/scenarios/search_only.yaml``).
The mission is a small tree flown by the real :class:`~chaser_bt.mission.runner.MissionRunner` over
the simulator's MAVLink (:class:`~sitl.bench.rehearsal.InProcessVehicle`) with the rehearsal's radar
(:func:`sitl.bench.sensors.build_sensors`, surveyed pose): wait for a validated track, take off, fly to the
radar cue, and when the cue is lost search with :class:`~behaviours.search.RHCSearch` or
:class:`~behaviours.search.MaxBeliefSearch`. As in the paper's test the radar goes silent once the
chaser is within ``silence_within_m`` (200 m) of the target -- this harness drops every datagram the
mission would receive from then on, deciding on the scoring side's knowledge of both positions (the
mission never reads truth) -- and the camera detects nothing, so the search runs on. Each tick of
the search logs the belief gain the mission published on ``/search/belief`` (the probability of
detecting the target at that look, given not seen before), the cumulative detection probability by
the belief (the sensor model's ledger) and, for scoring only, whether the target was really inside
the camera's footprint.

The target's path is drawn from the seed (:func:`target_waypoints`), so planners are compared seed by
seed; ``benchmarks/search_sitl_belief_gain.py`` runs the comparison and draws the figure.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import py_trees
import yaml

from chaser_bt.cli_args import seed as seed_argument
from chaser_bt.mission.runner import MissionRunner
from chaser_bt.search import GridSpec
from chaser_bt.tree import load_tree_text, reset_blackboard
from chaser_bt.vision.camera import CameraModel
from sitl.bench.in_process import InProcessVehicle
from sitl.bench.sensors import SensorOptions, build_sensors
from sitl.world.scenario import Scenario

__all__ = ["SEARCH_ONLY", "SearchConfig", "SearchTrial", "PlanningState", "RadarGate", "add_command", "run_trial",
           "search_tree", "summary", "target_waypoints", "trial_scenario"]

log = logging.getLogger(__name__)

SEARCH_ONLY = Path(__file__).resolve().parents[1] / "scenarios" / "search_only.yaml"
SEARCH_KEY = "/search/belief"

_TREE = """
version: 1
main: SearchOnly
trees:
  SearchOnly:
    Sequence:
      name: search only
      children:
        - RetryUntilSuccessful:
            name: wait for a validated track
            num_attempts: -1
            child: {{RadarTrackValidated: {{min_confidence: 0.8}}}}
        - ArmAndTakeoff: {{altitude_m: {altitude_m}}}
        - ForceSuccess:
            name: until the cue is lost
            child:
              ReactiveSequence:
                name: fly to the cue
                children:
                  - RadarCue: {{max_age_s: 2}}
                  - FollowGlobal: {{target: "{{target/cue}}", output: guided, slant_range_m: 40, elevation_deg: 0}}
        - {search}
"""


@dataclass(frozen=True)
class SearchConfig:
    """Which search the tree flies: ``planner`` "rhc" (horizon, gamma) or "max" (max-belief)."""

    planner: str
    horizon: int = 5
    gamma: float = 0.9

    def __post_init__(self) -> None:
        if self.planner not in ("rhc", "max"):
            raise ValueError(f"planner must be 'rhc' or 'max', got {self.planner!r}")

    @property
    def label(self) -> str:
        return "max-belief" if self.planner == "max" else f"RHC h={self.horizon} γ={self.gamma:g}"

    def node(self, grid_center: tuple[float, float, float]) -> str:
        """The search leaf in YAML flow style."""
        center = "[" + ", ".join(f"{v:.1f}" for v in grid_center) + "]"
        if self.planner == "max":
            return f"MaxBeliefSearch: {{grid_center: {center}}}"
        return f"RHCSearch: {{grid_center: {center}, horizon: {self.horizon}, gamma: {self.gamma}}}"


@dataclass(frozen=True)
class PlanningState:
    """A belief (on grid ``spec``) and pose the search planned on (for benchmarks/bench_search.py)."""

    spec: GridSpec
    belief: np.ndarray
    position_enu: np.ndarray
    yaw_enu_rad: float


@dataclass
class SearchTrial:
    """One search-only run. Times are mission seconds; ``t`` counts from the first search tick.

    ``gain[i]``: belief gain of the look at tick i (what the mission published); ``detected[i]``: the
    belief's cumulative detection probability (mass the sensor model removed); ``in_view[i]``
    (scoring only): the target truly inside the camera's footprint then.
    """

    config: SearchConfig
    seed: int
    radar_off_s: float | None = None
    search_start_s: float | None = None
    t: list[float] = field(default_factory=list)
    gain: list[float] = field(default_factory=list)
    detected: list[float] = field(default_factory=list)
    in_view: list[bool] = field(default_factory=list)
    tick_ms: list[float] = field(default_factory=list)
    states: list[PlanningState] = field(default_factory=list)
    outcome: str = "searched"
    wall_s: float = 0.0

    @property
    def first_in_view_s(self) -> float | None:
        """Seconds of search until the target was first inside the footprint (None: never)."""
        hits = np.flatnonzero(self.in_view)
        return float(self.t[hits[0]]) if hits.size else None


class RadarGate:
    """A datagram source that passes another's datagrams until :meth:`silence` (then none, ever)."""

    def __init__(self, source) -> None:
        self.source = source
        self.silenced = False

    def silence(self) -> None:
        self.silenced = True

    def receive(self) -> list[bytes]:
        data = self.source.receive()  # drained either way, as a radar that stopped sending
        return [] if self.silenced else data


def target_waypoints(seed: int, n: int = 12) -> list[list[float]]:
    """A seeded path for the target (ENU from home; the radar is 150 m north of home): starts 350-420 m
    north of home and wanders (legs of 40-90 m, turns of up to 90 deg) in a box 300-450 m north and
    +-200 m east, at least 100 m inside the search grid's edges, between 25 and 55 m up."""
    rng = np.random.default_rng([seed, 0x5EA])
    p = np.array([rng.uniform(-60, 60), rng.uniform(350, 420), rng.uniform(30, 50)])
    heading = rng.uniform(-math.pi, math.pi)
    pts = [p.copy()]
    for _ in range(n):
        heading += rng.uniform(-math.pi / 2, math.pi / 2)
        leg = rng.uniform(40, 90)
        q = p + leg * np.array([math.cos(heading), math.sin(heading), 0.0])
        q[0], q[1] = np.clip(q[0], -200, 200), np.clip(q[1], 300, 450)
        q[2] = float(np.clip(p[2] + rng.uniform(-10, 10), 25, 55))
        if np.linalg.norm(q[:2] - p[:2]) < 1.0:
            heading += math.pi
            continue
        heading = math.atan2(q[1] - p[1], q[0] - p[0])
        p = q
        pts.append(p.copy())
    return [[round(float(v), 1) for v in pt] for pt in pts]


def trial_scenario(seed: int, path: str | Path = SEARCH_ONLY, speed_mps: float = 4.0) -> Scenario:
    """The search-only scenario with the target's path drawn from ``seed``."""
    p = Path(path)
    doc = yaml.safe_load(p.read_text())
    doc["targets"][0]["waypoints"] = {"points_enu_m": target_waypoints(seed), "speed_mps": speed_mps, "loop": False}
    return Scenario.from_dict(doc, f"{p} (seed {seed})")


def search_tree(config: SearchConfig, grid_center: tuple[float, float, float], altitude_m: float = 40.0) -> str:
    """The search-only mission (YAML): validated track, take-off, fly to the cue, search once it is lost."""
    return _TREE.format(altitude_m=altitude_m, search=config.node(grid_center))


def run_trial(config: SearchConfig, seed: int, *, scenario: Scenario | None = None, search_s: float = 120.0,
              silence_within_m: float = 200.0, keep_states_every_s: float = 0.0, rate_hz: float = 10.0) -> SearchTrial:
    """Fly one search-only run (module docstring); stop ``search_s`` after the search starts.

    ``keep_states_every_s`` > 0 keeps a :class:`PlanningState` that often (for the planner benchmark).
    """
    reset_blackboard()
    scenario = scenario if scenario is not None else trial_scenario(seed)
    if scenario.radar is None or not scenario.targets:
        raise ValueError(f"{scenario.name}: a search-only trial needs a radar and a scripted target")
    vehicle = InProcessVehicle(scenario, seed)
    sim = vehicle.sim
    sensors = build_sensors(vehicle, SensorOptions(radar=True, radar_pose="surveyed", camera=False, telemetry=False), seed)
    radar = sensors.radar
    assert radar is not None
    gate = RadarGate(radar.source)
    radar.source = gate
    # The grid is the paper's, +-400 m around the radar, at the radar's surveyed position (mission knowledge).
    center = radar.pose.position_enu
    tree = load_tree_text(search_tree(config, (float(center[0]), float(center[1]), 0.0)), f"search trial {config.label}")
    runner = MissionRunner(tree, vehicle.link, vehicle.clock, rate_hz=rate_hz, resources=sensors.resources)
    camera = CameraModel()  # the behaviours' camera defaults, for scoring "in view"
    target = sim.scenario.targets[0].path
    out = SearchTrial(config, seed)
    wall0 = time.perf_counter()
    last_t, next_state_t = None, -math.inf
    runner.setup()
    try:
        while sim.time_s < scenario.time_limit_s:
            vehicle.step()
            truth = sim.truth
            if truth.crashed:
                out.outcome = "crashed"
                break
            tgt = target.position_enu(sim.time_s)
            if not gate.silenced and float(np.linalg.norm(truth.pos_enu - tgt)) <= silence_within_m:
                gate.silence()
                out.radar_off_s = float(sim.time_s)
            if not runner.tick_if_due():
                continue
            snap = py_trees.blackboard.Blackboard.storage.get(SEARCH_KEY)
            if snap is not None and snap.t != last_t:
                last_t = snap.t
                if out.search_start_s is None:
                    out.search_start_s = float(snap.t)
                out.t.append(float(snap.t) - out.search_start_s)
                out.gain.append(float(snap.gain))
                out.detected.append(float(snap.belief.ledger.observed))
                out.in_view.append(bool(camera.visible(tgt[None], truth.pos_enu, truth.attitude)[0]))
                out.tick_ms.append(float(runner.tick_wall_ms[-1]) if runner.tick_wall_ms else math.nan)
                if keep_states_every_s > 0 and snap.t >= next_state_t:
                    next_state_t = snap.t + keep_states_every_s
                    st = vehicle.link.state
                    pos = np.array(st.position_enu, dtype=float)
                    out.states.append(PlanningState(snap.belief.spec, snap.belief.p.copy(), pos, float(st.yaw_enu_rad)))
                if out.t[-1] >= search_s:
                    break
            if runner.finished:
                out.outcome = f"mission ended: {runner.tip_message()}"
                break
        else:
            out.outcome = "time limit before the search ran its course"
    finally:
        runner.stop("search trial over")
    out.wall_s = time.perf_counter() - wall0
    log.info("%s seed %d: %s, search from %.1f s, %d looks, %.1f s wall", config.label, seed, out.outcome,
             out.search_start_s or math.nan, len(out.t), out.wall_s)
    return out


def summary(trial: SearchTrial) -> dict:
    """The trial in a few numbers (the ``search-trial`` command's output)."""
    return {
        "config": trial.config.label, "seed": trial.seed, "outcome": trial.outcome,
        "radar_off_s": None if trial.radar_off_s is None else round(trial.radar_off_s, 2),
        "search_start_s": None if trial.search_start_s is None else round(trial.search_start_s, 2),
        "looks": len(trial.t), "searched_s": round(trial.t[-1], 1) if trial.t else 0.0,
        "mean_gain": round(float(np.mean(trial.gain)), 5) if trial.gain else 0.0,
        "detected": round(trial.detected[-1], 4) if trial.detected else 0.0,
        "first_in_view_s": None if trial.first_in_view_s is None else round(trial.first_in_view_s, 1),
        "wall_s": round(trial.wall_s, 1),
    }


#: The longest ``--horizon``. The exact planner searches the 26^h paths of h moves by branch and bound:
#: on the trial's 40 x 40 x 10 grid one plan takes about 0.02 s at h = 5, 0.4 s at h = 6, 1 s at
#: h = 7 and 8 s at h = 8 (peaked belief, one core), about 8x more per move; its tables grow as
#: (2h + 1)^3 (h = 1000 asks numpy for tens of GiB). Past 8 a plan never ends in a flight's time.
MAX_HORIZON = 8


def run_search_trial(args: argparse.Namespace) -> int:
    """``chaser-bt search-trial``: one search-only run; 0 when the search ran its course, 1 if not, 2 on bad input."""
    if args.horizon < 1 or not 0.0 < args.gamma <= 1.0 or not args.search_s > 0:
        print(f"chaser-bt: search-trial needs --horizon >= 1, 0 < --gamma <= 1 and --search-s > 0 (got {args.horizon}, "
              f"{args.gamma}, {args.search_s})", file=sys.stderr)
        return 2
    if args.horizon > MAX_HORIZON:
        print(f"chaser-bt: search-trial --horizon {args.horizon}: at most {MAX_HORIZON} (the exact search takes about "
              f"8x longer per move: seconds per plan at {MAX_HORIZON})", file=sys.stderr)
        return 2
    trial = run_trial(SearchConfig(args.planner, args.horizon, args.gamma), args.seed, search_s=args.search_s)
    out = summary(trial)
    if args.json:
        print(json.dumps(out, ensure_ascii=False))
    else:
        for key, value in out.items():
            print(f"{key:>16}: {'-' if value is None else value}")
    return 0 if trial.outcome == "searched" else 1


def add_command(subparsers) -> None:
    """Add ``search-trial`` to the ``chaser-bt`` sub-commands."""
    p = subparsers.add_parser("search-trial", help="the paper's search-only SITL test: fly to the radar cue, search on",
                              description="Fly sitl/scenarios/search_only.yaml in the simulator: the radar goes silent "
                                          "within 200 m of the target, the camera detects nothing, and the search runs "
                                          "on; print its belief gain and detection probability.")
    p.add_argument("--planner", choices=("rhc", "max"), default="rhc", help="RHC (Algorithm 2; default) or max-belief")
    p.add_argument("--horizon", type=int, default=5, metavar="H",
                   help=f"RHC moves per path, h, 1-{MAX_HORIZON}: the exact search takes about 8x longer per move "
                        f"(seconds per plan at h = {MAX_HORIZON}) (default 5)")
    p.add_argument("--gamma", type=float, default=0.9, metavar="X", help="RHC discount, in (0, 1] (default 0.9)")
    p.add_argument("--seed", type=seed_argument, default=1, metavar="N", help="simulator seed (also draws the target's path; default 1)")
    p.add_argument("--search-s", type=float, default=120.0, metavar="S", help="seconds of search before the trial stops (default 120)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=run_search_trial)
