"""The operator's designation over MAVLink: MAV_CMD_USER_1 from a ground station, signed, acked.

Every command here is built and signed by pymavlink's own MAVLink class, as a ground station's
would be, and decoded by a parser set up as the vehicle link's is; the expected answers come from
the rules in docs/ground.md ("Designation over MAVLink"), worked out per case.
"""

from __future__ import annotations

import logging
import math
import os
import time

os.environ["MAVLINK20"] = "1"

import py_trees  # noqa: E402
import pytest  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from chaser_bt.vehicle.designation import (  # noqa: E402
    Auth,
    DesignationInbox,
    Judgement,
    MavlinkDesignation,
    authenticity,
    judge,
)
from chaser_bt.vehicle.signing import SigningConfig, SigningGate  # noqa: E402

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))
USER_1 = 31010  # MAV_CMD_USER_1, common.xml
ACCEPTED, DENIED, UNSUPPORTED = 0, 2, 3  # MAV_RESULT, common.xml
VEHICLE, CHASER = 1, 191  # the vehicle's system id; MAV_COMP_ID_ONBOARD_COMPUTER
INT32_MAX = 2**31 - 1


def _now_stamp() -> int:
    """MAVLink signing's timestamp for now: 10 us ticks since 2015-01-01 00:00 UTC (Unix 1420070400)."""
    return int((time.time() - 1420070400) * 100_000)


def _gcs(key: bytes | None = KEY, *, sysid: int = 255, compid: int = 190, link_id: int = 0, file=None):
    """A ground station's encoder; with ``key`` it signs, as pymavlink does for MAVProxy."""
    mav = mavlink2.MAVLink(file, srcSystem=sysid, srcComponent=compid)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.link_id = link_id
        mav.signing.timestamp = _now_stamp()
        mav.signing.sign_outgoing = True
    return mav


def _vehicle_parser(key: bytes | None = KEY):
    """A parser with the link's signing gate attached (or none), as VehicleLink sets up its own."""
    rx = mavlink2.MAVLink(None)
    rx.robust_parsing = True
    gate = None
    if key is not None:
        gate = SigningGate(SigningConfig(key), _now_stamp())
        gate.attach(rx)
    return rx, gate


def _designate(track: float, *, to=(VEHICLE, CHASER), params=(0, 0, 0, 0, 0, 0), command: int = USER_1):
    return mavlink2.MAVLink_command_long_message(to[0], to[1], command, 0, track, *params)


def _designate_int(track: float, *, to=(VEHICLE, CHASER), x: int = 0, y: int = 0, z: float = 0.0):
    return mavlink2.MAVLink_command_int_message(to[0], to[1], 0, USER_1, 0, 0, track, 0, 0, 0, x, y, z)


def _over_the_air(msg, gcs=None, parser=None):
    """``msg`` packed by the ground station, decoded by the vehicle's parser: (message, its Auth)."""
    gcs = gcs if gcs is not None else _gcs()
    rx, gate = parser if parser is not None else _vehicle_parser()
    (decoded,) = rx.parse_buffer(msg.pack(gcs))
    return decoded, authenticity(decoded, gate)


def _judge(msg, gcs=None, parser=None, allow_unsigned: bool = False) -> Judgement | None:
    decoded, auth = _over_the_air(msg, gcs, parser)
    return judge(decoded, sysid=VEHICLE, compid=CHASER, auth=auth, allow_unsigned=allow_unsigned)


# ----------------------------------------------------------------------------- authentication
def test_a_signed_designation_is_accepted_as_command_long_and_as_command_int():
    assert _judge(_designate(4117)) == Judgement("accepted", ACCEPTED, track_id=4117)
    assert _judge(_designate_int(4117)) == Judgement("accepted", ACCEPTED, track_id=4117)
    # the broadcast component of our system is ours too
    assert _judge(_designate(12, to=(VEHICLE, 0))).track_id == 12


