"""The link against a vehicle that lies: absurd telemetry, a jumping home, a frozen clock, a clone,
and set-points outside the command envelope. Nothing raises out of poll(), nothing absurd is sent."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from vehicle_fakes import HOME, make_rig

from chaser_bt.vehicle import CommandEnvelope, LinkConfig, UnsafeCommand, VehicleQuiet


def _guided_in_the_air():
    rig = make_rig(armed=True, mode_number=4)
    rig.fake.position = (HOME.lat_deg, HOME.lon_deg, HOME.alt_m + 20.0, 20.0)
    rig.run(2.5)
    assert rig.link.state.home is not None and rig.link.state.mode == "GUIDED"
    return rig


def _position_targets(rig):
    return rig.fake.sent_by_link("SET_POSITION_TARGET_GLOBAL_INT")


def test_a_target_beyond_the_envelope_is_never_sent():
    rig = _guided_in_the_air()
    for target in ([0.0, 12_431_000.0, 20.0], [0.0, 100.0, 6_006_110.0], [math.nan, 0.0, 20.0]):
        with pytest.raises(UnsafeCommand):
            rig.link.goto_enu(target)
    with pytest.raises(UnsafeCommand, match="40.0 m/s across"):
        rig.link.velocity_enu([40.0, 0.0, 0.0])
    rig.run(0.5)
    assert _position_targets(rig) == [] and rig.fake.sent_by_link("SET_POSITION_TARGET_LOCAL_NED") == []
    rig.link.goto_enu([30.0, 40.0, 20.0])  # inside: sent
    rig.run(0.2)
    assert len(_position_targets(rig)) == 1


def test_the_envelope_is_configurable():
    tight = CommandEnvelope(max_distance_m=50.0, max_alt_m=30.0, max_speed_mps=5.0)
    rig = make_rig(LinkConfig(envelope=tight), armed=True, mode_number=4)
    rig.run(2.5)
    with pytest.raises(UnsafeCommand, match="60 m from home"):
        rig.link.goto_enu([0.0, 60.0, 10.0])
    with pytest.raises(UnsafeCommand):
        rig.link.set_speed(6.0)
    rig.link.goto_enu([0.0, 45.0, 25.0])


FENCE = {"FENCE_ENABLE": 1, "FENCE_TYPE": 7, "FENCE_RADIUS": 300.0, "FENCE_ALT_MAX": 100.0, "FENCE_ALT_MIN": -10.0,
         "FENCE_MARGIN": 2.0}


def test_the_envelope_keeps_inside_the_vehicles_fence_less_its_margin():
    env = CommandEnvelope()
    # ArduCopter's defaults with the fence on (type 7: maximum altitude, circle, polygon): 298 m, 98 m.
    inside = env.within_fence(FENCE)
    assert (inside.max_distance_m, inside.max_alt_m, inside.min_alt_m) == (298.0, 98.0, -20.0)
    # The minimum altitude too (type 15); a circle wider than the envelope leaves the envelope's.
    both = env.within_fence({**FENCE, "FENCE_TYPE": 15, "FENCE_RADIUS": 5000.0})
    assert (both.max_distance_m, both.max_alt_m, both.min_alt_m) == (2000.0, 98.0, -8.0)
    # Off, half-read, or no usable space: unchanged.
    assert env.within_fence({**FENCE, "FENCE_ENABLE": 0}) is env
    assert env.within_fence({k: v for k, v in FENCE.items() if k != "FENCE_MARGIN"}) is env
    nonsense = env.within_fence({**FENCE, "FENCE_RADIUS": 1.0, "FENCE_ALT_MAX": 1.0})
    assert (nonsense.max_distance_m, nonsense.max_alt_m) == (2000.0, 500.0)


def test_a_target_beyond_the_vehicles_fence_is_not_sent_once_the_fence_is_read():
    rig = _guided_in_the_air()
    rig.link.goto_enu([0.0, 350.0, 20.0])  # the fence not read yet: the configured envelope
    rig.link.params.update(FENCE)  # as PARAM_VALUEs would fill it (chaser_bt.mission.preflight.read_fence)
    with pytest.raises(UnsafeCommand, match="350 m from home, beyond the envelope's 298 m"):
        rig.link.goto_enu([0.0, 350.0, 20.0])
    with pytest.raises(UnsafeCommand, match="outside the envelope's -20..98 m"):
        rig.link.goto_enu([0.0, 100.0, 99.0])
    rig.link.goto_enu([0.0, 290.0, 90.0])


def test_a_home_that_jumps_two_thousand_km_down_is_dropped_and_targets_stay_relative_to_the_first():
    rig = _guided_in_the_air()
    rig.fake.mav.home_position_send(int(HOME.lat_deg * 1e7), int(HOME.lon_deg * 1e7), -2_147_483_000,
                                    0, 0, 0, [1, 0, 0, 0], 0, 0, 0)
    rig.run(0.5)
    assert rig.link.state.home.alt_m == pytest.approx(HOME.alt_m)
    assert rig.link.state.telemetry_rejected["home_range"] == 1
    rig.link.goto_enu([10.0, 0.0, 25.0])
    rig.run(0.2)
    (sent,) = _position_targets(rig)
    assert sent.alt == pytest.approx(25.0, abs=0.01)  # relative to the real home, not +2,147,584 m


def test_a_zero_quaternion_is_dropped_inside_poll_not_raised():
    rig = _guided_in_the_air()
    rig.fake.mav.attitude_quaternion_send(int(rig.clock.now() * 1000), 0.0, 0.0, 0.0, 0.0, 0, 0, 0)
    rig.fake.mav.attitude_quaternion_send(int(rig.clock.now() * 1000), math.nan, 0.0, 0.0, 1.0, 0, 0, 0)
    rig.run(0.5)
    assert rig.link.state.telemetry_rejected == {"quaternion_norm": 1, "non_finite": 1}
    assert rig.link.state.telemetry_fault == ""


def test_a_flood_of_garbage_telemetry_is_a_fault_then_quiet_and_the_hold_is_a_stop():
    rig = _guided_in_the_air()

    def flood():
        for _ in range(20):
            rig.fake.mav.attitude_quaternion_send(int(rig.clock.now() * 1000), 0.0, 0.0, 0.0, 0.0, 0, 0, 0)

    rig.fake.tick, real_tick = (lambda: (flood(), real_tick())), rig.fake.tick
    rig.run(0.2)
    assert rig.link.state.telemetry_fault.startswith("telemetry cannot be trusted")
    assert rig.link.hover()  # the hold does not trust the position: zero velocity where it really is
    rig.run(0.1)
    (stop,) = rig.fake.sent_by_link("SET_POSITION_TARGET_LOCAL_NED")
    assert (stop.vx, stop.vy, stop.vz) == (0.0, 0.0, 0.0)
    with pytest.raises(VehicleQuiet, match="telemetry cannot be trusted"):
        rig.run(6.0)


def test_a_vehicle_clock_that_stops_while_messages_flow_is_quiet_within_the_bound():
    rig = _guided_in_the_air()
    frozen_ms = int(rig.clock.now() * 1000)

    def frozen_telemetry():
        rig.fake.mav.attitude_send(frozen_ms, 0.0, 0.0, 0.0, 0, 0, 0)  # time_boot_ms never moves

    rig.fake.telemetry = False
    rig.fake.tick, real_tick = (lambda: (frozen_telemetry(), real_tick())), rig.fake.tick
    started = rig.clock.now()
    with pytest.raises(VehicleQuiet, match="time frozen"):
        rig.run(10.0)
    assert rig.clock.now() - started <= 5.2


def test_a_clone_sending_under_the_vehicles_ids_is_a_telemetry_fault():
    rig = _guided_in_the_air()
    clone = mavlink2.MAVLink(rig.fake.end, srcSystem=1, srcComponent=1)
    clone.seq = 117

    def both():
        clone.heartbeat_send(mavlink2.MAV_TYPE_OCTOROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
                             mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 9, mavlink2.MAV_STATE_STANDBY)
        rig.fake.heartbeat()  # the real one keeps talking too

    rig.fake.tick, real_tick = (lambda: (both(), real_tick())), rig.fake.tick
    rig.run(1.0)
    assert "two senders use the vehicle's ids" in rig.link.state.telemetry_fault
    assert np.isfinite(rig.link.state.t_boot_s)
