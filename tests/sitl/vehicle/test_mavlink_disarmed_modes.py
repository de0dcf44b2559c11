"""Mode changes while disarmed, over MAVLink, as ArduCopter answers them.

Reference: ArduCopter's Copter::set_mode (ignore_checks = !motors->armed(): any mode while
disarmed, the checks at arming) and the 4.7.0-dev SITL in ``../shared/ardupilot``: GUIDED set 3 s
after boot, before its EKF used GPS, got COMMAND_ACK 0 and HEARTBEAT custom_mode 4.
"""

from __future__ import annotations

from mavlink_gcs import PipeGcs, mav, quick_scenario

from sitl.simulator import Simulator


def _booting_gcs() -> PipeGcs:
    # ArduCopter SITL's boot: GPS fix 5 s, EKF position 25 s, pre-arm 40 s
    gcs = PipeGcs(Simulator(quick_scenario(boot={"gps_fix_s": 5.0, "ekf_ready_s": 25.0, "prearm_ok_s": 40.0}), 0))
    gcs.run(3.0)
    return gcs


def test_guided_is_accepted_before_the_ekf_has_a_position_and_arming_says_why_not():
    gcs = _booting_gcs()
    assert gcs.set_mode(4).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.wait_for("HEARTBEAT", 1.5).custom_mode == 4
    ack, seen = gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert ack.result == mav.MAV_RESULT_FAILED
    assert "PreArm: Need 3D Fix" in [m.text for m in seen if m.get_type() == "STATUSTEXT"]


def test_rtl_is_accepted_disarmed_before_home_is_set_and_cannot_be_armed():
    gcs = _booting_gcs()
    assert gcs.sim.autopilot.home is None
    assert gcs.set_mode(6).result == mav.MAV_RESULT_ACCEPTED
    gcs.run(40.0)  # past every boot check: RTL itself is not an armable mode
    ack, seen = gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert ack.result == mav.MAV_RESULT_FAILED
    assert "Arm: Mode not armable" in [m.text for m in seen if m.get_type() == "STATUSTEXT"]
