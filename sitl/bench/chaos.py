"""Chaos for campaigns: one random fault per run, drawn from the run's seed, while the aircraft flies.

``campaign --chaos`` flies every run with one of these struck at a random time between 60 s and
140 s of simulated time, when the shipped missions are in the air (boot and take-off take about
55 s; the patrol and SAR land at about 150 s): a forced disarm, a failing battery cell (with ArduCopter's
default battery action, none), a GPS loss (EKF failsafe), a lost radio, or another ground station
switching to LOITER. The campaign then counts false successes (the mission said ``completed``
while the truth crashed or needed a failsafe) and runs that ended with the aircraft not safe
(:mod:`sitl.bench.safe_end`), and summarises the time from fault to safe.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from sitl.vehicle.setup import Fault, GroundStationEvent
from sitl.world.scenario import Scenario

__all__ = ["CHAOS_KINDS", "WINDOW_S", "with_random_fault"]

CHAOS_KINDS = ("disarm", "battery_drop", "gps_loss", "link_loss", "rc_loss", "ground_station_loiter")
#: When a fault may strike (s of simulated time): after the boot (pre-arm ~40 s) and the climb.
WINDOW_S = (60.0, 140.0)


def with_random_fault(scenario: Scenario, seed: int) -> tuple[Scenario, dict]:
    """``scenario`` with one fault drawn from ``seed``, and ``{"kind", "at_s"}`` for the report."""
    rng = np.random.default_rng([seed, 0xC4A05])
    kind = str(rng.choice(CHAOS_KINDS))
    at_s = round(float(rng.uniform(WINDOW_S[0], min(WINDOW_S[1], scenario.time_limit_s))), 1)
    if kind == "ground_station_loiter":
        changed = dataclasses.replace(scenario, ground_station=scenario.ground_station + (GroundStationEvent(at_s, "LOITER"),))
    else:
        changed = dataclasses.replace(scenario, faults=scenario.faults + (Fault(at_s, kind),))
        if kind == "battery_drop":
            changed = dataclasses.replace(changed, params={**scenario.params, "BATT_FS_LOW_ACT": 0})
    return changed, {"kind": kind, "at_s": at_s}
