"""Rehearsal: fly a mission tree against the in-process simulator and score it (DESIGN §7).

The mission side is exactly what flies a real aircraft: a :class:`VehicleLink` speaking encoded
MAVLink (over an in-memory pipe instead of a radio), the :class:`MissionRunner` and a validated
tree. The two halves run lock-step in one thread: one physics step, one non-blocking poll of the
link, a tick when the mission clock says one is due. Nothing reads the wall clock except the
report's ``wall_time_s``, so a seed reproduces a run exactly.

Only this module looks at the simulator's ground truth, and only to score the run.
"""

from __future__ import annotations

import logging
import math
import statistics
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import py_trees

from chaser_bt.mission.clock import FunctionClock
from chaser_bt.mission.runner import MissionRunner, StatusChange
from chaser_bt.tree import MissionTree, load_tree, reset_blackboard
from chaser_bt.vehicle import LinkConfig, VehicleError, VehicleLink
from chaser_bt.vehicle.pipe import byte_pipe
from sitl.scenario import Scenario, load_scenario
from sitl.simulator import Simulator

__all__ = ["InProcessVehicle", "RehearsalReport", "rehearse"]

log = logging.getLogger(__name__)


@dataclass
class RehearsalReport:
    """The rehearsal's JSON report (keys of DESIGN §7 that apply to this mission, and more)."""

    outcome: str  # landed | completed | timeout | failsafe | crashed | error
    tree: str
    scenario: str
    seed: int
    sim_time_s: float
    wall_time_s: float
    realtime_factor: float
    ticks: int
    status_changes: int  # entries in the runner's tick log
    tick_ms_median: float
    landed_dist_m: float | None  # horizontal distance from home at the last touchdown
    max_alt_m: float  # highest point above home (truth)
    distance_flown_m: float  # horizontal path length (truth)
    battery_used_pct: float
    message: str  # why it ended: the last running leaf's feedback, or the error

    def to_dict(self) -> dict:
        return asdict(self)


