"""The fault battery on ArduPilot's own ArduCopter SITL: the patrol with one fault each, judged twice.

The cases and the judgement are tests/e2e/test_fault_outcomes.py's; only who flies changes
(``rehearse(..., autopilot="ardupilot")``: ArduCopter in our world). The faults are struck from a
second ground station on ArduCopter's SERIAL1, the way ArduPilot's own autotest strikes them
(sitl/ardupilot/faults.py): a forced disarm, SIM_BATT_VOLTAGE, SIM_GPS1_ENABLE, SIM_RC_FAIL with the
pilot's transmitter silent, a mode change; a link loss cuts the mission's link at a relay. Each case
also checks that ArduCopter acknowledged the injection, so a fault that never struck cannot pass.

Where ArduCopter differs from the built-in simulator it is said at the assertion, with its texts:

- a forced disarm, a GPS loss and a lost transmitter end the same way;
- the built-in's "GCS Failsafe" after a failsafe takes the aircraft (the rehearsal stops the
  mission, and with it the heartbeats) is not seen here: ArduCopter ships FS_GCS_ENABLE 0;
- a lost link needs FS_GCS_ENABLE 1 set (the built-in's default): with ArduCopter's 0 the aircraft
  would hover in GUIDED; its "GCS Failsafe" is heard only by the second ground station, since the
  mission's link is down.

The flights skip, saying so, when no ArduCopter SITL is found (``$CHASER_BT_ARDUPILOT`` or
``../shared/ardupilot``); they are marked slow, and ArduCopter runs one at a time (15-40 s of wall
time a case on two cores). Two quick tests need no SITL: what the second ground station sends and
when, to a socket standing where SERIAL1 would, and the link relay's cut.
"""

from __future__ import annotations

import dataclasses
import os
import socket
from pathlib import Path

import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from sitl.ardupilot.faults import SECOND_GCS_SYSID, FaultInjector, LinkRelay  # noqa: E402
from sitl.ardupilot.process import ArduPilotMissing, find_ardupilot  # noqa: E402
from sitl.bench.rehearsal import AutopilotChoice, rehearse  # noqa: E402
from sitl.vehicle.setup import Fault, GroundStationEvent  # noqa: E402
from sitl.world.scenario import load_scenario  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TREE = ROOT / "trees" / "patrol.yaml"
# The world's clock starts when ArduCopter is ready to arm. The built-in battery strikes at 62 s of
# its clock, 22 s after its scenario's boot.prearm_ok_s (40 s); 22 s here is the same time after
# ready: on the first leg, at 20 m (reached at about 14 s), about 70 m out.
FAULT_AT_S = 22.0


@pytest.fixture(scope="module")
def ardupilot() -> AutopilotChoice:
    try:
        folder = find_ardupilot()
    except ArduPilotMissing as exc:
        pytest.skip(f"{exc}: the fault battery on ArduCopter needs its SITL")
    return AutopilotChoice("ardupilot", folder=folder)


def _patrol_with(**changes):
    base = load_scenario(ROOT / "sitl" / "scenarios" / "patrol.yaml")
    if "params" in changes:
        changes["params"] = {**base.params, **changes["params"]}
    return dataclasses.replace(base, **changes)


def _fly(ardupilot: AutopilotChoice, **changes):
    """The report, the witness's texts, what was injected (at_s, what, reply) and what the second GCS heard."""
    seen = {}
    report = rehearse(TREE, _patrol_with(**changes), seed=1, autopilot=ardupilot,
                      on_start=lambda runner, vehicle, resources: seen.update(runner=runner, vehicle=vehicle))
    injector = seen["vehicle"].sim.faults
    injected = [] if injector is None else [(i.at_s, i.what, i.reply) for i in injector.injections]
    heard = [] if injector is None else [text for _, text in injector.texts]
    return report, [text for _, text in seen["runner"].witness.texts], injected, heard


@pytest.mark.slow
def test_no_fault_completes_and_lands_at_home(ardupilot):
    report, texts, injected, _ = _fly(ardupilot)
    assert report.mission_outcome == "completed" and report.outcome == "landed", report.message
    assert report.landed_dist_m < 1.0 and report.final_state == "landed" and report.t_safe_s is None
    assert texts == [] and injected == []


@pytest.mark.slow
def test_a_forced_disarm_in_the_air_is_a_crash_never_a_landing(ardupilot):
    report, _, injected, _ = _fly(ardupilot, faults=(Fault(FAULT_AT_S, "disarm"),))
    assert injected == [(FAULT_AT_S, "disarm: forced disarm", "COMMAND_ACK ACCEPTED")]
    assert report.outcome == "crashed"  # the truth: it fell
    assert report.mission_outcome == "crashed", report.message


