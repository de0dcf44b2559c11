"""The mission, fence and rally protocol, as ArduCopter answers it.

Reference: the 4.7.0-dev SITL in ``../shared/ardupilot``, read with pymavlink (home 42.5, -71.6,
80 m): MISSION_REQUEST_LIST gave MISSION_COUNT 1 for the mission and 0 for fence and rally; item 0
was home (frame 0 GLOBAL, command 16 NAV_WAYPOINT, x/y home's 1e7 degrees, z home's AMSL altitude);
MISSION_REQUEST_INT past the end (mission seq 5, fence seq 0) got MISSION_ACK 13 INVALID_SEQUENCE;
an upload of 2 items was asked for with MISSION_REQUEST (not _INT) seq 0 and 1, acknowledged with
MISSION_ACK 0 and "Flight plan received", and read back unchanged; MISSION_CLEAR_ALL got MISSION_ACK
0 and left MISSION_COUNT 0. The simulator stores what is uploaded; it does not fly AUTO.
"""

from __future__ import annotations

from mavlink_gcs import FIELD, mav, ready_gcs

MISSION, FENCE, RALLY = 0, 1, 2


def _count(gcs, mission_type: int) -> int:
    gcs.send(mav.MAVLink_mission_request_list_message(1, 1, mission_type))
    return gcs.wait_for("MISSION_COUNT", 1.0, lambda m: m.mission_type == mission_type).count


def _reply(gcs, request):
    gcs.send(request)
    return next(
        m for m in gcs.run(0.1) if m.get_type() in ("MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK",
                                                     "MISSION_REQUEST", "MISSION_REQUEST_INT"))


def _waypoint(seq: int, lat: float, lon: float, alt: float, frame: int = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT):
    return mav.MAVLink_mission_item_int_message(1, 1, seq, frame, mav.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, 0,
                                                round(lat * 1e7), round(lon * 1e7), alt, MISSION)


def test_a_fresh_vehicle_has_home_as_its_only_mission_item_and_no_fence_or_rally():
    gcs = ready_gcs()
    assert (_count(gcs, MISSION), _count(gcs, FENCE), _count(gcs, RALLY)) == (1, 0, 0)
    home = gcs.sim.autopilot.home
    item = _reply(gcs, mav.MAVLink_mission_request_int_message(1, 1, 0, MISSION))
    assert item.get_type() == "MISSION_ITEM_INT"
    assert (item.seq, item.frame, item.command, item.mission_type) == (0, mav.MAV_FRAME_GLOBAL, 16, MISSION)
    assert abs(item.x - FIELD["lat_deg"] * 1e7) < 100 and abs(item.y - FIELD["lon_deg"] * 1e7) < 100
    assert (item.x, item.y) == (round(home.lat_deg * 1e7), round(home.lon_deg * 1e7))
    assert abs(item.z - FIELD["alt_m"]) < 1.0 and abs(item.z - home.alt_m) < 1e-4  # a float32 field
    assert (item.target_system, item.target_component) == (255, 190)


def test_a_sequence_number_past_the_end_is_invalid():
    gcs = ready_gcs()
    ack = _reply(gcs, mav.MAVLink_mission_request_int_message(1, 1, 5, MISSION))
    assert (ack.get_type(), ack.type, ack.mission_type) == ("MISSION_ACK", mav.MAV_MISSION_INVALID_SEQUENCE, MISSION)
    ack = _reply(gcs, mav.MAVLink_mission_request_int_message(1, 1, 0, FENCE))
    assert (ack.get_type(), ack.type, ack.mission_type) == ("MISSION_ACK", mav.MAV_MISSION_INVALID_SEQUENCE, FENCE)


