"""The fault battery on both autopilots: the patrol flown with one fault each, built-in and ArduCopter SITL.

The cases are tests/e2e/test_fault_outcomes.py's: trees/patrol.yaml on sitl/scenarios/patrol.yaml
(seed 1) with

- ``no_fault``;
- ``disarm``: a forced disarm in the air;
- ``battery_drop``: a failing cell, with ArduCopter's default battery action, none (BATT_FS_LOW_ACT 0);
- ``gps_loss``: the GPS goes silent for good (the EKF failsafe);
- ``rc_loss``: the safety pilot's transmitter goes silent for good (the radio failsafe, FS_THR_ENABLE 1);
- ``rc_loss_guided_continues``: the same with FS_OPTIONS 4 (the radio failsafe leaves GUIDED flying);
- ``ground_station_loiter``: another ground station switches to LOITER;
- ``fence``: FENCE_ENABLE 1, FENCE_RADIUS 60 (the 100 m square does not fit: GUIDED refuses the leg);
- ``link_loss``: the mission's radio goes silent for good, with FS_GCS_ENABLE 1 (the built-in's
  default; ArduCopter ships it 0, and would then hover in GUIDED until the battery ran out).

Each fault strikes in the first leg, airborne at 20 m: on the built-in at 62 s of its clock (it is
ready to arm at 40 s, the scenario's ``boot.prearm_ok_s``, and at 20 m from about 54 s), on
ArduCopter at 22 s of the world's clock, which starts when ArduCopter is ready to arm (so the same
22 s after ready; at 20 m from about 14 s). ArduCopter gets its faults from a second ground station
on its SERIAL1 (:mod:`sitl.ardupilot.faults`).

Prints one JSON line: ``cases`` maps each case to ``{"builtin": {...}, "ardupilot": {...}, "agree": bool}``,
each autopilot's entry holding ``mission_outcome``, ``final_state``, ``outcome``, ``landed_dist_m``,
``t_safe_s``, ``sim_time_s``, ``message``, ``texts`` (the autopilot's failsafe texts the mission saw,
``runner.witness.texts``) and, on ArduCopter, ``injected`` (what the second ground station sent,
when, and ArduCopter's reply) and ``operator_texts`` (every STATUSTEXT that ground station heard).
``agree`` says whether the two autopilots' ``mission_outcome`` agree (null when one was not flown);
``disagree`` lists the cases where they do not. Without an ArduCopter SITL, ``ardupilot`` holds
``{"skipped": why}``. ArduCopter runs one at a time (about 15-40 s of wall time each on two cores).

Run: CHASER_BT_ARDUPILOT=DIR .venv/bin/python benchmarks/bench_fault_battery.py [--autopilot builtin|ardupilot|both]
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from sitl.bench.rehearsal import AutopilotChoice, rehearse  # noqa: E402
from sitl.vehicle.setup import Fault, GroundStationEvent  # noqa: E402
from sitl.world.scenario import Scenario, load_scenario  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402

TREE = ROOT / "trees" / "patrol.yaml"
SCENARIO = ROOT / "sitl" / "scenarios" / "patrol.yaml"
FAULT_AT_S = 62.0  # the built-in's clock, as tests/e2e/test_fault_outcomes.py: the first leg, at 20 m
log = logging.getLogger("bench_fault_battery")
BENCHMARK = Benchmark(
    "fault_battery", __doc__,
    against="built-in simulator and ArduCopter SITL, the same cases on both (an autopilot not flown says why)",
    units={
        "fault_at_s": "s on each autopilot's clock when the fault strikes",
        "cases.*.agree": "whether the two autopilots' mission_outcome agree (– when one was not flown)",
        "mission_outcome": "how the mission ended", "final_state": "the vehicle's state at the end",
        "landed_dist_m": "m from home where it landed", "t_safe_s": "s from the fault to a safe state",
        "sim_time_s": "simulated s", "texts": "the autopilot's failsafe texts the mission saw",
        "disagree": "cases whose autopilots disagree",
    },
    headline=("disagree", "cases.no_fault.builtin.mission_outcome", "cases.rc_loss.builtin.mission_outcome",
              "cases.link_loss.builtin.mission_outcome"),
)


@dataclass(frozen=True)
class Case:
    """One fault (or none) and the parameters it is flown with."""

    name: str
    fault: str | None = None  # a Fault kind
    loiter: bool = False  # a ground station's LOITER instead of a fault
    params: dict[str, float] = field(default_factory=dict)


CASES = (
    Case("no_fault"),
    Case("disarm", "disarm"),
    Case("battery_drop", "battery_drop", params={"BATT_FS_LOW_ACT": 0}),
    Case("gps_loss", "gps_loss"),
    Case("rc_loss", "rc_loss"),
    Case("rc_loss_guided_continues", "rc_loss", params={"FS_OPTIONS": 4}),
    Case("ground_station_loiter", loiter=True),
    Case("fence", params={"FENCE_ENABLE": 1, "FENCE_RADIUS": 60}),
    Case("link_loss", "link_loss", params={"FS_GCS_ENABLE": 1}),
)


def fault_at_s(autopilot: str, base: Scenario) -> float:
    """When the fault strikes on ``autopilot``'s clock: the same time after the vehicle is ready to arm."""
    return FAULT_AT_S if autopilot == "builtin" else FAULT_AT_S - base.boot.prearm_ok_s


