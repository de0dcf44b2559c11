"""Simulator composition: ports, lock-step stepping, determinism and the scripted radio link."""

from __future__ import annotations

import itertools

import pytest
from mavlink_gcs import PipeGcs, mav, quick_scenario

from chaser_bt.vehicle.pipe import byte_pipe
from sitl.simulator import Simulator


def _scripted_session(seed: int) -> bytes:
    """Everything a simulator sends during a fixed GCS session: boot, arm, take off, fly north."""
    sim = Simulator(quick_scenario(wind={"speed_mps": 4.0, "gust_std_mps": 1.0}), seed)
    sim_end, gcs_end = byte_pipe()
    sim.attach(sim_end)
    gcs = mav.MAVLink(None, srcSystem=255, srcComponent=190)
    script = {
        200: mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_DO_SET_MODE, 0, 1, 4, 0, 0, 0, 0, 0),
        210: mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0),
        220: mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 10),
        900: mav.MAVLink_set_position_target_local_ned_message(
            0, 1, 1, mav.MAV_FRAME_LOCAL_NED, 0b110111111000, 30, 0, -10, 0, 0, 0, 0, 0, 0, 0, 0),
    }
    out = bytearray()
    for step in range(1500):
        if step in script:
            gcs_end.write(script[step].pack(gcs))
            gcs.seq += 1
        sim.step()
        out += gcs_end.read()
    return bytes(out)


def test_same_scenario_and_seed_give_byte_identical_output():
    first = _scripted_session(7)
    assert len(first) > 40_000  # a substantial session (MAVLink 2 trims zero bytes: a grounded vehicle sends fewer)
    assert _scripted_session(7) == first


def test_a_different_seed_changes_the_noise_on_the_wire():
    assert _scripted_session(7) != _scripted_session(8)


def test_every_attached_port_gets_the_same_telemetry_and_commands_from_any_port_work():
    # each port is its own link, as ArduCopter gives each client one (../shared/ardupilot/README):
    # the same default telemetry on both, a command from b obeyed, its ACK to b only
    sim = Simulator(quick_scenario(), 0)
    a, b = PipeGcs(sim), PipeGcs(sim, sysid=254)
    a.run(3.5)
    b.poll()
    assert [m.get_type() for _, m in a.log] == [m.get_type() for _, m in b.log]
    b.command(mav.MAV_CMD_DO_SET_MODE, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 5)
    assert a.wait_for("HEARTBEAT", 1.5, lambda m: m.custom_mode == 5) is not None
    b.poll()
    assert b.of_type("COMMAND_ACK")[-1].target_system == 254
    assert a.of_type("COMMAND_ACK") == []


def test_message_rates_are_set_per_port():
    # ArduCopter: SET_MESSAGE_INTERVAL and REQUEST_DATA_STREAM apply to the link they came in on
    sim = Simulator(quick_scenario(), 0)
    a, b = PipeGcs(sim), PipeGcs(sim, sysid=254)
    a.command(mav.MAV_CMD_SET_MESSAGE_INTERVAL, mav.MAVLINK_MSG_ID_ATTITUDE, 20_000)  # 50 Hz
    b.send(mav.MAVLink_request_data_stream_message(1, 1, mav.MAV_DATA_STREAM_ALL, 0, 0))  # b: streams off
    a.run(0.1)
    b.poll()
    t0 = sim.time_s + 1e-6  # what was read after this
    a.run(2.0)
    b.poll()
    assert len(a.of_type("ATTITUDE", t0)) == pytest.approx(100, abs=2)
    assert b.of_type("ATTITUDE", t0) == [] and b.of_type("GLOBAL_POSITION_INT", t0) == []
    assert len(b.of_type("HEARTBEAT", t0)) == 2  # not a stream: 1 Hz on every link
    assert len(a.of_type("GLOBAL_POSITION_INT", t0)) == pytest.approx(8, abs=1)  # a keeps its 4 Hz


def test_each_port_numbers_its_own_packets():
    # per-link sequence numbers: no gaps on one client for what another was sent
    sim = Simulator(quick_scenario(), 0)
    a, b = PipeGcs(sim), PipeGcs(sim, sysid=254)
    a.run(0.5)
    for _ in range(5):
        b.command(mav.MAV_CMD_REQUEST_MESSAGE, mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    a.run(1.0)
    seqs = [m.get_seq() for _, m in a.log if m.get_srcSystem() == 1]
    assert all((y - x) % 256 == 1 for x, y in itertools.pairwise(seqs))


def test_detached_port_hears_nothing_more():
    sim = Simulator(quick_scenario(), 0)
    gcs = PipeGcs(sim)
    gcs.run(1.0)
    sim.detach(gcs.sim_end)
    sim.run_until(3.0)
    assert gcs.end.read() == b""


def test_run_until_advances_sim_time_by_whole_physics_steps():
    sim = Simulator(quick_scenario(), 0, physics_hz=100.0)
    assert sim.dt == pytest.approx(0.01)
    sim.run_until(2.5)
    assert sim.time_s == pytest.approx(2.5, abs=1e-6)
    sim.run_until(1.0)  # never backwards
    assert sim.time_s == pytest.approx(2.5, abs=1e-6)


def test_scripted_link_loss_cuts_both_directions_for_its_duration():
    scenario = quick_scenario(faults=[{"at_s": 5.0, "kind": "link_loss", "duration_s": 3.0}])
    sim = Simulator(scenario, 0)
    gcs = PipeGcs(sim)
    gcs.run(4.0)
    assert sim.link_up
    gcs.run(1.5)  # 5.5 s: inside the outage
    assert not sim.link_up
    gcs.command(mav.MAV_CMD_DO_SET_MODE, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 5)  # lost on the way up
    gcs.run(4.0)  # to 9.5 s
    times = sorted(m.time_boot_ms for m in gcs.of_type("ATTITUDE"))
    gap = [t for t in times if 5000 <= t < 8000]
    assert gap == []
    assert any(t < 5000 for t in times) and any(t >= 8000 for t in times)
    assert gcs.of_type("COMMAND_ACK") == []
    assert gcs.of_type("HEARTBEAT")[-1].custom_mode == 0  # the mode change never arrived


def test_link_loss_without_duration_lasts_for_good_and_override_restores_it():
    sim = Simulator(quick_scenario(faults=[{"at_s": 1.0, "kind": "link_loss"}]), 0)
    gcs = PipeGcs(sim)
    gcs.run(1.5)
    n = len(gcs.log)
    gcs.run(3.0)
    assert len(gcs.log) == n
    sim.link_up = True
    gcs.run(1.1)
    assert len(gcs.log) > n
    sim.link_up = None  # back to the script: still in the permanent outage
    assert not sim.link_up


def test_lost_link_in_flight_triggers_the_gcs_failsafe_through_the_radio_cut():
    scenario = quick_scenario(faults=[{"at_s": 20.0, "kind": "link_loss", "duration_s": 30.0}])
    gcs = PipeGcs(Simulator(scenario, 0))
    gcs.run(3.5)
    gcs.set_mode(4)
    gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    gcs.command_ack(mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10)
    while gcs.sim.time_s < 30.0:  # heartbeats keep flowing, but the radio dies at 20 s
        gcs.heartbeat()
        gcs.run(1.0)
    assert gcs.sim.autopilot.mode == "RTL"