def test_unsigned_and_wrongly_signed_designations_are_dropped_without_an_answer():
    unsigned = _judge(_designate(4117), gcs=_gcs(None))
    assert (unsigned.outcome, unsigned.ack) == ("unsigned", None)
    forged = _judge(_designate(4117), gcs=_gcs(OTHER_KEY))
    assert (forged.outcome, forged.ack) == ("bad_signature", None)
    # a link without a key cannot check a signature: nothing it receives is authenticated
    no_key = _judge(_designate(4117), parser=_vehicle_parser(None))
    assert no_key.outcome == "unsigned"


def test_a_replayed_designation_is_a_bad_signature():
    gcs, parser = _gcs(), _vehicle_parser()
    packet = _designate(4117).pack(gcs)
    rx, gate = parser
    first, again = rx.parse_buffer(packet + packet)
    assert authenticity(first, gate) is Auth.SIGNED
    assert authenticity(again, gate) is Auth.BAD_SIGNATURE  # same timestamp on the same stream


def test_the_bench_flag_believes_unsigned_but_never_a_bad_signature():
    assert _judge(_designate(7), gcs=_gcs(None), allow_unsigned=True) == Judgement("accepted", ACCEPTED, track_id=7)
    assert _judge(_designate(7), gcs=_gcs(OTHER_KEY), allow_unsigned=True).outcome == "bad_signature"


# ----------------------------------------------------------------------------- addressing
def test_addressing_another_vehicle_or_component_or_every_system():
    assert _judge(_designate(5, to=(2, CHASER))) == Judgement("not_for_us", reason="for vehicle 2")
    assert _judge(_designate(5, to=(VEHICLE, 1))) is None  # the autopilot's
    everyone = _judge(_designate(5, to=(0, 0)))
    assert (everyone.outcome, everyone.ack, everyone.track_id) == ("denied", DENIED, None)


def test_other_commands_addressed_to_us_are_unsupported_and_broadcast_ones_are_left_alone():
    request = mavlink2.MAV_CMD_REQUEST_MESSAGE
    assert _judge(_designate(0, command=request)).ack == UNSUPPORTED
    assert _judge(_designate(0, command=request, to=(VEHICLE, 0))) is None
    assert _judge(_designate(0, command=request, to=(0, 0))) is None
    # unsigned, even an unknown command gets no answer
    assert _judge(_designate(0, command=request), gcs=_gcs(None)).ack is None
    # another message kind is never ours
    rx, gate = _vehicle_parser()
    (hb,) = rx.parse_buffer(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(_gcs()))
    assert judge(hb, sysid=VEHICLE, compid=CHASER, auth=Auth.SIGNED) is None


# ----------------------------------------------------------------------------- fields
@pytest.mark.parametrize("track", [-1.0, 4117.5, math.nan, math.inf, 2**24 + 2])
def test_a_track_id_that_is_not_a_whole_number_in_range_is_denied_naming_param1(track):
    j = _judge(_designate(track))
    assert (j.outcome, j.ack, j.bad_param) == ("denied", DENIED, 1)


def test_track_ids_up_to_2_to_the_24_are_exact_on_the_wire():
    assert _judge(_designate(2**24)).track_id == 16_777_216
    assert _judge(_designate(0)).track_id == 0
    # 2^24 + 1 is no float32: the ground station's float rounds it to 2^24 before it is sent
    assert _judge(_designate(2**24 + 1)).track_id == 16_777_216


def test_reserved_parameters_must_be_zero_or_nan():
    j = _judge(_designate(9, params=(0, 5.0, 0, 0, 0, 0)))  # param3
    assert (j.outcome, j.bad_param) == ("denied", 3)
    assert _judge(_designate(9, params=(math.nan,) * 6)).track_id == 9
    assert _judge(_designate_int(9, x=INT32_MAX, y=INT32_MAX, z=math.nan)).track_id == 9  # "not used"
    assert _judge(_designate_int(9, x=12)).bad_param == 5
    assert _judge(_designate_int(9, z=1.0)).bad_param == 7


