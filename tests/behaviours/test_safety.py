"""The safety layer's pieces on their own: mode authority, geofence, cue approach, and the safety leaves
ticked in tiny trees against a scripted vehicle state (the simulator flights are in tests/e2e/test_chase_transitions.py)."""

from __future__ import annotations

import math
import os

os.environ["MAVLINK20"] = "1"

import numpy as np
import py_trees
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.path import Path as MplPath
from pymavlink.dialects.v20 import ardupilotmega as mav

from chaser_bt.clock import ManualClock
from chaser_bt.control.cue_approach import approach_point
from chaser_bt.mission.geofence import Geofence, point_in_polygon
from chaser_bt.tree import load_tree_text
from chaser_bt.vehicle import VehicleState
from chaser_bt.vehicle.mode_authority import PENDING_HEARTBEATS, ModeAuthority

Status = py_trees.common.Status
GUIDED, LOITER, RTL = 4, 5, 6
ARMED = mav.MAV_MODE_FLAG_SAFETY_ARMED | mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


class _Msg:
    """A decoded message as the link hands it to listeners: a pymavlink message with its source."""

    def __init__(self, msg, src: int = 1):
        self._msg, self._src = msg, src

    def __getattr__(self, name):
        return getattr(self._msg, name)

    def get_srcSystem(self):
        return self._src


def _heartbeat(mode: int, armed: bool = True, src: int = 1):
    base = ARMED if armed else mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    return _Msg(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, base, mode, 4, 3), src)


def _set_mode(mode: int):
    return _Msg(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_DO_SET_MODE, 0, 1, mode, 0, 0, 0, 0, 0), 255)


class _FakeLink:
    """What the safety leaves use of a VehicleLink."""

    def __init__(self):
        self.target_sysid = 1
        self.last_setpoint = None
        self.sent: list[str] = []
        self.receivers, self.senders = [], []

    def add_listener(self, *, on_receive=None, on_send=None):
        if on_receive:
            self.receivers.append(on_receive)
        if on_send:
            self.senders.append(on_send)

    def receive(self, msg):
        for r in self.receivers:
            r(msg)

    def release_rc(self):
        self.sent.append("release_rc")
        self.last_setpoint = type("S", (), {"kind": "rc_release"})()

    def set_mode(self, name):
        self.sent.append(f"set_mode({name})")
        return type("Cmd", (), {"done": False, "ok": False})()

    def hover(self):
        self.sent.append("hover")
        return True

    frame = None  # no mission frame: RTL measures only the way down

    def rtl(self):
        self.sent.append("rtl")
        return type("Cmd", (), {"done": True, "ok": True})()


# ---------------------------------------------------------------------------- mode authority

def test_mode_changes_the_mission_asked_for_are_its_own_and_others_are_foreign():
    t = [10.0]
    authority = ModeAuthority(lambda: t[0], lambda: 1)
    authority.on_receive(_heartbeat(GUIDED))
    authority.on_send(_set_mode(LOITER))
    authority.on_receive(_heartbeat(GUIDED))  # not switched yet
    authority.on_receive(_heartbeat(LOITER))
    assert authority.foreign == [] and authority.own_changes == 1
    t[0] = 20.0
    authority.on_receive(_Msg(mav.MAVLink_statustext_message(4, b"GCS Failsafe")))
    authority.on_receive(_Msg(mav.MAVLink_statustext_message(6, b"EKF3 IMU0 is using GPS")))  # chatter after it
    authority.on_receive(_heartbeat(RTL))
    (change,) = authority.foreign
    assert (change.t, change.previous, change.mode, change.armed, change.why) == (20.0, "LOITER", "RTL", True, "GCS Failsafe")
    assert authority.foreign_since(19.9) == change and authority.foreign_since(20.0) is None
    t[0] = 30.0
    authority.on_receive(_heartbeat(RTL, armed=False))  # landed and disarmed
    authority.on_receive(_heartbeat(LOITER, armed=False))  # someone on the ground picks a mode
    assert authority.foreign_since(19.9).mode == "LOITER"
    assert authority.foreign_since(19.9, armed_only=True) == change  # in flight, only the RTL counted


