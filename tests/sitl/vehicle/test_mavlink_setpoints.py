"""GUIDED set-points over MAVLink land where ArduCopter would put them (frames, type_mask, yaw).

Targets are given in MAVLink's frames (NED, 1e7 degrees, body) and checked against the simulator's
ground truth in ENU, with the expected ENU point written out by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mavlink_gcs import FIELD, airborne_gcs, mav

POS_ONLY = 0b110111111000  # ignore velocity, acceleration, yaw, yaw rate
POS_YAW = 0b100111111000  # position and yaw
VEL_ONLY = 0b110111000111
_M_PER_DEG_LAT = 111_083.0  # at 42.5 deg N, see test_mavlink_telemetry
_M_PER_DEG_LON = 82_197.4


def _truth(gcs) -> np.ndarray:
    return gcs.sim.truth.pos_enu


def _local(gcs, frame: int, x: float, y: float, z: float, mask: int = POS_ONLY, yaw: float = 0.0) -> None:
    gcs.send(mav.MAVLink_set_position_target_local_ned_message(
        0, 1, 1, frame, mask, x, y, z, 0, 0, 0, 0, 0, 0, yaw, 0))


def _global(gcs, frame: int, north_m: float, east_m: float, alt: float) -> None:
    lat = round((FIELD["lat_deg"] + north_m / _M_PER_DEG_LAT) * 1e7)
    lon = round((FIELD["lon_deg"] + east_m / _M_PER_DEG_LON) * 1e7)
    gcs.send(mav.MAVLink_set_position_target_global_int_message(
        0, 1, 1, frame, POS_ONLY, lat, lon, alt, 0, 0, 0, 0, 0, 0, 0, 0))


@pytest.mark.parametrize("frame", [mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mav.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT])
def test_global_int_relative_target_is_reached_and_held(frame):
    gcs = airborne_gcs(10.0)
    _global(gcs, frame, north_m=40.0, east_m=-25.0, alt=15.0)
    gcs.run(30.0)
    np.testing.assert_allclose(_truth(gcs), [-25.0, 40.0, 15.0], atol=1.0)


def test_global_int_amsl_target_uses_sea_level_altitude():
    gcs = airborne_gcs(10.0)
    _global(gcs, mav.MAV_FRAME_GLOBAL_INT, north_m=0.0, east_m=0.0, alt=FIELD["alt_m"] + 20.0)
    gcs.run(15.0)
    assert _truth(gcs)[2] == pytest.approx(20.0, abs=0.5)


def test_local_ned_target_is_relative_to_the_ekf_origin():
    gcs = airborne_gcs(10.0)
    _local(gcs, mav.MAV_FRAME_LOCAL_NED, 10.0, -5.0, -8.0)  # 10 m north, 5 m west, 8 m up
    gcs.run(15.0)
    np.testing.assert_allclose(_truth(gcs), [-5.0, 10.0, 8.0], atol=0.7)


def test_body_offset_target_is_rotated_by_the_heading():
    gcs = airborne_gcs(10.0)
    _local(gcs, mav.MAV_FRAME_LOCAL_OFFSET_NED, 0, 0, 0, mask=POS_YAW, yaw=math.pi / 2)  # face east, stay
    gcs.run(8.0)
    start = _truth(gcs).copy()
    _local(gcs, mav.MAV_FRAME_BODY_OFFSET_NED, 10.0, 5.0, 0.0)  # 10 m ahead, 5 m right: east, south
    gcs.run(12.0)
    np.testing.assert_allclose(_truth(gcs) - start, [10.0, -5.0, 0.0], atol=0.7)


def test_local_offset_target_is_relative_to_the_current_position():
    gcs = airborne_gcs(10.0)
    start = _truth(gcs).copy()
    _local(gcs, mav.MAV_FRAME_LOCAL_OFFSET_NED, 0.0, 6.0, 2.0)  # 6 m east, 2 m down
    gcs.run(10.0)
    np.testing.assert_allclose(_truth(gcs) - start, [6.0, 0.0, -2.0], atol=0.7)


def test_velocity_target_in_body_frame_moves_along_the_heading():
    gcs = airborne_gcs(10.0)
    _local(gcs, mav.MAV_FRAME_LOCAL_OFFSET_NED, 0, 0, 0, mask=POS_YAW, yaw=math.pi)  # face south
    gcs.run(8.0)
    for _ in range(30):
        gcs.send(mav.MAVLink_set_position_target_local_ned_message(
            0, 1, 1, mav.MAV_FRAME_BODY_NED, VEL_ONLY, 0, 0, 0, 3.0, 0, 0, 0, 0, 0, 0, 0))
        gcs.run(0.1)
    vel = gcs.sim.truth.vel_enu
    assert vel[1] == pytest.approx(-3.0, abs=0.3) and abs(vel[0]) < 0.3


def test_yaw_in_a_position_target_sets_the_heading():
    gcs = airborne_gcs(10.0)
    _local(gcs, mav.MAV_FRAME_LOCAL_OFFSET_NED, 0, 0, 0, mask=POS_YAW, yaw=math.radians(-45.0))  # north-west
    gcs.run(8.0)
    assert gcs.sim.autopilot.heading_deg == pytest.approx(315.0, abs=2.0)


def test_unsupported_frame_makes_guided_hold_position():
    gcs = airborne_gcs(10.0)
    _local(gcs, mav.MAV_FRAME_LOCAL_NED, 30.0, 0.0, -10.0)
    gcs.run(3.0)  # on its way north
    _local(gcs, mav.MAV_FRAME_MISSION, 0.0, 0.0, 0.0)
    gcs.run(0.1)
    stopped_at = _truth(gcs).copy()
    gcs.run(10.0)
    assert np.linalg.norm(_truth(gcs)[:2] - stopped_at[:2]) < 8.0  # braked nearby, not at 30 m
    assert _truth(gcs)[1] < 25.0


def test_set_attitude_target_pitch_down_flies_north_holding_altitude():
    gcs = airborne_gcs(10.0)
    pitch = math.radians(-10.0)  # nose down, heading north
    q = [math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0]  # scalar-first, rotation about FRD y
    for _ in range(40):  # resent at 10 Hz (GUIDED attitude targets time out)
        gcs.send(mav.MAVLink_set_attitude_target_message(0, 1, 1, 0b00000111, q, 0, 0, 0, 0.5))
        gcs.run(0.1)
    att = gcs.of_type("ATTITUDE")[-1]
    assert att.pitch == pytest.approx(pitch, abs=math.radians(1.5))
    assert abs(att.roll) < math.radians(1.5)
    vel = gcs.sim.truth.vel_enu
    assert vel[1] > 3.0 and abs(vel[0]) < 0.5
    assert _truth(gcs)[2] == pytest.approx(10.0, abs=1.5)


def test_setpoints_outside_guided_are_ignored():
    gcs = airborne_gcs(10.0)
    assert gcs.set_mode(17).result == mav.MAV_RESULT_ACCEPTED  # BRAKE (LOITER would follow the sticks)
    start = _truth(gcs).copy()
    _local(gcs, mav.MAV_FRAME_LOCAL_NED, 30.0, 30.0, -10.0)
    gcs.run(8.0)
    assert np.linalg.norm(_truth(gcs) - start) < 1.0