def test_a_mission_upload_is_requested_item_by_item_stored_and_read_back():
    gcs = ready_gcs()
    req = _reply(gcs, mav.MAVLink_mission_count_message(1, 1, 2, MISSION))
    assert (req.get_type(), req.seq, req.mission_type) == ("MISSION_REQUEST", 0, MISSION)
    req = _reply(gcs, _waypoint(0, 42.5, -71.6, 0.0, mav.MAV_FRAME_GLOBAL_INT))
    assert (req.get_type(), req.seq) == ("MISSION_REQUEST", 1)
    gcs.send(_waypoint(1, 42.501, -71.6, 20.0))
    msgs = gcs.run(0.1)
    (ack,) = [m for m in msgs if m.get_type() == "MISSION_ACK"]
    assert (ack.type, ack.mission_type) == (mav.MAV_MISSION_ACCEPTED, MISSION)
    assert "Flight plan received" in [m.text for m in msgs if m.get_type() == "STATUSTEXT"]
    assert _count(gcs, MISSION) == 2
    item = _reply(gcs, mav.MAVLink_mission_request_int_message(1, 1, 1, MISSION))
    assert (item.frame, item.command, item.x, item.y, item.z) == (
        mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 16, 425010000, -716000000, 20.0)
    # item 0 reads as home whatever was uploaded there
    home_z = _reply(gcs, mav.MAVLink_mission_request_int_message(1, 1, 0, MISSION)).z
    assert abs(home_z - gcs.sim.autopilot.home.alt_m) < 1e-4


def test_the_legacy_request_gets_a_float_mission_item():
    gcs = ready_gcs()
    item = _reply(gcs, mav.MAVLink_mission_request_message(1, 1, 0, MISSION))
    assert item.get_type() == "MISSION_ITEM"
    assert abs(item.x - gcs.sim.autopilot.home.lat_deg) < 1e-6


def test_an_item_out_of_turn_is_asked_for_again():
    gcs = ready_gcs()
    _reply(gcs, mav.MAVLink_mission_count_message(1, 1, 2, MISSION))
    req = _reply(gcs, _waypoint(1, 42.5, -71.6, 10.0))
    assert (req.get_type(), req.seq) == ("MISSION_REQUEST", 0)


def test_clear_all_empties_the_mission():
    gcs = ready_gcs()
    gcs.send(mav.MAVLink_mission_clear_all_message(1, 1, MISSION))
    ack = gcs.wait_for("MISSION_ACK", 1.0)
    assert (ack.type, ack.mission_type) == (mav.MAV_MISSION_ACCEPTED, MISSION)
    assert _count(gcs, MISSION) == 0


def test_a_fence_polygon_upload_makes_a_polygon_only_fence_present():
    # AC_Fence::present(): a polygon fence counts once polygon points are stored
    gcs = ready_gcs(params={"FENCE_TYPE": 4})
    geofence = mav.MAV_SYS_STATUS_GEOFENCE
    assert not gcs.wait_for("SYS_STATUS", 1.0).onboard_control_sensors_present & geofence
    corners = [(42.5, -71.6), (42.501, -71.6), (42.501, -71.599)]
    _reply(gcs, mav.MAVLink_mission_count_message(1, 1, 3, FENCE))
    for seq, (lat, lon) in enumerate(corners):
        gcs.send(mav.MAVLink_mission_item_int_message(
            1, 1, seq, mav.MAV_FRAME_GLOBAL_INT, mav.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 0, 1, 3, 0, 0, 0,
            round(lat * 1e7), round(lon * 1e7), 0, FENCE))
        gcs.run(0.05)
    assert _count(gcs, FENCE) == 3
    assert gcs.wait_for("SYS_STATUS", 1.0).onboard_control_sensors_present & geofence


def test_a_rally_list_takes_only_rally_points():
    gcs = ready_gcs()
    _reply(gcs, mav.MAVLink_mission_count_message(1, 1, 1, RALLY))
    bad = mav.MAVLink_mission_item_int_message(1, 1, 0, mav.MAV_FRAME_GLOBAL_INT, mav.MAV_CMD_NAV_WAYPOINT, 0, 1,
                                               0, 0, 0, 0, 425000000, -716000000, 10, RALLY)
    ack = _reply(gcs, bad)
    assert (ack.get_type(), ack.type, ack.mission_type) == ("MISSION_ACK", mav.MAV_MISSION_UNSUPPORTED, RALLY)
    assert _count(gcs, RALLY) == 0