def scenario_for(case: Case, autopilot: str, base: Scenario) -> Scenario:
    """The patrol scenario with ``case``'s fault and parameters."""
    at = fault_at_s(autopilot, base)
    changes: dict = {"params": {**base.params, **case.params}}
    if case.fault is not None:
        changes["faults"] = (Fault(at, case.fault),)
    if case.loiter:
        changes["ground_station"] = (GroundStationEvent(at, "LOITER"),)
    return dataclasses.replace(base, **changes)


def fly(case: Case, autopilot: str, base: Scenario, folder: Path | None, seed: int) -> dict:
    """Fly one case on one autopilot; the report's figures and what the autopilot said."""
    seen: dict = {}
    choice = AutopilotChoice(autopilot, folder=folder) if autopilot == "ardupilot" else AutopilotChoice()
    start = time.perf_counter()
    report = rehearse(TREE, scenario_for(case, autopilot, base), seed=seed, autopilot=choice,
                      on_start=lambda runner, vehicle, resources: seen.update(runner=runner, vehicle=vehicle))
    row = {"mission_outcome": report.mission_outcome, "final_state": report.final_state, "outcome": report.outcome,
           "landed_dist_m": report.landed_dist_m, "t_safe_s": report.t_safe_s, "sim_time_s": report.sim_time_s,
           "message": report.message, "texts": [text for _, text in seen["runner"].witness.texts]}
    injector = getattr(seen["vehicle"].sim, "faults", None) if autopilot == "ardupilot" else None
    if injector is not None:
        row["injected"] = [[i.at_s, i.what, i.reply] for i in injector.injections]
        row["operator_texts"] = [[t, text] for t, text in injector.texts]
    log.info("%s on %s: %s / %s (%.0f s of wall time)", case.name, autopilot, report.mission_outcome,
             report.final_state, time.perf_counter() - start)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--autopilot", choices=("builtin", "ardupilot", "both"), default="both",
                        help="who flies the battery (default both)")
    parser.add_argument("--ardupilot", type=Path, default=None,
                        help="folder of the ArduCopter SITL (default $CHASER_BT_ARDUPILOT, else ../shared/ardupilot)")
    parser.add_argument("--cases", default=",".join(c.name for c in CASES),
                        help=f"comma-separated cases (default all: {','.join(c.name for c in CASES)})")
    parser.add_argument("--seed", type=int, default=1, help="the scenario's seed (default 1)")
    add_record_flag(parser)
    args = parser.parse_args()
    os.environ.setdefault("MAVLINK20", "1")
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr, format="%(name)s: %(message)s")
    log.setLevel(logging.INFO)
    from sitl.ardupilot.process import ArduPilotMissing, find_ardupilot

    wanted = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = sorted(set(wanted) - {c.name for c in CASES})
    if unknown:
        parser.error(f"unknown case(s): {', '.join(unknown)}")
    cases = [c for c in CASES if c.name in wanted]
    autopilots = ["builtin", "ardupilot"] if args.autopilot == "both" else [args.autopilot]
    base = load_scenario(SCENARIO)
    skipped: dict[str, str] = {}
    folder = None
    if "ardupilot" in autopilots:
        try:
            folder = find_ardupilot(args.ardupilot)
        except ArduPilotMissing as exc:
            skipped["ardupilot"] = str(exc)
    results: dict[str, dict] = {}
    for case in cases:
        entry: dict = {}
        for autopilot in autopilots:
            if autopilot in skipped:
                entry[autopilot] = {"skipped": skipped[autopilot]}
                continue
            try:
                entry[autopilot] = fly(case, autopilot, base, folder, args.seed)
            except Exception as exc:  # one case's failure is a row, not the end of the battery
                log.exception("%s on %s failed", case.name, autopilot)
                entry[autopilot] = {"error": f"{type(exc).__name__}: {exc}"}
        outcomes = [entry.get(a, {}).get("mission_outcome") for a in ("builtin", "ardupilot")]
        entry["agree"] = outcomes[0] == outcomes[1] if None not in outcomes else None
        results[case.name] = entry
    emit({"tree": "patrol", "seed": args.seed, "fault_at_s": {a: fault_at_s(a, base) for a in autopilots},
          "cases": results, "disagree": [n for n, e in results.items() if e["agree"] is False]}, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