@pytest.mark.slow
def test_the_autopilots_battery_failsafe_sends_the_patrol_home_early(ardupilot):
    # SITL's 3S pack (SIM_BATT_VOLTAGE 12.6) loses a cell: 8.4 V, under ArduCopter's BATT_LOW_VOLT 10.5
    # for BATT_LOW_TIMER (10 s), with no action (BATT_FS_LOW_ACT 0); the patrol's guard takes it home.
    report, texts, injected, _ = _fly(ardupilot, faults=(Fault(FAULT_AT_S, "battery_drop"),),
                                      params={"BATT_FS_LOW_ACT": 0})
    assert injected == [(FAULT_AT_S, "battery_drop: SIM_BATT_VOLTAGE 8.4", "PARAM_VALUE 8.4")]
    assert texts[0].startswith("Battery 1 is low 8.40V"), texts
    assert report.mission_outcome == "returned early", report.message
    assert report.outcome == "landed" and report.landed_dist_m < 1.0
    assert report.final_state == "landed" and 0.0 < report.t_safe_s < 120.0  # from the fault to the touchdown


@pytest.mark.slow
def test_an_ekf_failsafe_is_the_autopilots_abort_and_its_land_is_left_alone(ardupilot):
    report, texts, injected, _ = _fly(ardupilot, faults=(Fault(FAULT_AT_S, "gps_loss"),))
    assert injected == [(FAULT_AT_S, "gps_loss: SIM_GPS1_ENABLE 0", "PARAM_VALUE 0")]
    assert report.mission_outcome == "aborted by the autopilot", report.message
    # ArduCopter's words: "EKF variance: position lost", then "EKF Failsafe: changed to Land Mode".
    assert any("EKF Failsafe" in text for text in texts), texts
    # The failsafe's LAND, with no position to hold, brings it down where the wind takes it: not at home.
    assert report.outcome == "failsafe" and report.final_state == "landed"
    assert report.landed_dist_m > 5.0


@pytest.mark.slow
def test_a_ground_stations_mode_change_is_a_take_over(ardupilot):
    report, _, injected, _ = _fly(ardupilot, ground_station=(GroundStationEvent(FAULT_AT_S, "LOITER"),))
    assert injected == [(FAULT_AT_S, "ground station: LOITER", "COMMAND_ACK ACCEPTED")]
    assert report.mission_outcome == "taken over", report.message
    assert report.final_state not in ("moving", "falling", "crashed")


@pytest.mark.slow
def test_a_lost_link_is_link_lost_and_the_autopilot_brings_it_home(ardupilot):
    # FS_GCS_ENABLE 1 is the built-in's default; ArduCopter ships it 0 (docs/ardupilot.md: set it).
    report, texts, _, heard = _fly(ardupilot, faults=(Fault(FAULT_AT_S, "link_loss"),), params={"FS_GCS_ENABLE": 1})
    assert report.mission_outcome == "link lost", report.message
    assert report.outcome == "failsafe" and report.landed_dist_m < 5.0  # the GCS failsafe's RTL
    assert report.final_state == "landed"
    # The mission's link is down, so only the operator's second ground station hears why.
    assert texts == [] and "GCS Failsafe" in heard, heard


@pytest.mark.slow
def test_a_fence_that_refuses_the_leg_fails_it_with_the_cause_instead_of_waiting_for_the_battery(ardupilot):
    report, _, _, _ = _fly(ardupilot, params={"FENCE_ENABLE": 1, "FENCE_RADIUS": 60})
    assert report.mission_outcome == "failed", report.message
    assert "no progress for 30 s with 100 m to go" in report.message
    assert report.sim_time_s < 120.0  # within the stall bound of the first leg, not the battery's
    assert report.final_state == "holding"  # the failed leg's hold took


@pytest.mark.slow
def test_a_lost_transmitter_is_the_autopilots_radio_failsafe_and_its_rtl_lands_at_home(ardupilot):
    # copter.parm's FS_THR_ENABLE 1: no RC pulses for RC_FS_TIMEOUT while flying GUIDED -> "Radio Failsafe", RTL.
    report, texts, injected, _ = _fly(ardupilot, faults=(Fault(FAULT_AT_S, "rc_loss"),))
    assert injected == [(FAULT_AT_S, "rc_loss: SIM_RC_FAIL 1", "PARAM_VALUE 1")]
    assert report.mission_outcome == "aborted by the autopilot", report.message
    assert texts[0] == "Radio Failsafe", texts
    assert report.outcome == "failsafe" and report.landed_dist_m < 5.0 and report.final_state == "landed"


@pytest.mark.slow
def test_a_transmitter_lost_with_guided_allowed_to_continue_completes_the_patrol(ardupilot):
    # FS_OPTIONS bit 2: the radio failsafe leaves GUIDED flying; the mission goes on and says what happened.
    report, texts, injected, _ = _fly(ardupilot, faults=(Fault(FAULT_AT_S, "rc_loss"),), params={"FS_OPTIONS": 4})
    assert injected == [(FAULT_AT_S, "rc_loss: SIM_RC_FAIL 1", "PARAM_VALUE 1")]
    assert report.mission_outcome == "completed", report.message
    assert report.outcome == "landed" and report.landed_dist_m < 1.0
    assert texts[0] == "Radio Failsafe - Continuing Guided Mode", texts


