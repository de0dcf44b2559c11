"""Rehearsal: fly a mission tree against the in-process simulator and score it (DESIGN §7).

The mission side is exactly what flies a real aircraft: a :class:`VehicleLink` speaking encoded
MAVLink (over an in-memory pipe instead of a radio), the :class:`MissionRunner` and a validated
tree. The two halves run lock-step in one thread: one physics step, one non-blocking poll of the
link, a tick when the mission clock says one is due. Nothing reads the wall clock except the
report's ``wall_time_s``, so a seed reproduces a run exactly.

The mission gets every sensor the scenario provides (:mod:`sitl.bench.sensors`: radar, rendered camera,
target telemetry), as a real flight would. Only this module and :mod:`sitl.bench.scoring` look at the
simulator's ground truth, and only to score the run (DESIGN §7) and fill its flight trace.
"""

from __future__ import annotations

import copy
import logging
import math
import statistics
import time
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Callable

import numpy as np
import py_trees

from chaser_bt.cli_args import AUTOPILOTS
from chaser_bt.log.trace import FlightTrace, TraceEvent
from chaser_bt.mission.resources import required_resources, used_resources
from chaser_bt.mission.retask import RetaskRequest
from chaser_bt.mission.runner import MissionRunner, RunStatus, StatusChange
from chaser_bt.tree import MissionTree, load_tree, reset_blackboard
from chaser_bt.vehicle import LinkConfig, VehicleError, VehicleQuiet
from sitl.bench.in_process import InProcessVehicle
from sitl.bench.safe_end import SafeWatch
from sitl.bench.sar_scoring import SarObserver, people_enu
from sitl.bench.scoring import PHASE_KEY, RehearsalObserver
from sitl.bench.sensors import SensorOptions, build_sensors
from sitl.simulator import Simulator
from sitl.world.scenario import Scenario, load_scenario

__all__ = ["RehearsalInterrupted", "RehearsalReport", "SensorSetupError", "rehearse"]

log = logging.getLogger(__name__)

#: Simulated seconds after the mission stops in which its hold must take effect (``final_state``).
SETTLE_S = 10.0


@dataclass
class RehearsalReport:
    """The rehearsal's JSON report (keys of docs/design.md §7 that apply to this mission, and more).

    The scores (``t_airborne_s`` ... ``wrong_assoc_frac``) are defined in :mod:`sitl.bench.scoring`; each is
    None where it does not apply. ``trace`` (with ``rehearse(trace=True)``) is not part of
    :meth:`to_dict`.
    """

    outcome: str  # landed | completed | following | timeout | failsafe | crashed | error
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
    battery_used_pct: float | None  # None: the autopilot did not report its battery
    message: str  # why it ended: the last running leaf's feedback, or the error
    mission_outcome: str | None = None  # what the mission itself concluded, from telemetry (chaser_bt.mission.outcome)
    final_state: str | None = None  # the truth SETTLE_S after the mission stopped (sitl.bench.safe_end)
    t_safe_s: float | None = None  # first scripted fault -> the safe state that lasted (None: no fault, or not safe)
    t_airborne_s: float | None = None  # radar validation -> take-off altitude (paper 15.48 s)
    t_acquire_s: float | None = None  # take-off altitude -> first vision acquisition (paper 4.95 s)
    target_in_fov_frac: float | None = None  # from acquisition to the end of following (paper 0.91)
    target_in_fov_frac_flight: float | None = None  # over all autonomous flight
    detection_frac: float | None = None  # camera frames in that span with a true detection (paper 0.66)
    radar_assoc_frac: float | None = None  # 1 s windows in flight with the ownship's track associated (paper 0.917)
    wrong_assoc_frac: float | None = None  # ... associated to a track that is not the ownship
    radar_windows: int = 0  # 1 s windows behind radar_assoc_frac
    detection_frames: int = 0  # camera frames behind detection_frac (from acquisition to the end of following)
    custody_frac: float | None = None  # follow ticks following something: share on the designated object
    target_switches: int | None = None  # changes of the object followed
    losses: int | None = None  # the designated object unmatched for over 2 s while following
    reacquire_s_max: float | None = None  # the longest such gap that ended
    envelope_frac: float | None = None  # follow ticks inside the paper's envelope (30-50 m, 30-50 deg)
    custody_at_end: bool | None = None  # the last object followed is the designated one
    followed_s_by_object: dict[str, float] | None = None  # seconds each object was followed
    designated_object: str | None = None  # the object the mission designated (truth: its radar track's)
    retasks: list[dict] | None = None  # every retask offered (chaser_bt.mission.retask.Retask.as_dict), taken or not
    retasks_scheduled: int = 0  # retasks the scenario schedules (``retask``); a campaign's success needs each taken
    sensors: list[str] = field(default_factory=list)  # the sensors the tree requires or uses (of those the rehearsal provides)
    radar_pose: str | None = None  # calibrated | surveyed
    radar_pose_err_m: float | None = None  # mission's radar position minus the truth
    radar_yaw_err_deg: float | None = None
    sensors_wall_s: float = 0.0  # setting the sensors up (radar calibration, detector load, the camera's world), not in wall_time_s
    sar_found: bool | None = None  # search and rescue: the mission's last find lies within 10 m of a person
    sar_find_error_m: float | None = None  # ... its distance to the nearest person
    sar_t_find_s: float | None = None  # ... mission time of the first find
    trace: FlightTrace | None = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict:
        """Every key but the trace (JSON-ready)."""
        return {f.name: copy.copy(getattr(self, f.name)) for f in fields(self) if f.name != "trace"}


