"""Every parameter comes with the MAVLink type and the default a real ArduCopter gives it.

Reference: PARAM_VALUE from the 4.7.0-dev SITL in ``../shared/ardupilot`` (stock copter.parm), each
parameter read by name with pymavlink: (value, MAV_PARAM_TYPE). INT8 = 2, INT16 = 4, INT32 = 6,
REAL32 = 9. Values the simulator deliberately sets otherwise (its own airframe and battery, its
GCS failsafe, and what copter.parm changes from ArduCopter's firmware default) are named below.
"""

from __future__ import annotations

import pytest
from mavlink_gcs import mav, ready_gcs

REAL = {
    "FRAME_CLASS": (1.0, 2), "FRAME_TYPE": (0.0, 2), "FENCE_ENABLE": (0.0, 2), "FENCE_TYPE": (7.0, 2),
    "FENCE_RADIUS": (150.0, 9), "FENCE_ALT_MAX": (100.0, 9), "FENCE_ALT_MIN": (-10.0, 9),
    "FENCE_ACTION": (1.0, 2), "FENCE_MARGIN": (2.0, 9), "MAV_GCS_SYSID": (255.0, 4),
    "ANGLE_MAX": (3000.0, 4), "PILOT_SPEED_UP": (250.0, 4), "PILOT_SPEED_DN": (0.0, 4),
    "PILOT_ACCEL_Z": (250.0, 4), "PILOT_Y_RATE": (202.5, 9), "THR_DZ": (100.0, 4), "RC1_DZ": (20.0, 4),
    "RC2_DZ": (20.0, 4), "RC3_DZ": (30.0, 4), "RC4_DZ": (20.0, 4), "RC_OVERRIDE_TIME": (3.0, 9),
    "WPNAV_SPEED": (1000.0, 9), "WPNAV_SPEED_UP": (250.0, 9), "WPNAV_SPEED_DN": (150.0, 9),
    "WPNAV_ACCEL": (250.0, 9), "WPNAV_ACCEL_Z": (100.0, 9), "WPNAV_RADIUS": (200.0, 9),
    "LOIT_SPEED": (1250.0, 9), "LOIT_ACC_MAX": (500.0, 9), "LOIT_BRK_ACCEL": (250.0, 9),
    "RTL_ALT": (1500.0, 6), "RTL_ALT_FINAL": (0.0, 4), "RTL_CLIMB_MIN": (0.0, 4), "RTL_SPEED": (0.0, 4),
    "RTL_LOIT_TIME": (5000.0, 6), "LAND_SPEED": (50.0, 4), "LAND_SPEED_HIGH": (0.0, 4),
    "LAND_ALT_LOW": (1000.0, 4), "DISARM_DELAY": (10.0, 2), "ARMING_CHECK": (1.0, 6),
    "FS_GCS_ENABLE": (0.0, 2), "FS_GCS_TIMEOUT": (5.0, 9), "FS_EKF_ACTION": (1.0, 2),
    "GUID_OPTIONS": (0.0, 6), "GUID_TIMEOUT": (3.0, 9), "BATT_CAPACITY": (3300.0, 6),
    "BATT_LOW_VOLT": (10.5, 9), "BATT_LOW_MAH": (0.0, 9), "BATT_LOW_TIMER": (10.0, 2),
    "BATT_FS_LOW_ACT": (0.0, 2), "MAV_SYSID": (1.0, 4),
}
# the simulator's own choices (see sitl/vehicle/params.py): an octocopter, X layout (ArduCopter's
# firmware default FRAME_TYPE; copter.parm sets 0); AC_Fence's firmware default radius 300 m
# (copter.parm sets 150); FS_GCS_ENABLE 1; the simulated 6S pack and its RTL failsafe
OURS = {"FRAME_CLASS": 3.0, "FRAME_TYPE": 1.0, "FENCE_RADIUS": 300.0, "FS_GCS_ENABLE": 1.0,
        "BATT_CAPACITY": None, "BATT_LOW_VOLT": 21.0, "BATT_FS_LOW_ACT": 2.0}


@pytest.fixture(scope="module")
def by_name():
    gcs = ready_gcs()
    for name in REAL:
        gcs.send(mav.MAVLink_param_request_read_message(1, 1, name.encode(), -1))
    gcs.run(0.5)
    return {m.param_id: m for m in gcs.of_type("PARAM_VALUE")}


@pytest.mark.parametrize("name", sorted(REAL))
def test_type_and_default_are_arducopters(by_name, name):
    value, mav_type = REAL[name]
    assert name in by_name, f"{name} is not answered"
    reply = by_name[name]
    assert reply.param_type == mav_type
    expected = OURS.get(name, value)
    if expected is not None:
        assert reply.param_value == pytest.approx(expected)