# -- no SITL needed -----------------------------------------------------------------------------------

def _recv_all(sock: socket.socket, parser) -> list:  # noqa: ANN001
    msgs = []
    while True:
        try:
            data = sock.recv(65536)
        except BlockingIOError:
            return msgs
        if not data:
            return msgs
        msgs += parser.parse_buffer(data) or []


def test_the_second_ground_station_sends_each_fault_on_the_worlds_clock_and_records_the_reply():
    listener = socket.create_server(("127.0.0.1", 0))
    faults = (Fault(2.0, "rc_loss", 1.0), Fault(3.0, "gps_loss", 4.0), Fault(5.0, "disarm"), Fault(6.0, "battery_drop"))
    injector = FaultInjector(faults, (GroundStationEvent(7.0, "LOITER"),), listener.getsockname())
    vehicle = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    parser = mavlink2.MAVLink(None)
    sent: list[tuple[float, str, tuple]] = []
    peer = None
    try:
        for i in range(0, 451):
            t = round(i * 0.02, 2)
            injector.step(t)
            if peer is None:
                peer, _ = listener.accept()
                peer.setblocking(False)
            for msg in _recv_all(peer, parser):
                assert msg.get_srcSystem() == SECOND_GCS_SYSID
                kind = msg.get_type()
                if kind == "PARAM_REQUEST_READ":  # answered as ArduCopter would, SITL's 3S pack
                    value = {"SIM_BATT_VOLTAGE": 12.6, "BATT_LOW_VOLT": 10.5}[msg.param_id]
                    peer.sendall(vehicle.param_value_encode(msg.param_id.encode(), value, 9, 1000, 0).pack(vehicle))
                elif kind == "PARAM_SET":
                    sent.append((t, kind, (msg.param_id, round(msg.param_value, 3))))
                    peer.sendall(vehicle.param_value_encode(msg.param_id.encode(), msg.param_value, 9, 1000, 0).pack(vehicle))
                elif kind == "COMMAND_LONG":
                    sent.append((t, kind, (msg.command, msg.param1, msg.param2)))
                    if msg.command == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM:
                        ack = vehicle.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED, 0, 0, SECOND_GCS_SYSID, 190)
                        peer.sendall(ack.pack(vehicle))
            assert injector.rc_silent(t) == (2.0 <= t < 3.0)
    finally:
        injector.close()
        listener.close()
        if peer is not None:
            peer.close()
    assert sent == [
        (2.0, "PARAM_SET", ("SIM_RC_FAIL", 1.0)),
        (3.0, "PARAM_SET", ("SIM_RC_FAIL", 0.0)),
        (3.0, "PARAM_SET", ("SIM_GPS1_ENABLE", 0.0)),
        (5.0, "COMMAND_LONG", (mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0.0, 21196.0)),
        (6.0, "PARAM_SET", ("SIM_BATT_VOLTAGE", 8.4)),  # one cell of three lost
        (7.0, "PARAM_SET", ("SIM_GPS1_ENABLE", 1.0)),
        (7.0, "COMMAND_LONG", (mavlink2.MAV_CMD_DO_SET_MODE, 1.0, 5.0)),  # custom mode LOITER
    ]
    replies = {i.what: i.reply for i in injector.injections}
    assert replies["disarm: forced disarm"] == "COMMAND_ACK ACCEPTED"
    assert replies["battery_drop: SIM_BATT_VOLTAGE 8.4"] == "PARAM_VALUE 8.4"
    assert replies["ground station: LOITER"] is None  # never answered: recorded as such, not as accepted


def test_the_link_relay_carries_both_ways_and_a_link_loss_drops_both_ways():
    vehicle = socket.create_server(("127.0.0.1", 0))
    relay = LinkRelay(vehicle.getsockname())
    mission = socket.create_connection(("127.0.0.1", int(relay.url.rsplit(":", 1)[1])))
    try:
        relay.pump(True)
        serial0, _ = vehicle.accept()
        for sock in (mission, serial0):  # no Nagle: each small write goes out at once, as ArduCopter's do
            sock.setblocking(False)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

        def exchange(up: bool) -> tuple[bytes, bytes]:
            mission.sendall(b"command")
            serial0.sendall(b"telemetry")
            relay.pump(up)
            got = []
            for sock in (serial0, mission):
                try:
                    got.append(sock.recv(100))
                except BlockingIOError:
                    got.append(b"")
            return got[0], got[1]

        assert exchange(True) == (b"command", b"telemetry")
        assert exchange(False) == (b"", b"")
        assert exchange(True) == (b"command", b"telemetry")
        assert relay.dropped_bytes == len(b"command") + len(b"telemetry")  # lost, not held back
        serial0.close()
    finally:
        mission.close()
        relay.close()
        vehicle.close()