class _Scorer:
    """Follows the ground truth during a run: touchdowns, height, distance flown."""

    def __init__(self) -> None:
        self.was_airborne = False
        self.landed_at: np.ndarray | None = None
        self.max_alt_m = 0.0
        self.distance_m = 0.0
        self._last_xy: tuple[float, float] | None = None

    def observe(self, truth) -> None:
        """Called every physics step, so on plain floats (np.hypot kept: it is what the figures were scored with)."""
        x, y, z = np.asarray(truth.pos_enu, dtype=float).tolist()
        self.max_alt_m = max(self.max_alt_m, z)
        if self._last_xy is not None:
            self.distance_m += float(np.hypot(x - self._last_xy[0], y - self._last_xy[1]))
        self._last_xy = (x, y)
        if not truth.on_ground:
            self.was_airborne = True
        elif self.was_airborne:  # on the ground after flying: the latest touchdown point
            self.landed_at = np.array([x, y, z])

    @property
    def landed_dist_m(self) -> float | None:
        return None if self.landed_at is None else float(np.hypot(*self.landed_at[:2]))


class RehearsalInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) during a rehearsal: the tree was halted; ``report`` scores the flight so far.

    A KeyboardInterrupt, so a caller that does not look for the report (a campaign) still stops.
    """

    def __init__(self, report: RehearsalReport) -> None:
        super().__init__(report.message)
        self.report = report


class SensorSetupError(RuntimeError):
    """The rehearsal's sensors could not be set up (the camera's render process failed, say): nothing
    was flown. The message is one line, the cause's last; the cause is chained with its traceback."""