def test_a_reason_sent_just_after_the_mode_change_still_explains_it():
    """ArduCopter's RC failsafe showed RTL in a heartbeat before its text: a change with no reason takes
    the first NOTICE-or-worse text within LATE_REASON_S (2 s), and only that one; later, or after a
    change that had its reason, a text is kept for the next change as before."""
    t = [10.0]
    authority = ModeAuthority(lambda: t[0], lambda: 1)
    authority.on_receive(_heartbeat(GUIDED))
    authority.on_receive(_heartbeat(RTL))
    assert authority.foreign[-1].why == ""
    t[0] = 11.5
    authority.on_receive(_Msg(mav.MAVLink_statustext_message(6, b"EKF3 IMU0 is using GPS")))  # INFO: never a reason
    authority.on_receive(_Msg(mav.MAVLink_statustext_message(2, b"Radio Failsafe")))
    authority.on_receive(_Msg(mav.MAVLink_statustext_message(4, b"PreArm: Radio failsafe on")))
    assert authority.foreign[-1].why == "Radio Failsafe"
    authority.on_receive(_heartbeat(LOITER))  # the next change: the later text was kept for it
    assert authority.foreign[-1].why == "PreArm: Radio failsafe on"
    authority.on_receive(_heartbeat(GUIDED))
    t[0] = 14.0  # too late for the GUIDED change
    authority.on_receive(_Msg(mav.MAVLink_statustext_message(4, b"GCS Failsafe")))
    assert authority.foreign[-1].why == ""
    authority.on_receive(_heartbeat(RTL))
    assert authority.foreign[-1].why == "GCS Failsafe"


def test_a_request_the_vehicle_never_honoured_expires_after_some_heartbeats():
    authority = ModeAuthority(lambda: 0.0, lambda: 1)
    authority.on_receive(_heartbeat(GUIDED))
    authority.on_send(_set_mode(LOITER))
    for _ in range(PENDING_HEARTBEATS + 1):
        authority.on_receive(_heartbeat(GUIDED))
    authority.on_receive(_heartbeat(LOITER))  # now it is the operator's doing
    assert [c.mode for c in authority.foreign] == ["LOITER"]


def test_rtl_command_counts_as_asking_for_rtl_and_other_systems_are_ignored():
    authority = ModeAuthority(lambda: 0.0, lambda: 1)
    authority.on_receive(_heartbeat(GUIDED))
    authority.on_send(_Msg(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0, 0, 0, 0, 0, 0)))
    authority.on_receive(_heartbeat(LOITER, src=2))  # the intruder's heartbeat
    authority.on_receive(_heartbeat(RTL))
    assert authority.foreign == [] and authority.mode == "RTL"


# ---------------------------------------------------------------------------- geofence

def test_cylinder_and_ceiling_by_hand():
    fence = Geofence(radius_m=100.0, max_alt_m=50.0, center_en=(10.0, 0.0))
    assert fence.breach([10.0, 99.0, 20.0]) is None
    assert "fence radius" in fence.breach([10.0, 101.0, 20.0])
    assert "ceiling" in fence.breach([0.0, 0.0, 51.0])
    assert fence.breach([math.nan, 0.0, 0.0]) is None  # unknown position: no verdict


def test_bad_fences_are_refused():
    with pytest.raises(ValueError, match="pairs"):
        Geofence(polygon_en=(0, 0, 1, 1))
    with pytest.raises(ValueError, match=">= 0"):
        Geofence(radius_m=-1.0)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.floats(-100, 100), st.floats(-100, 100)), min_size=3, max_size=8),
       st.floats(-120, 120), st.floats(-120, 120))
def test_polygon_containment_agrees_with_matplotlib(vertices, x, y):
    poly = np.array(vertices)
    path = MplPath(np.vstack([poly, poly[:1]]), closed=True)
    # Away from the edges the two must agree (on an edge either answer is acceptable).
    edges = [(poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly))]
    near = min(_segment_distance(np.array([x, y]), a, b) for a, b in edges)
    if near > 1e-3:
        assert point_in_polygon(x, y, poly) == bool(path.contains_point((x, y)))