class InProcessVehicle:
    """The simulator and a :class:`VehicleLink` joined by an in-memory MAVLink pipe, run lock-step.

    ``step()`` advances physics by one step and lets the link read what arrived. The link's timers
    run on simulated time (the rehearsal's stand-in for the wall clock) and the mission clock is
    the vehicle's boot time as telemetry reports it, exactly as when flying the simulator remotely.
    """

    def __init__(
        self,
        scenario: Scenario,
        seed: int,
        link_config: LinkConfig | None = None,
        ground_tap: Callable[[bytes], None] | None = None,
    ) -> None:
        """``ground_tap``, when given, sees every chunk of bytes the mission's link sends to the vehicle."""
        self.sim = Simulator(scenario, seed)
        vehicle_end, ground_end = byte_pipe()
        self.sim.attach(vehicle_end)
        end = ground_end if ground_tap is None else _TappedEnd(ground_end, ground_tap)
        # The pipe also carries the intruders' own telemetry: name the vehicle's system id, as a
        # ground station configured for one aircraft would, rather than lock onto whoever speaks first.
        config = link_config or LinkConfig(target_sysid=self.sim.endpoint.sysid)
        self.link = VehicleLink.over_pipe(end, config, monotonic=lambda: self.sim.time_s)
        self.clock = FunctionClock(lambda: self.link.state.t_boot_s)

    def step(self) -> None:
        self.sim.step()
        self.link.poll()

    def run_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Step until ``predicate()`` holds (True) or ``timeout_s`` of sim time pass (False)."""
        deadline = self.sim.time_s + timeout_s
        while not predicate():
            if self.sim.time_s >= deadline:
                return False
            self.step()
        return True

    def fly(self, runner: MissionRunner, timeout_s: float) -> py_trees.common.Status:
        """Tick ``runner`` lock-step until its root finishes or ``timeout_s`` pass; its last status."""
        self.run_until(lambda: runner.tick_if_due() and runner.finished, timeout_s)
        return runner.status


class _TappedEnd:
    """A pipe end that shows every chunk written to it to ``tap`` first (to compare what missions send)."""

    def __init__(self, end, tap: Callable[[bytes], None]) -> None:
        self._end, self._tap = end, tap

    def write(self, data: bytes) -> int:
        self._tap(bytes(data))
        return self._end.write(data)

    def read(self) -> bytes:
        return self._end.read()


class _Scorer:
    """Follows the ground truth during a run: touchdowns, height, distance flown."""

    def __init__(self) -> None:
        self.was_airborne = False
        self.landed_at: np.ndarray | None = None
        self.max_alt_m = 0.0
        self.distance_m = 0.0
        self._last_xy: np.ndarray | None = None

    def observe(self, truth) -> None:
        pos = np.asarray(truth.pos_enu, dtype=float)
        self.max_alt_m = max(self.max_alt_m, float(pos[2]))
        if self._last_xy is not None:
            self.distance_m += float(np.hypot(*(pos[:2] - self._last_xy)))
        self._last_xy = pos[:2].copy()
        if not truth.on_ground:
            self.was_airborne = True
        elif self.was_airborne:  # on the ground after flying: the latest touchdown point
            self.landed_at = pos.copy()

    @property
    def landed_dist_m(self) -> float | None:
        return None if self.landed_at is None else float(np.hypot(*self.landed_at[:2]))


def rehearse(
    tree: MissionTree | str | Path,
    scenario: Scenario | str | Path,
    seed: int,
    *,
    rate_hz: float = 10.0,
    link_config: LinkConfig | None = None,
    on_tick: Callable[[list[StatusChange]], None] | None = None,
    ground_tap: Callable[[bytes], None] | None = None,
) -> RehearsalReport:
    """Fly ``tree`` against a fresh simulator built from ``scenario`` with ``seed``; score it.

    ``on_tick`` is called after every tick with the tick's status changes (``--show-ticks``).
    ``ground_tap`` sees every chunk of bytes the mission sends to the vehicle (see :class:`InProcessVehicle`).
    """
    reset_blackboard()
    if not isinstance(tree, MissionTree):
        tree = load_tree(tree)
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)

    vehicle = InProcessVehicle(scenario, seed, link_config, ground_tap)
    sim = vehicle.sim
    runner = MissionRunner(tree, vehicle.link, vehicle.clock, rate_hz=rate_hz)
    if on_tick is not None:
        runner.on_tick(on_tick)
    scorer = _Scorer()
    battery_start = sim.autopilot.battery().remaining_pct

    outcome, message = "timeout", f"time limit of {scenario.time_limit_s:.0f} s reached"
    wall_start = time.perf_counter()
    try:
        while sim.time_s < scenario.time_limit_s:
            vehicle.step()
            truth = sim.truth
            scorer.observe(truth)
            if truth.crashed:
                outcome, message = "crashed", "the vehicle hit the ground hard"
                break
            if runner.tick_if_due() and runner.finished:
                message = runner.tip_message()
                outcome = _finished_outcome(runner.status, sim)
                runner.stop(f"root returned {runner.status.name}")
                break
    except VehicleError as exc:
        # The mission lost the vehicle (e.g. a scripted link loss): score what the autopilot's own
        # failsafes make of it.
        runner.stop(str(exc))
        outcome, message = _fly_out_failsafe(sim, scorer, scenario.time_limit_s, str(exc))
    except Exception as exc:  # a leaf raised: the run is an error, and it still gets a report
        log.exception("rehearsal tick raised")
        runner.stop(str(exc))
        outcome, message = "error", f"{type(exc).__name__}: {exc}"
    wall = time.perf_counter() - wall_start

    ticks_ms = runner.tick_wall_ms
    return RehearsalReport(
        outcome=outcome,
        tree=tree.name,
        scenario=scenario.name,
        seed=seed,
        sim_time_s=round(sim.time_s, 3),
        wall_time_s=round(wall, 3),
        realtime_factor=round(sim.time_s / wall, 1) if wall > 0 else math.inf,
        ticks=runner.ticks,
        status_changes=len(runner.tick_log),
        tick_ms_median=round(statistics.median(ticks_ms), 4) if ticks_ms else 0.0,
        landed_dist_m=None if scorer.landed_dist_m is None else round(scorer.landed_dist_m, 2),
        max_alt_m=round(scorer.max_alt_m, 2),
        distance_flown_m=round(scorer.distance_m, 1),
        battery_used_pct=round(battery_start - sim.autopilot.battery().remaining_pct, 2),
        message=message,
    )


def _finished_outcome(status: py_trees.common.Status, sim: Simulator) -> str:
    if status == py_trees.common.Status.FAILURE:
        return "error"
    return "landed" if sim.truth.on_ground and not sim.autopilot.armed else "completed"


def _fly_out_failsafe(sim: Simulator, scorer: _Scorer, limit_s: float, why: str) -> tuple[str, str]:
    """Keep simulating without the mission until the vehicle is down or time runs out."""
    while sim.time_s < limit_s and not (sim.truth.on_ground and not sim.autopilot.armed):
        sim.step()
        truth = sim.truth
        scorer.observe(truth)
        if truth.crashed:
            return "crashed", f"{why}; then the vehicle hit the ground hard"
    if sim.truth.on_ground and not sim.autopilot.armed:
        return "failsafe", f"{why}; the autopilot's failsafe brought it down"
    return "timeout", f"{why}; still airborne at the time limit"