def rehearse(
    tree: MissionTree | str | Path,
    scenario: Scenario | str | Path,
    seed: int,
    *,
    rate_hz: float = 10.0,
    link_config: LinkConfig | None = None,
    on_tick: Callable[[list[StatusChange]], None] | None = None,
    ground_tap: Callable[[bytes], None] | None = None,
    sensors: SensorOptions | None = None,
    on_start: Callable[[MissionRunner, InProcessVehicle, dict], None] | None = None,
    trace: bool = False,
    progress: Callable[[float, str | None], None] | None = None,
    autopilot: AutopilotChoice | None = None,
) -> RehearsalReport:
    """Fly ``tree`` against a fresh simulator built from ``scenario`` with ``seed``; score it.

    ``on_tick`` is called after every tick with the tick's status changes (``--show-ticks``).
    ``ground_tap`` sees every chunk of bytes the mission sends to the vehicle (see :class:`InProcessVehicle`).
    ``sensors`` says which sensors the mission gets (default :class:`SensorOptions`: every one the
    scenario provides). ``on_start(runner, vehicle, resources)`` runs after the tree's setup, before
    the first tick (a recorder's hook). ``trace`` fills ``report.trace`` (:class:`FlightTrace`).
    ``progress(sim_time_s, phase)`` is called after every tick (:class:`~sitl.bench.rehearsal_progress.RehearsalProgress`).
    ``autopilot`` chooses who flies: the built-in simulator (default) or ArduPilot's ArduCopter SITL
    inside the same world (:class:`AutopilotChoice`, :mod:`sitl.bench.ardupilot_vehicle`).

    Raises:
        RehearsalInterrupted: on Ctrl-C, carrying the report of the flight so far (outcome ``interrupted``).
        SensorSetupError: the sensors could not be set up; nothing was flown.
    """
    reset_blackboard()
    if not isinstance(tree, MissionTree):
        tree = load_tree(tree)
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)

    vehicle = _vehicle(scenario, seed, link_config, ground_tap, autopilot or AutopilotChoice())
    sim = vehicle.sim
    sensors_start = time.perf_counter()
    options = sensors or SensorOptions()
    looks = "camera" in required_resources(tree.root)
    if options.render_process and not looks:
        options = replace(options, render_process=False)  # no leaf looks: no process to draw for it
    mission_sensors = None
    try:
        mission_sensors = build_sensors(vehicle, options, seed)
        if looks and mission_sensors.frame_source is not None:
            mission_sensors.frame_source.prepare()  # the camera's world is set-up, like the radar's calibration
    except BaseException as exc:
        if mission_sensors is not None:
            mission_sensors.close()
        vehicle.close()
        if isinstance(exc, Exception):
            last = str(exc).strip().splitlines()[-1:] or [""]  # a child's traceback ends with its own error
            raise SensorSetupError(f"the sensors could not be set up: {type(exc).__name__}: {last[0]}") from exc
        raise
    sensors_wall = time.perf_counter() - sensors_start
    runner = MissionRunner(tree, vehicle.link, vehicle.clock, rate_hz=rate_hz, resources=mission_sensors.resources)
    if on_tick is not None:
        runner.on_tick(on_tick)
    observer = RehearsalObserver(sim, vehicle.link, runner, mission_sensors, trace=trace)
    runner.on_retask(lambda r: observer.events.append(
        TraceEvent(r.t, "retask", f"{r.name}: {'taken' if r.accepted else 'refused'}, {r.message}")))
    scheduled = list(scenario.retasks)
    sar = SarObserver(sim)
    scorer = _Scorer()
    battery_start = sim.autopilot.battery().remaining_pct
    safety = SafeWatch()

    outcome, message = "timeout", f"time limit of {scenario.time_limit_s:.0f} s reached"
    run_status, verdict = RunStatus.INTERRUPTED, None  # as the mission sees it: stopped at the time limit
    wall_start = time.perf_counter()
    interrupted = False
    try:
        runner.setup()
        if on_start is not None:
            on_start(runner, vehicle, mission_sensors.resources)
        while sim.time_s < scenario.time_limit_s:
            vehicle.step()
            while scheduled and sim.time_s >= scheduled[0].at_s:  # between ticks: the retask's safe point
                due = scheduled.pop(0)
                runner.retask(RetaskRequest(due.tree.read_bytes(), due.tree.name, due.tree.parent,
                                            f"scenario at {due.at_s:g} s", subtree=due.subtree))
            truth = sim.truth
            scorer.observe(truth)
            safety.observe(sim.time_s, truth, sim.autopilot.mode, sim.autopilot.armed)
            if truth.crashed:
                outcome, message = "crashed", "the vehicle hit the ground hard"
                break
            if runner.tick_if_due():
                observer.after_tick(vehicle.clock.now())
                sar.after_tick()
                if progress is not None:
                    progress(sim.time_s, py_trees.blackboard.Blackboard.storage.get(PHASE_KEY))
                if runner.finished:
                    message = runner.end_message()
                    outcome = _finished_outcome(runner.status, sim)
                    if _falling(sim) or _autopilot_landing(sim, runner):  # score where it comes down
                        outcome, message = _fly_out_failsafe(sim, scorer, scenario.time_limit_s, message)
                    run_status = RunStatus.SUCCESS if runner.status == py_trees.common.Status.SUCCESS else RunStatus.FAILURE
                    runner.stop(f"root returned {runner.status.name}")
                    break
        else:
            if observer.following():
                outcome = "following"
                message = f"following at the time limit of {scenario.time_limit_s:.0f} s: {runner.tip_message()}"
            runner.stop(f"the rehearsal's time limit of {scenario.time_limit_s:.0f} s")  # as an operator ends a mission
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: halt the tree, and report what was flown so far
        runner.stop("interrupted by the operator")
        interrupted = True
        outcome, message = "interrupted", f"interrupted by the operator at {sim.time_s:.1f} s of simulated time"
    except VehicleError as exc:
        # The mission lost the vehicle (e.g. a scripted link loss): score what the autopilot's own
        # failsafes make of it.
        runner.stop(str(exc))
        verdict = runner.verdict(RunStatus.ERROR, str(exc), link_lost=isinstance(exc, VehicleQuiet))
        outcome, message = _fly_out_failsafe(sim, scorer, scenario.time_limit_s, str(exc))
    except Exception as exc:  # a leaf raised: the run is an error, and it still gets a report
        log.exception("rehearsal tick raised")
        runner.stop(str(exc))
        outcome, message = "error", f"{type(exc).__name__}: {exc}"
        run_status = RunStatus.ERROR
    finally:
        # the flight's figures, before the settle
        sim_time_s, battery_end, wall = sim.time_s, sim.autopilot.battery().remaining_pct, time.perf_counter() - wall_start
        if not interrupted:  # the mission has stopped: where does its last command leave the aircraft?
            try:
                _settle(vehicle, safety, SETTLE_S)
            except Exception:  # scoring only: never hide how the flight itself ended
                log.exception("could not simulate the settle after the mission stopped")
        mission_sensors.close()
        vehicle.close()
    if verdict is None:
        verdict = runner.verdict(run_status, message)

    ticks_ms = runner.tick_wall_ms
    pose_err = _radar_pose_error(sim, mission_sensors)
    report = RehearsalReport(
        outcome=outcome,
        tree=tree.name,
        scenario=scenario.name,
        seed=seed,
        sim_time_s=round(sim_time_s, 3),
        wall_time_s=round(wall, 3),
        realtime_factor=round(sim_time_s / wall, 1) if wall > 0 else math.inf,
        ticks=runner.ticks,
        status_changes=len(runner.tick_log),
        tick_ms_median=round(statistics.median(ticks_ms), 4) if ticks_ms else 0.0,
        landed_dist_m=None if scorer.landed_dist_m is None else round(scorer.landed_dist_m, 2),
        max_alt_m=round(scorer.max_alt_m, 2),
        distance_flown_m=round(scorer.distance_m, 1),
        battery_used_pct=_battery_used(battery_start, battery_end),
        message=message,
        mission_outcome=verdict.outcome.value,
        final_state=safety.state or None,
        t_safe_s=_rounded(safety.time_to_safe(_first_fault_s(scenario))),
        **observer.report_keys(),
        **sar.report_keys(),
        sensors=sorted(set(mission_sensors.resources) & used_resources(tree.root)),
        radar_pose=None if mission_sensors.radar_pose is None else mission_sensors.radar_pose.method,
        radar_pose_err_m=pose_err[0],
        radar_yaw_err_deg=pose_err[1],
        sensors_wall_s=round(sensors_wall, 3),
        retasks=[r.as_dict() for r in runner.retasks] or None,
        retasks_scheduled=len(scenario.retasks),
    )
    meta: dict = {"tree": tree.name, "scenario": scenario.name, "seed": seed, "outcome": outcome}
    people = people_enu(sim.scenario, sim_time_s)
    if people:  # for the overhead figure: where the people were, and the find
        meta["people_enu"] = [[round(float(v), 2) for v in p] for p in people]
        if sar.find is not None:
            meta["find_enu"] = [round(float(v), 2) for v in sar.find.position_enu]
    report.trace = observer.trace(meta)
    if interrupted:
        raise RehearsalInterrupted(report)
    return report