# ----------------------------------------------------------------------------- the inbox
def test_the_inbox_counts_everything_keeps_the_accepted_and_warns_once_per_kind(caplog):
    inbox = DesignationInbox(CHASER)
    rx, gate = _vehicle_parser()
    signed, unsigned = _gcs(sysid=250), _gcs(None, sysid=250)
    packets = [_designate(4117).pack(signed), _designate(1).pack(unsigned), _designate(2).pack(unsigned),
               _designate(-3).pack(signed), _designate(5, to=(9, CHASER)).pack(signed), _designate(8).pack(signed)]
    with caplog.at_level(logging.DEBUG, logger="chaser_bt.vehicle.designation"):
        for msg in rx.parse_buffer(b"".join(packets)):
            inbox.receive(msg, sysid=VEHICLE, auth=authenticity(msg, gate))
    c = inbox.counters
    assert (c.accepted, c.unsigned, c.denied, c.not_for_us, c.bad_signature, c.dropped) == (2, 2, 1, 1, 0, 4)
    assert inbox.take() == [MavlinkDesignation(4117, 250, 190, True), MavlinkDesignation(8, 250, 190, True)]
    assert inbox.take() == []
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert sum("dropped: not signed" in w for w in warnings) == 1  # the second is logged at DEBUG
    assert any("answered DENIED: param1 -3.0" in w for w in warnings)
    assert inbox.summary() == "MAVLink: 2 designation(s), 4 dropped"


def test_the_bench_inbox_says_so_loudly(caplog):
    with caplog.at_level(logging.WARNING, logger="chaser_bt.vehicle.designation"):
        inbox = DesignationInbox(CHASER, allow_unsigned=True)
        (msg,) = _vehicle_parser(None)[0].parse_buffer(_designate(3).pack(_gcs(None)))
        inbox.receive(msg, sysid=VEHICLE, auth=Auth.UNSIGNED)
    text = caplog.text
    assert "UNSIGNED designations are believed (bench use only)" in text and "track 3 from 255/190 UNSIGNED" in text
    assert inbox.take() == [MavlinkDesignation(3, 255, 190, False)]
    assert inbox.summary().endswith("unsigned allowed")


# ----------------------------------------------------------------------------- the link
def _link_rig(**config):
    from chaser_bt.vehicle import LinkConfig
    from tests.vehicle.vehicle_fakes import make_rig

    rig = make_rig(LinkConfig(**config))
    rig.run(1.5)  # the vehicle is heard; the link's heartbeats go out
    return rig


def test_an_unsigned_link_listens_for_no_designation_and_keeps_its_one_identity():
    rig = _link_rig()
    assert rig.link.designations is None and rig.link.take_designations() == []
    _gcs(None, sysid=250, file=rig.fake.end).send(_designate(4117))
    rig.run(0.5)
    assert rig.link.take_designations() == []
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in rig.fake.received} == {(255, 190)}


def test_the_link_answers_as_its_component_and_hands_the_designation_out():
    rig = _link_rig(designation_unsigned=True)
    beats = [m for m in rig.fake.sent_by_link("HEARTBEAT") if m.get_srcComponent() == CHASER]
    assert beats and all((m.get_srcSystem(), m.type, m.autopilot) == (VEHICLE, mavlink2.MAV_TYPE_ONBOARD_CONTROLLER,
                                                                      mavlink2.MAV_AUTOPILOT_INVALID) for m in beats)
    gcs = _gcs(None, sysid=250, compid=190, file=rig.fake.end)
    gcs.send(_designate(4117))
    gcs.send(_designate(-1))
    gcs.send(_designate(7, to=(VEHICLE, 1)))  # the autopilot's: not answered by the link
    rig.run(0.5)
    acks = [m for m in rig.fake.sent_by_link("COMMAND_ACK")]
    assert [(m.get_srcSystem(), m.get_srcComponent(), m.command, m.result, m.result_param2, m.target_system,
             m.target_component) for m in acks] == [(VEHICLE, CHASER, USER_1, ACCEPTED, 0, 250, 190),
                                                     (VEHICLE, CHASER, USER_1, DENIED, 1, 250, 190)]
    assert rig.link.take_designations() == [MavlinkDesignation(4117, 250, 190, False)]
    assert rig.link.counters.other_systems == 1  # the command for the autopilot, as before


