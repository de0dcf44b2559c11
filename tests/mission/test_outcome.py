"""The outcome of a flight: hand-built evidence against the precedence rules and exit codes."""

from __future__ import annotations

import numpy as np
import pytest

from chaser_bt.mission.outcome import EXIT_CODES, FlightWitness, Outcome, judge
from chaser_bt.vehicle.mode_authority import ForeignModeChange, ModeAuthority
from chaser_bt.vehicle.state import LandedState, VehicleState


def _witness(*, crash_at_m: float | None = None, foreign: list[ForeignModeChange] = (), texts=()) -> FlightWitness:
    authority = ModeAuthority(lambda: 0.0, lambda: 1)
    authority.foreign.extend(foreign)
    w = FlightWitness(authority=authority, texts=list(texts))
    if crash_at_m is not None:
        s = VehicleState(armed=True, alt_rel_m=crash_at_m, landed_state=LandedState.IN_AIR)
        s.velocity_enu = np.zeros(3)
        w.observe(10.0, s)
        s.armed = False
        w.observe(10.5, s)
    return w


def test_only_completed_exits_zero_and_every_outcome_has_its_own_code():
    assert EXIT_CODES[Outcome.COMPLETED] == 0
    assert set(EXIT_CODES) == set(Outcome)
    assert len(set(EXIT_CODES.values())) == len(Outcome) and 2 not in EXIT_CODES.values()  # 2 is bad input


def test_a_tree_that_succeeded_on_its_own_path_completed():
    v = judge("success", "return and land: landed and disarmed", _witness())
    assert v.outcome is Outcome.COMPLETED and v.exit_code == 0 and v.line() == "completed: return and land: landed and disarmed"


def test_a_crash_beats_the_trees_own_success():
    # The runner's RTL said nothing wrong (e.g. a leaf that only waits for a disarm): the witness saw a fall.
    v = judge("success", "landed and disarmed", _witness(crash_at_m=19.5))
    assert v.outcome is Outcome.CRASHED and v.exit_code == 6
    assert "disarmed in the air at 19.5 m" in v.cause


def test_a_guard_branch_is_a_return_not_a_completion():
    v = judge("success", "return and land: landed and disarmed", _witness(), "safety:battery")
    assert v.outcome is Outcome.RETURNED_EARLY and v.exit_code == 3 and v.cause.startswith("battery guard")


@pytest.mark.parametrize("why, texts, outcome", [
    ("Battery 1 is low 10.40V used 8000 mAh", [(99.0, "Battery 1 is low 10.40V used 8000 mAh")], Outcome.AUTOPILOT_ABORT),
    ("EKF Failsafe", [(98.0, "EKF Failsafe")], Outcome.AUTOPILOT_ABORT),
    ("", [], Outcome.PILOT_TOOK_OVER),
    # a failsafe text long before a pilot's switch does not explain it
    ("", [(20.0, "Battery 1 is low 10.40V used 8000 mAh")], Outcome.PILOT_TOOK_OVER),
])
def test_someone_elses_mode_is_the_autopilots_when_its_own_text_explains_it(why, texts, outcome):
    change = ForeignModeChange(100.0, "GUIDED", "LOITER" if outcome is Outcome.PILOT_TOOK_OVER else "RTL", True, why)
    v = judge("success", "pilot has the aircraft", _witness(foreign=[change], texts=texts))
    assert v.outcome is outcome
    assert "GUIDED -> " in v.cause


def test_a_mode_change_on_the_ground_is_not_a_take_over():
    change = ForeignModeChange(5.0, "STABILIZE", "GUIDED", False)
    assert judge("success", "done", _witness(foreign=[change])).outcome is Outcome.COMPLETED


@pytest.mark.parametrize("status, kwargs, phase, outcome", [
    ("interrupted", {}, None, Outcome.INTERRUPTED),
    ("error", {"link_lost": True}, None, Outcome.LINK_LOST),
    ("success", {}, "safety:link_lost", Outcome.LINK_LOST),
    ("error", {}, None, Outcome.ERROR),
    ("failure", {}, None, Outcome.FAILED),
    ("success", {}, "safety:pilot_gate", Outcome.PILOT_TOOK_OVER),
    ("failure", {}, "safety:geofence", Outcome.FAILED),  # the guard's RTL itself failed
    ("success", {}, "follow", Outcome.COMPLETED),
])
def test_precedence_of_the_runs_own_ending(status, kwargs, phase, outcome):
    assert judge(status, "why", _witness(), phase, **kwargs).outcome is outcome


def test_failsafe_texts_that_changed_nothing_are_kept_as_notes():
    v = judge("success", "done", _witness(texts=[(50.0, "Battery 1 is low 10.40V used 0 mAh")] * 3))
    assert v.outcome is Outcome.COMPLETED and v.notes == ("Battery 1 is low 10.40V used 0 mAh",)
    assert v.line().endswith("(autopilot: Battery 1 is low 10.40V used 0 mAh)")
