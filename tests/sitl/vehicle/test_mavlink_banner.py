"""The boot banner and AUTOPILOT_VERSION, as ArduCopter sends them.

Reference: the 4.7.0-dev SITL in ``../shared/ardupilot``, read with pymavlink. MAV_CMD_DO_SEND_BANNER
and PARAM_REQUEST_LIST were each answered with "ArduCopter V4.7.0-dev (90700977)", the board's id
line and "Frame: QUAD/PLUS" (copter.parm: FRAME_CLASS 1, FRAME_TYPE 0); REQUEST_MESSAGE
AUTOPILOT_VERSION and REQUEST_AUTOPILOT_CAPABILITIES sent no banner. AUTOPILOT_VERSION carried
capabilities 64495, flight_sw_version 0x04070000 (4.7.0, type DEV) and flight_custom_version the
8 characters of the git hash in the banner.
"""

from __future__ import annotations

import re

from mavlink_gcs import PipeGcs, mav, quick_scenario, ready_gcs

from sitl.simulator import Simulator

FIRMWARE_LINE = re.compile(r"^ArduCopter V(\d+)\.(\d+)\.(\d+)(-dev)? \((\w{8})\)$")  # the real SITL's style
REAL_CAPABILITIES = 64495
NOT_SIMULATED = (mav.MAV_PROTOCOL_CAPABILITY_TERRAIN | mav.MAV_PROTOCOL_CAPABILITY_FLIGHT_TERMINATION
                 | mav.MAV_PROTOCOL_CAPABILITY_COMPASS_CALIBRATION)


def _texts(msgs) -> list[str]:
    return [m.text for m in msgs if m.get_type() == "STATUSTEXT"]


def test_the_banner_goes_out_at_boot():
    gcs = PipeGcs(Simulator(quick_scenario(), 0))
    texts = _texts(gcs.run(0.1))
    assert FIRMWARE_LINE.match(texts[0])
    assert texts[1] == "Frame: OCTA/X"  # FRAME_CLASS 3, FRAME_TYPE 1


def test_the_frame_line_and_heartbeat_type_follow_frame_class():
    gcs = PipeGcs(Simulator(quick_scenario(params={"FRAME_CLASS": 1, "FRAME_TYPE": 0}), 0))
    msgs = gcs.run(1.1)
    assert "Frame: QUAD/PLUS" in _texts(msgs)  # the real SITL's own line for these parameters
    assert {m.type for m in msgs if m.get_type() == "HEARTBEAT"} == {mav.MAV_TYPE_QUADROTOR}


def test_param_request_list_and_do_send_banner_send_it_again():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_param_request_list_message(1, 1))
    texts = _texts(gcs.run(0.2))
    assert FIRMWARE_LINE.match(texts[0]) and texts[1] == "Frame: OCTA/X"
    ack, seen = gcs.command_ack(mav.MAV_CMD_DO_SEND_BANNER)
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    texts = _texts(seen + gcs.run(0.1))
    assert FIRMWARE_LINE.match(texts[0]) and texts[1] == "Frame: OCTA/X"


def test_requesting_autopilot_version_sends_no_banner():
    gcs = ready_gcs()
    _, seen = gcs.command_ack(mav.MAV_CMD_REQUEST_MESSAGE, mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    assert not any(FIRMWARE_LINE.match(t) for t in _texts(seen + gcs.run(0.1)))


def test_autopilot_version_matches_the_banner_and_arducopters_capabilities():
    gcs = PipeGcs(Simulator(quick_scenario(), 0))
    banner = _texts(gcs.run(0.1))[0]
    gcs.command(mav.MAV_CMD_REQUEST_MESSAGE, mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    version = gcs.wait_for("AUTOPILOT_VERSION", 1.0)
    assert version.capabilities == REAL_CAPABILITIES & ~NOT_SIMULATED
    major, minor, patch, dev, build = FIRMWARE_LINE.match(banner).groups()
    sw = version.flight_sw_version
    assert (sw >> 24, (sw >> 16) & 0xFF, (sw >> 8) & 0xFF) == (int(major), int(minor), int(patch))
    release = sw & 0xFF
    assert (release == mav.FIRMWARE_VERSION_TYPE_DEV) == (dev is not None)
    assert bytes(version.flight_custom_version).decode("ascii") == build
