"""The simulator forwards MAVLink between its ports by ArduPilot's rules (MAVLink_routing.cpp's comment).

The autopilot is 1/1. Port ``gcs`` carries a ground station (255/190), ``companion`` a companion
computer (1/191), ``other`` a second ground station (250/190). Each case names the rule of
ArduPilot's routing theory it checks (1a-1e: processed locally; 2a-2d: forwarded on a link).
"""

from __future__ import annotations

import gc
import os

os.environ["MAVLINK20"] = "1"

import pytest  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from sitl.vehicle.routing import Router  # noqa: E402


class Port:
    """A stand-in for a channel: only its identity matters to the router."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return self.name


def _from(sysid: int, compid: int, msg):
    """``msg`` as it arrives from ``sysid``/``compid``: packed and decoded again."""
    sender = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    (decoded,) = mavlink2.MAVLink(None).parse_buffer(msg.pack(sender))
    return decoded


def _heartbeat(kind: int = mavlink2.MAV_TYPE_GCS):
    return mavlink2.MAVLink_heartbeat_message(kind, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 4, 3)


def _command(to_sys: int, to_comp: int):
    return mavlink2.MAVLink_command_long_message(to_sys, to_comp, 31010, 0, 4117, 0, 0, 0, 0, 0, 0)


def _network():
    router = Router(1, 1)
    gcs, companion, other = Port("gcs"), Port("companion"), Port("other")
    ports = [gcs, companion, other]
    for port, ids in ((gcs, (255, 190)), (companion, (1, 191)), (other, (250, 190))):
        router.check_and_forward(_from(*ids, _heartbeat()), port, ports)
    return router, gcs, companion, other, ports


@pytest.fixture
def net():
    return _network()


def test_every_message_teaches_where_its_source_is(net):
    router, gcs, companion, other, _ = net
    assert router.routes() == [(255, 190, gcs), (1, 191, companion), (250, 190, other)]


def test_a_heartbeat_goes_everywhere_but_where_its_source_is_known(net):
    router, gcs, companion, other, ports = net
    assert router.check_and_forward(_from(1, 191, _heartbeat()), companion, ports) == (True, [gcs, other])
    # a second ground station with the first one's ids: neither hears the other's heartbeat
    router.check_and_forward(_from(255, 190, _heartbeat()), other, ports)
    assert router.check_and_forward(_from(255, 190, _heartbeat()), gcs, ports) == (True, [companion])


@pytest.mark.parametrize("target, local, forwarded", [
    ((1, 1), True, []),  # 1d: for the autopilot alone
    ((1, 191), False, ["companion"]),  # 2d: our system, a component heard on the companion's port
    ((1, 195), True, []),  # 1e: our system, a component heard nowhere
    ((1, 0), True, ["companion"]),  # 1d + 2d: every component of our system
    ((0, 0), True, ["companion", "other"]),  # 1b + 2b: everyone
    ((250, 190), False, ["other"]),  # 2c: another system, heard on that port
    ((250, 7), False, ["other"]),  # 2c: another system: its component is its own business
    ((77, 1), False, []),  # a system heard nowhere
])
def test_a_command_from_the_ground_station_goes_where_its_target_is(net, target, local, forwarded):
    router, gcs, _, _, ports = net
    go_local, out = router.check_and_forward(_from(255, 190, _command(*target)), gcs, ports)
    assert (go_local, [p.name for p in out]) == (local, forwarded)


def test_messages_without_targets_are_broadcast_and_radio_status_stays(net):
    router, gcs, companion, other, ports = net
    text = mavlink2.MAVLink_statustext_message(6, b"hello")
    assert router.check_and_forward(_from(1, 191, text), companion, ports) == (True, [gcs, other])  # 1a + 2a
    radio = mavlink2.MAVLink_radio_status_message(200, 190, 100, 90, 80, 0, 0)
    assert router.check_and_forward(_from(255, 190, radio), gcs, ports) == (True, [])


def test_our_own_messages_looped_back_are_neither_processed_nor_learnt(net):
    router, gcs, _, _, ports = net
    assert router.check_and_forward(_from(1, 1, _heartbeat(mavlink2.MAV_TYPE_OCTOROTOR)), gcs, ports) == (False, [])
    router.check_and_forward(_from(1, 0, mavlink2.MAVLink_statustext_message(6, b"x")), gcs, ports)
    assert all((s, k) not in ((1, 1), (1, 0)) for s, k, _ in router.routes())


def test_a_closed_port_takes_its_routes_with_it():
    router, gcs, companion, other, ports = _network()
    ports.remove(companion)
    del companion
    gc.collect()
    assert [(s, k) for s, k, _ in router.routes()] == [(255, 190), (250, 190)]
    assert router.check_and_forward(_from(255, 190, _command(1, 191)), gcs, ports) == (True, [])  # 1e again
