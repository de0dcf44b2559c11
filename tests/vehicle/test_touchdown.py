"""A disarm is a landing only after a touchdown seen while armed; anything else is a fall."""

from __future__ import annotations

import numpy as np

from chaser_bt.vehicle.state import LandedState, VehicleState
from chaser_bt.vehicle.touchdown import Touchdown, TouchdownJudge


def _state(armed: bool, alt: float, vz: float = 0.0, landed: LandedState = LandedState.UNDEFINED) -> VehicleState:
    s = VehicleState(armed=armed, alt_rel_m=alt, landed_state=landed)
    s.velocity_enu = np.array([0.0, 0.0, vz])
    return s


def _fly(samples: list[tuple[float, VehicleState]]) -> TouchdownJudge:
    judge = TouchdownJudge()
    for t, s in samples:
        judge.observe(t, s)
    return judge


def test_a_landing_descent_then_disarm_is_landed():
    # LAND at 0.5 m/s: the last armed reports sit at the ground, settled; the disarm is heard 1 s later.
    samples = [(t, _state(True, max(0.0, 5.0 - 0.5 * t), -0.5 if t < 10 else 0.0)) for t in np.arange(0.0, 12.0, 0.25)]
    judge = _fly(samples + [(13.0, _state(False, 0.0))])
    assert judge.verdict is Touchdown.LANDED and judge.detail == "landed and disarmed"


def test_a_disarm_at_height_is_a_crash_naming_the_height():
    judge = _fly([(t, _state(True, 19.5)) for t in np.arange(0.0, 5.0, 0.25)] + [(5.2, _state(False, 19.3, -2.0))])
    assert judge.verdict is Touchdown.CRASHED
    assert "19.5 m above home" in judge.detail


def test_the_fall_after_the_disarm_is_not_taken_for_a_touchdown():
    # The heartbeat that says "disarmed" comes after the fall: the reports after it show the aircraft
    # at rest on the ground, but no armed report ever did.
    samples = [(t, _state(True, 2.0)) for t in np.arange(0.0, 3.0, 0.25)]
    judge = _fly(samples + [(3.7, _state(False, 0.0)), (4.0, _state(False, 0.0))])
    assert judge.verdict is Touchdown.CRASHED


def test_the_autopilots_on_ground_state_counts_at_any_height():
    # A landing on a roof 10 m above home: ArduCopter's land detector says ON_GROUND, and it holds still.
    samples = [(0.0, _state(True, 10.0, -0.3, LandedState.LANDING))]
    samples += [(t, _state(True, 10.0, 0.0, LandedState.ON_GROUND)) for t in np.arange(0.5, 2.0, 0.25)]
    judge = _fly(samples + [(2.2, _state(False, 10.0, 0.0, LandedState.ON_GROUND))])
    assert judge.verdict is Touchdown.LANDED


def test_on_ground_reported_as_the_rotors_stop_is_not_a_touchdown():
    # ArduCopter declares a disarmed aircraft landed at once; the HEARTBEAT saying "disarmed" comes
    # later, so the falling aircraft reads "armed, ON_GROUND" meanwhile, speeding up.
    samples = [(t, _state(True, 16.8, 0.0, LandedState.IN_AIR)) for t in np.arange(0.0, 2.0, 0.25)]
    samples += [(2.0 + dt, _state(True, 16.8 - 4.9 * dt * dt, -9.8 * dt, LandedState.ON_GROUND)) for dt in (0.05, 0.25, 0.5, 0.75)]
    judge = _fly(samples + [(2.9, _state(False, 12.0, -8.8, LandedState.ON_GROUND))])
    assert judge.verdict is Touchdown.CRASHED


def test_a_touchdown_too_brief_for_the_land_detector_is_not_a_landing():
    samples = [(0.0, _state(True, 3.0, -0.5)), (0.25, _state(True, 0.0, 0.0)), (0.5, _state(True, 0.0, 0.0))]
    assert _fly(samples + [(0.8, _state(False, 0.0))]).verdict is Touchdown.CRASHED


def test_in_air_state_overrides_a_low_height():
    # Hovering 0.5 m above home with the autopilot saying IN_AIR, then disarmed: a drop, not a landing.
    judge = _fly([(t, _state(True, 0.5, 0.0, LandedState.IN_AIR)) for t in np.arange(0.0, 3.0, 0.5)] + [(3.0, _state(False, 0.0))])
    assert judge.verdict is Touchdown.CRASHED


def test_a_touchdown_before_a_take_off_does_not_explain_a_later_disarm():
    samples = [(0.0, _state(True, 0.0)), (0.5, _state(True, 0.0))]
    samples += [(0.5 + k * 0.25, _state(True, 0.5 * k, 1.0, LandedState.IN_AIR)) for k in range(1, 8)]
    judge = _fly(samples + [(2.6, _state(False, 3.5))])
    assert judge.verdict is Touchdown.CRASHED and "3.5 m above home" in judge.detail


def test_a_touchdown_heard_too_long_before_the_disarm_does_not_count():
    judge = _fly([(0.0, _state(True, 0.0)), (5.0, _state(False, 0.0))])  # telemetry silent for 5 s
    assert judge.verdict is Touchdown.CRASHED and "0.0 m above home" in judge.detail


def test_never_armed_and_re_armed_are_flying():
    judge = _fly([(0.0, _state(False, 0.0)), (1.0, _state(False, 0.0))])
    assert judge.verdict is Touchdown.FLYING
    judge = _fly([(0.0, _state(True, 3.0)), (1.0, _state(False, 3.0)), (2.0, _state(True, 0.0))])
    assert judge.verdict is Touchdown.FLYING and judge.detail == ""