@dataclass(frozen=True)
class AutopilotChoice:
    """Who flies a rehearsal: ``"builtin"`` (the built-in simulator) or ``"ardupilot"`` (ArduCopter SITL
    in our world, on the rotor body ``airframe``, the binary in ``folder`` or where
    :func:`sitl.ardupilot.process.find_ardupilot` looks)."""

    name: str = "builtin"
    airframe: str = "s1000"
    folder: str | Path | None = None

    def __post_init__(self) -> None:
        if self.name not in AUTOPILOTS:
            raise ValueError(f"autopilot {self.name!r}: expected one of {', '.join(AUTOPILOTS)}")



def _vehicle(scenario: Scenario, seed: int, link_config: LinkConfig | None, ground_tap, choice: AutopilotChoice):
    if choice.name == "builtin":
        return InProcessVehicle(scenario, seed, link_config, ground_tap)
    if ground_tap is not None:
        raise ValueError("ground_tap needs the built-in simulator (ArduCopter's link is a TCP socket)")
    from sitl.bench.ardupilot_vehicle import ArduPilotVehicle

    return ArduPilotVehicle(scenario, seed, link_config, airframe=choice.airframe, ardupilot=choice.folder)


def _battery_used(start_pct: float, end_pct: float) -> float | None:
    """Percent of the battery used; None when the autopilot did not report it."""
    used = start_pct - end_pct
    return round(used, 2) if math.isfinite(used) else None


