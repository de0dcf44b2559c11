"""Telemetry checked before it is believed: hand-made hostile messages, and any field values at all."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from vehicle_fakes import HOME, roundtrip

from chaser_bt.geo import GeoPoint
from chaser_bt.vehicle.source_watch import SequenceWatch
from chaser_bt.vehicle.state import VehicleState, update_state
from chaser_bt.vehicle.telemetry_check import TelemetryGate, TelemetryLimits, telemetry_problem


def _home(lat=HOME.lat_deg, lon=HOME.lon_deg, alt_m=HOME.alt_m):
    return mavlink2.MAVLink_home_position_message(round(lat * 1e7), round(lon * 1e7), round(alt_m * 1e3),
                                                  0, 0, 0, [1, 0, 0, 0], 0, 0, 0)


def _position(lat=HOME.lat_deg, lon=HOME.lon_deg, alt_m=HOME.alt_m + 20, rel_m=20.0, v_cms=(0, 0, 0)):
    return mavlink2.MAVLink_global_position_int_message(1000, round(lat * 1e7), round(lon * 1e7), round(alt_m * 1e3),
                                                        round(rel_m * 1e3), *v_cms, 0)


def _quaternion(q):
    return mavlink2.MAVLink_attitude_quaternion_message(1000, *q, 0, 0, 0)


@pytest.mark.parametrize("msg, reason", [
    (_quaternion((0.0, 0.0, 0.0, 0.0)), "quaternion_norm"),
    (_quaternion((math.nan, 0.0, 0.0, 1.0)), "non_finite"),
    (mavlink2.MAVLink_attitude_message(1000, 0.1, math.inf, 0.0, 0, 0, 0), "non_finite"),
    (mavlink2.MAVLink_attitude_message(1000, 0.1, 2.0, 0.0, 0, 0, 0), "attitude_range"),  # pitch past vertical
    (_position(lat=91.0), "position_range"),
    (_position(alt_m=200_000.0), "position_range"),  # 200 km up
    (_position(v_cms=(30000, 0, 0)), "speed_range"),  # 300 m/s
    (_home(alt_m=-2_147_483.0), "home_range"),
    (mavlink2.MAVLink_battery_status_message(0, 0, 0, 0, [0] * 10, 0, 0, 0, 120), "battery_range"),
])
def test_what_no_aircraft_reports_is_refused_with_its_reason(msg, reason):
    assert telemetry_problem(roundtrip(msg), VehicleState())[0] == reason


def test_a_unit_quaternion_a_real_position_and_a_first_home_pass():
    state = VehicleState()
    for msg in (_quaternion((0.9238795, 0.0, 0.0, 0.3826834)), _position(), _home()):
        assert telemetry_problem(roundtrip(msg), state) is None


def test_home_may_move_to_where_it_armed_but_not_jump():
    state = VehicleState(home=HOME)
    north_30m = HOME.lat_deg + 30.0 / 111_000.0  # ArduCopter resets home where it arms: metres away
    assert telemetry_problem(roundtrip(_home(lat=north_30m)), state) is None
    north_200m = HOME.lat_deg + 200.0 / 111_000.0
    reason, detail = telemetry_problem(roundtrip(_home(lat=north_200m)), state)
    assert reason == "home_jump" and "200 m across" in detail
    assert telemetry_problem(roundtrip(_home(alt_m=HOME.alt_m + 100.0)), state)[0] == "home_jump"


def test_the_gate_counts_drops_on_the_state_and_a_flood_is_a_fault_that_clears():
    state, gate = VehicleState(), TelemetryGate(TelemetryLimits(flood_window_s=2.0, flood_min=10))
    good, bad = roundtrip(_position()), roundtrip(_quaternion((0, 0, 0, 0)))
    for k in range(9):  # 9 bad among 9 good in 2 s: below flood_min
        assert gate.admit(good, state, 0.1 * k) and not gate.admit(bad, state, 0.1 * k + 0.05)
    assert state.telemetry_rejected == {"quaternion_norm": 9} and gate.fault == ""
    assert not gate.admit(bad, state, 0.95)  # the tenth: 10 of 19 in the window
    assert gate.fault.startswith("telemetry cannot be trusted: 10 of 19 messages dropped in 2 s")
    for k in range(30):  # 3 s of clean telemetry
        gate.admit(good, state, 1.0 + 0.1 * k)
    assert gate.fault == ""


def test_a_second_sender_under_the_vehicles_ids_is_seen_a_lossy_link_is_not():
    lossy = SequenceWatch()
    rng = np.random.default_rng(3)
    seq = 0
    for _ in range(1000):  # 30 % of packets lost: the counter only ever skips forward
        seq += 1 + int(rng.geometric(0.7)) - 1
        lossy.observe(seq)
    assert lossy.fault == "" and lossy.backward_steps == 0
    two = SequenceWatch()
    a, b = 0, 117
    for k in range(60):  # the real autopilot and a clone, interleaved
        a, b = a + 1, b + 1
        two.observe(a if k % 2 else b)
    assert "two senders use the vehicle's ids" in two.fault


_FIELD = st.one_of(st.integers(-2**31, 2**31 - 1), st.floats(allow_nan=True, allow_infinity=True))


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(["ATTITUDE", "ATTITUDE_QUATERNION", "GLOBAL_POSITION_INT", "HOME_POSITION"]),
       st.lists(_FIELD, min_size=10, max_size=10))
def test_whatever_the_fields_nothing_raises_and_what_is_believed_is_finite(mtype, values):
    # The wire format bounds each field's type; within it, any value. Checked messages never raise,
    # and a message that passes leaves the state finite where the tree reads it.
    maker = {
        "ATTITUDE": lambda v: mavlink2.MAVLink_attitude_message(1000, *[float(x) for x in v[:6]]),
        "ATTITUDE_QUATERNION": lambda v: _quaternion([float(x) for x in v[:4]]),
        "GLOBAL_POSITION_INT": lambda v: mavlink2.MAVLink_global_position_int_message(
            1000, *[int(x) if math.isfinite(x) else 0 for x in v[:3]], int(v[3]) if math.isfinite(v[3]) else 0,
            *[max(-32768, min(32767, int(x))) if math.isfinite(x) else 0 for x in v[4:7]], 0),
        "HOME_POSITION": lambda v: mavlink2.MAVLink_home_position_message(
            *[int(x) if math.isfinite(x) else 0 for x in v[:3]], 0, 0, 0, [1, 0, 0, 0], 0, 0, 0),
    }
    try:
        msg = roundtrip(maker[mtype](values))
    except Exception:  # a value the wire cannot carry (the encoder refuses it): not a message anyone can send
        return
    state = VehicleState(home=GeoPoint(HOME.lat_deg, HOME.lon_deg, HOME.alt_m))
    if telemetry_problem(msg, state) is not None:
        return
    update_state(state, msg, None)
    if mtype == "ATTITUDE_QUATERNION" or mtype == "ATTITUDE":
        assert math.isfinite(state.yaw_enu_rad) and np.all(np.isfinite(state.attitude.as_quat()))
    if mtype == "GLOBAL_POSITION_INT":
        assert -90 <= state.lat_deg <= 90 and np.all(np.isfinite(state.velocity_enu))