def _segment_distance(p, a, b):
    ab = b - a
    denom = float(np.dot(ab, ab))
    t = 0.0 if denom < 1e-12 else float(np.clip(np.dot(p - a, ab) / denom, 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


# ---------------------------------------------------------------------------- cue approach

def test_approach_stops_short_of_the_cue_above_it_facing_it():
    # Chaser at home, cue 100 m north at 30 m: goal 30 m short (70 m north), 25 m above the cue, nose north.
    plan = approach_point([0, 0, 20], [0, 100, 30], standoff_m=30.0, min_alt_m=20.0, height_above_m=25.0)
    np.testing.assert_allclose(plan.goal_enu, [0, 70, 55], atol=1e-9)
    assert plan.yaw_enu_rad == pytest.approx(math.pi / 2)
    assert plan.distance_m == pytest.approx(70.0)


def test_approach_backs_off_when_too_close_and_keeps_the_minimum_altitude():
    # 3-4-5: chaser 5 m south-west of the cue; standoff 10 m along the same line, floor 20 m.
    plan = approach_point([-3, -4, 12], [0, 0, 2], standoff_m=10.0, min_alt_m=20.0, height_above_m=5.0)
    np.testing.assert_allclose(plan.goal_enu, [-6, -8, 20], atol=1e-9)
    assert plan.yaw_enu_rad == pytest.approx(math.atan2(4, 3))


# ---------------------------------------------------------------------------- leaves in tiny trees

class _Rig:
    """A tree of safety leaves with a scripted vehicle state and clock."""

    def __init__(self, body: str, inputs: str = "[]"):
        text = f"version: 1\ninputs: {inputs}\ntrees:\n  T:\n" + "\n".join("    " + ln for ln in body.strip().splitlines())
        self.tree = load_tree_text(text, source="<test>")
        self.link, self.clock, self.state = _FakeLink(), ManualClock(0.0), VehicleState()
        self.bb = py_trees.blackboard.Client(name="rig")
        self.bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
        for node in self.tree.root.iterate():
            node.setup(link=self.link, clock=self.clock)

    def tick(self, t: float) -> Status:
        self.clock.set(t)
        self.bb.set("/vehicle/state", self.state)
        self.tree.root.tick_once()
        return self.tree.root.status


def test_pilot_gate_reads_the_switch_and_stamps_each_enable():
    rig = _Rig("PilotGate: {channel: 7}")
    assert rig.tick(0.0) == Status.FAILURE  # no RC_CHANNELS yet: off
    rig.state.rc_channels = (1500,) * 6 + (1900,)
    assert rig.tick(1.0) == Status.SUCCESS
    assert py_trees.blackboard.Blackboard.storage["/safety/enabled_since"] == 1.0
    assert rig.tick(2.0) == Status.SUCCESS
    rig.state.rc_channels = (1500,) * 6 + (1800,)  # not above ArduPilot's 1800
    assert rig.tick(3.0) == Status.FAILURE
    rig.state.rc_channels = (1500,) * 6 + (2000,)
    assert rig.tick(4.0) == Status.SUCCESS
    assert py_trees.blackboard.Blackboard.storage["/safety/enabled_since"] == 4.0


def test_link_lost_after_the_silence_on_the_mission_clock():
    rig = _Rig("LinkLost: {max_silence_s: 3.0}")
    assert rig.tick(0.0) == Status.FAILURE  # nothing heard yet
    rig.state.t_boot_s = 5.0
    assert rig.tick(1.0) == Status.FAILURE
    assert rig.tick(4.0) == Status.FAILURE  # exactly 3 s
    assert rig.tick(4.1) == Status.SUCCESS
    rig.state.t_boot_s = 5.5
    assert rig.tick(4.2) == Status.FAILURE


def test_untrustworthy_telemetry_is_a_lost_link():
    rig = _Rig("LinkLost: {max_silence_s: 3.0}")
    rig.state.t_boot_s = 5.0
    assert rig.tick(1.0) == Status.FAILURE
    rig.state.telemetry_fault = "two senders use the vehicle's ids"
    assert rig.tick(1.1) == Status.SUCCESS and rig.tree.root.feedback_message == "two senders use the vehicle's ids"


def test_latch_holds_success_until_autonomy_is_re_enabled():
    rig = _Rig('Latch: {child: {AlwaysFailure: {_successIf: "@breach"}}}', inputs="[breach]")
    bb = py_trees.blackboard.Client(name="t")
    bb.register_key("/breach", access=py_trees.common.Access.WRITE)
    bb.register_key("/safety/enabled_since", access=py_trees.common.Access.WRITE)
    bb.set("/breach", False)
    bb.set("/safety/enabled_since", 0.0)
    assert rig.tick(0.0) == Status.FAILURE
    bb.set("/breach", True)
    assert rig.tick(1.0) == Status.SUCCESS
    bb.set("/breach", False)  # back inside: still latched
    assert rig.tick(2.0) == Status.SUCCESS
    bb.set("/safety/enabled_since", 3.0)  # the pilot switched autonomy off and on
    assert rig.tick(3.0) == Status.FAILURE


def test_yield_releases_held_sticks_and_hands_a_guided_aircraft_back_once():
    rig = _Rig("YieldToPilot: {handback_mode: LOITER}")
    rig.state.armed, rig.state.mode, rig.state.landed_state = True, "GUIDED", rig.state.landed_state.IN_AIR
    rig.link.last_setpoint = type("S", (), {"kind": "rc_override"})()
    assert rig.tick(0.0) == Status.RUNNING
    assert rig.link.sent == ["release_rc", "set_mode(LOITER)"]
    assert rig.tick(1.0) == Status.RUNNING
    assert rig.link.sent == ["release_rc", "set_mode(LOITER)"]  # nothing more
    rig.state.landed_state = rig.state.landed_state.ON_GROUND  # the pilot lands it, and it sits still
    rig.state.velocity_enu = np.zeros(3)
    assert rig.tick(2.0) == Status.RUNNING
    assert rig.tick(3.0) == Status.RUNNING
    rig.state.armed = False
    assert rig.tick(3.5) == Status.SUCCESS  # landed and disarmed after flying: mission over


def test_yield_fails_when_the_aircraft_is_disarmed_in_the_air():
    rig = _Rig("YieldToPilot: {handback_mode: LOITER}")
    rig.state.armed, rig.state.mode, rig.state.landed_state = True, "LOITER", rig.state.landed_state.IN_AIR
    rig.state.alt_rel_m = 30.0
    assert rig.tick(0.0) == Status.RUNNING
    rig.state.armed = False
    assert rig.tick(1.0) == Status.FAILURE
    assert "disarmed in the air at 30.0 m" in rig.tree.root.feedback_message


def test_yield_without_hand_back_sends_nothing_at_all():
    rig = _Rig("YieldToPilot: {hand_back: false}")
    rig.state.armed, rig.state.mode = True, "GUIDED"
    assert rig.tick(0.0) == Status.RUNNING
    assert rig.link.sent == []


def test_unusable_safety_settings_are_validation_problems_at_their_line():
    from chaser_bt.tree import validate_tree_text

    text = """version: 1
trees:
  T:
    Sequence:
      children:
        - GeofenceBreached: {polygon_en: [0, 0, 1, 1]}
        - GeofenceBreached: {radius_m: -5}
        - PilotGate: {channel: 40}
        - FlyToCue: {standoff_m: -1}
        - GeofenceBreached: {radius_m: "{r}", polygon_en: [0, 0, 10, 0, 0, 10]}
"""
    problems = [str(p) for p in validate_tree_text(text, source="bad.yaml")]
    assert len(problems) == 4, problems
    assert "bad.yaml:6:" in problems[0] and "pairs of at least 3 vertices" in problems[0]
    assert "bad.yaml:7:" in problems[1] and "'radius_m' of GeofenceBreached must be >= 0, got -5" in problems[1]
    assert "bad.yaml:8:" in problems[2] and "'channel' of PilotGate must be 0..18, got 40" in problems[2]
    assert "bad.yaml:9:" in problems[3] and "'standoff_m' of FlyToCue must be >= 0, got -1" in problems[3]


def test_an_rtl_that_gets_no_nearer_the_ground_fails_with_the_autopilots_last_word():
    rig = _Rig("RTL: {stall_s: 20}")
    rig.state.armed, rig.state.mode, rig.state.landed_state = True, "RTL", rig.state.landed_state.IN_AIR
    rig.state.alt_rel_m, rig.state.velocity_enu, rig.state.t_boot_s = 30.0, np.zeros(3), 100.0
    assert rig.tick(100.0) == Status.RUNNING and rig.link.sent == ["rtl"]
    rig.state.statustexts.append((110.0, 4, "Terrain data missing"))
    for t in (105.0, 110.0, 115.0, 120.0):
        rig.state.alt_rel_m, rig.state.t_boot_s = 29.5, t  # hovering: RTL is not coming down
        assert rig.tick(t) == Status.RUNNING
    rig.state.t_boot_s = 120.5
    assert rig.tick(120.5) == Status.FAILURE
    assert rig.tree.root.feedback_message.startswith(
        "no progress for 20 s with 30 m to go: the autopilot said: Terrain data missing")