def _radar_pose_error(sim: Simulator, sensors) -> tuple[float | None, float | None]:
    """How far the mission's radar pose is from the truth: position (m) and boresight heading (deg)."""
    if sensors.radar is None or sim.radar is None:
        return None, None
    mine, true = sensors.radar.pose, sim.radar.pose
    d = float(np.linalg.norm(mine.position_enu - true.position_enu))
    dy = (mine.yaw_pitch_roll[0] - true.yaw_pitch_roll[0] + math.pi) % (2 * math.pi) - math.pi
    return round(d, 2), round(math.degrees(dy), 3)


def _finished_outcome(status: py_trees.common.Status, sim: Simulator) -> str:
    if status == py_trees.common.Status.FAILURE:
        return "error"
    return "landed" if sim.truth.on_ground and not sim.autopilot.armed else "completed"


def _settle(vehicle, safety: SafeWatch, seconds: float) -> None:
    """Simulate ``seconds`` more with the mission stopped (its hold sent), watching where the aircraft goes."""
    sim = vehicle.sim
    end = sim.time_s + seconds
    while sim.time_s < end:
        try:
            vehicle.step()
        except VehicleError:  # the mission's link is gone (a lost radio): the vehicle flies on regardless
            sim.step()
        safety.observe(sim.time_s, sim.truth, sim.autopilot.mode, sim.autopilot.armed)


def _first_fault_s(scenario: Scenario) -> float | None:
    """When the first scripted fault or foreign ground station's command strikes (None: none)."""
    times = [f.at_s for f in scenario.faults] + [e.at_s for e in scenario.ground_station]
    return min(times) if times else None


def _rounded(value: float | None, digits: int = 2) -> float | None:
    return None if value is None else round(value, digits)


def _falling(sim: Simulator) -> bool:
    return not sim.autopilot.armed and not sim.truth.on_ground


def _autopilot_landing(sim: Simulator, runner: MissionRunner) -> bool:
    """The tree stopped because the autopilot's own failsafe took the aircraft home or down (RTL, LAND)."""
    aborted = runner.witness.foreign_change() is not None and runner.witness.texts
    return bool(aborted) and sim.autopilot.armed and sim.autopilot.mode in ("RTL", "LAND")


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