# ----------------------------------------------------------------------------- through the simulator
def _scenario():
    from sitl.world.scenario import Scenario

    return Scenario.from_dict({
        "name": "designation", "home": {"lat_deg": 42.5445, "lon_deg": -71.6105, "alt_m": 80.0},
        "wind": {"speed_mps": 0.0, "gust_std_mps": 0.0},
        "boot": {"gps_fix_s": 1.0, "ekf_ready_s": 2.0, "prearm_ok_s": 3.0},
    }, source="<test>")


def test_a_ground_station_on_another_port_designates_through_the_simulator_as_through_arducopter():
    from chaser_bt.clock import ManualClock
    from chaser_bt.tree import load_tree_text
    from chaser_bt.vehicle import LinkConfig, VehicleLink, byte_pipe
    from sitl.simulator import Simulator

    sim = Simulator(_scenario(), 0)
    sim.endpoint.enable_signing(SigningConfig(KEY), epoch_unix_s=time.time())  # clocks as chaser-bt sitl's
    mission_end, sim_end = byte_pipe()
    sim.attach(sim_end)
    link = VehicleLink.over_pipe(mission_end, LinkConfig(signing=SigningConfig(KEY, link_id=1)),
                                 monotonic=lambda: sim.time_s)
    gcs_end, sim_gcs_end = byte_pipe()
    sim.attach(sim_gcs_end)
    gcs = _gcs(KEY, sysid=250, compid=190, link_id=2, file=gcs_end)
    heard = mavlink2.MAVLink(None)  # the ground station's parser: checks signatures, lets unsigned through
    heard.robust_parsing = True
    heard.signing.secret_key = KEY
    heard.signing.allow_unsigned_callback = lambda mav, msg_id: True
    seen: list = []

    def step() -> None:
        sim.step()
        link.poll()
        seen.extend(m for m in (heard.parse_buffer(gcs_end.read()) or []) if m.get_type() != "BAD_DATA")

    link.wait(lambda: link.target_compid is not None, 5.0, pump=step)
    gcs.heartbeat_send(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    link.wait(lambda: any(m.get_type() == "HEARTBEAT" and m.get_srcComponent() == CHASER for m in seen), 3.0, pump=step)
    # ArduCopter has learnt the route to component 191 and forwards its heartbeat: the ground station sees it

    _gcs(None, sysid=250, file=gcs_end).send(_designate(99))  # unsigned: the signing vehicle drops it
    gcs.send(_designate(4117))
    for _ in range(10):
        step()
    acks = [m for m in seen if m.get_type() == "COMMAND_ACK" and m.command == USER_1]
    assert [(m.get_srcSystem(), m.get_srcComponent(), m.result, m.target_system) for m in acks] == [
        (VEHICLE, CHASER, ACCEPTED, 250)]  # one answer, from the chaser, forwarded back by the vehicle
    assert acks[0].get_signed()  # signed by the link, with the key the ground station holds
    assert sim.endpoint.stats.forwarded >= 3 and sim.endpoint.signing.counters.unsigned_rejected >= 1
    assert link.designations.counters.accepted == 1 and link.designations.counters.unsigned == 0

    clock = ManualClock(0.0)
    py_trees.blackboard.Blackboard.set("/vehicle/state", link.state)
    py_trees.blackboard.Blackboard.unset("/radar/operator_confirmed_track")
    tree = load_tree_text("version: 1\ntrees:\n  Main:\n    GroundDesignation: {}\n", source="<test>")
    bt = py_trees.trees.BehaviourTree(tree.root)
    bt.setup(link=link, clock=clock)
    bt.tick()
    assert py_trees.blackboard.Blackboard.storage.get("/radar/operator_confirmed_track") == 4117
    assert bt.root.feedback_message == "uplink off (chaser-bt run --uplink); MAVLink: 1 designation(s), 0 dropped"


# ----------------------------------------------------------------------------- in a rehearsal
DESIGNATE_ON_THE_GROUND = """
version: 1
trees:
  Main:
    Parallel:
      success_count: 1
      children:
        - Wait: {duration_s: 40}
        - Sequence:
            children:
              - RetryUntilSuccessful:
                  num_attempts: -1
                  child:
                    RadarTrackValidated: {min_confidence: 0.3, min_track_age_s: 1.0}
              - KeepRunningUntilFailure:
                  child:
                    ForceSuccess:
                      child:
                        Sequence:
                          children:
                            - GroundDesignation: {}
                            - RadarCue: {max_age_s: 5.0}
"""


def test_a_designation_from_a_second_client_switches_the_chases_target_in_a_rehearsal():
    """Two intruders 300 m apart; the radar validates one; a ground station on a second port of the
    simulator designates the other's track (unsigned, the bench flag on); custody follows it."""
    from pathlib import Path

    import numpy as np

    from chaser_bt.tree import load_tree_text
    from chaser_bt.vehicle import LinkConfig, byte_pipe
    from sitl.bench.rehearsal import rehearse
    from sitl.bench.sensors import SensorOptions

    scenario = Path(__file__).resolve().parents[2] / "sitl" / "scenarios" / "hard" / "two_intruders.yaml"
    world: dict = {}
    ground = mavlink2.MAVLink(None)
    ground.robust_parsing = True

    def nearest_object(position_enu) -> str:
        """The simulated object the radar saw nearest ``position_enu`` (truth, not the mission's picture)."""
        objects = world["vehicle"].sim.radar_objects()
        return min(objects, key=lambda name: float(np.linalg.norm(objects[name][0] - position_enu)))

    def on_start(runner, vehicle, resources) -> None:
        gcs_end, sim_end = byte_pipe()
        vehicle.sim.attach(sim_end)  # the ground station's own port on the simulator
        world.update(vehicle=vehicle, radar=resources["radar"], gcs_end=gcs_end, acks=[],
                     gcs=_gcs(None, sysid=250, compid=190, file=gcs_end))

    def on_tick(changes) -> None:
        acks = [m for m in ground.parse_buffer(world["gcs_end"].read()) or [] if m.get_type() == "COMMAND_ACK"]
        world["acks"] += [(m.get_srcSystem(), m.get_srcComponent(), m.command, m.result) for m in acks]
        custody = py_trees.blackboard.Blackboard.storage.get("/target/custody")
        if custody is None or "designated" in world or custody.track_id is None:
            return
        picture = world["radar"].update(world["vehicle"].clock.now())  # this tick's, as the leaves saw it
        held = nearest_object(custody.position_enu)
        others = [tr for tr in picture.intruders if nearest_object(tr.position_enu) not in (held,)
                  and np.linalg.norm(tr.position_enu - custody.position_enu) > 150.0]
        if others:
            world.update(designated=others[0].track_id, first=held, other=nearest_object(others[0].position_enu))
            world["gcs"].send(_designate(others[0].track_id))

    tree = load_tree_text(DESIGNATE_ON_THE_GROUND, source="<test>")
    rehearse(tree, scenario, 3, link_config=LinkConfig(target_sysid=VEHICLE, designation_unsigned=True),
             sensors=SensorOptions(radar_pose="surveyed", camera=False, telemetry=False),
             on_start=on_start, on_tick=on_tick)
    assert "designated" in world, "the radar never showed both intruders"
    assert {world["first"], world["other"]} == {"intruder", "second"}
    assert (VEHICLE, CHASER, USER_1, ACCEPTED) in world["acks"]
    custody = py_trees.blackboard.Blackboard.storage.get("/target/custody")
    assert custody.target_id == world["designated"] and custody.designated_by == "operator"
    assert nearest_object(custody.position_enu) == world["other"]
