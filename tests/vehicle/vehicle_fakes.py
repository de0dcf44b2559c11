"""Test doubles for the vehicle link: a scripted ArduCopter peer speaking real MAVLink 2 over a pipe.

``FakeArduCopter`` answers the way ArduCopter does for what the link uses (heartbeat with the mode
number in custom_mode, COMMAND_ACK for every command, STATUSTEXT explaining refusals, PARAM_VALUE
echoes, HOME_POSITION on request); tests change its answers per command to script failures.
"""

from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"

from dataclasses import dataclass, field  # noqa: E402
from typing import Callable  # noqa: E402

from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from chaser_bt.clock import ManualClock  # noqa: E402
from chaser_bt.geo import GeoPoint  # noqa: E402
from chaser_bt.vehicle import LinkConfig, VehicleLink, byte_pipe  # noqa: E402
from chaser_bt.vehicle.pipe import PipeEnd  # noqa: E402

HOME = GeoPoint(42.5, -71.6, 80.0)
READY_EKF = mavlink2.EKF_ATTITUDE | mavlink2.EKF_VELOCITY_HORIZ | mavlink2.EKF_VELOCITY_VERT | \
    mavlink2.EKF_POS_HORIZ_REL | mavlink2.EKF_POS_HORIZ_ABS | mavlink2.EKF_POS_VERT_ABS


def roundtrip(msg: mavlink2.MAVLink_message, sysid: int = 1, compid: int = 1) -> mavlink2.MAVLink_message:
    """Encode ``msg`` as an autopilot would and decode it again, so tests see wire values."""
    encoder = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    decoded = mavlink2.MAVLink(None).parse_buffer(msg.pack(encoder))
    assert decoded is not None and len(decoded) == 1
    return decoded[0]


@dataclass
class FakeArduCopter:
    """ArduCopter as seen over MAVLink, scripted; time comes from ``clock`` like the link's."""

    end: PipeEnd
    clock: ManualClock
    sysid: int = 1
    compid: int = 1
    mode_number: int = 0  # STABILIZE
    armed: bool = False
    ready: bool = True  # pre-arm bit, 3-D fix, EKF position
    apply_modes: bool = True  # False: ack mode changes but keep showing the old mode
    send_home: bool = True
    telemetry: bool = True  # SYS_STATUS, GPS_RAW_INT, EKF_STATUS_REPORT, GLOBAL_POSITION_INT each second
    position: tuple[float, float, float, float] = (HOME.lat_deg, HOME.lon_deg, HOME.alt_m, 0.0)  # lat, lon, amsl, rel
    params: dict[str, float] = field(default_factory=lambda: {"RTL_ALT": 1500.0, "DISARM_DELAY": 10.0})
    # Per MAV_CMD: a function of the COMMAND_LONG returning (result or None for no ack, statustext or "", text_first)
    answers: dict[int, Callable[[object], tuple[int | None, str, bool]]] = field(default_factory=dict)
    received: list = field(default_factory=list)
    _next_hb: float = 0.0

    def __post_init__(self) -> None:
        self.mav = mavlink2.MAVLink(self.end, srcSystem=self.sysid, srcComponent=self.compid)
        self.parser = mavlink2.MAVLink(None)
        self.parser.robust_parsing = True

    # --- sending
    def send(self, msg: mavlink2.MAVLink_message) -> None:
        self.mav.send(msg)

    def heartbeat(self) -> None:
        base = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (mavlink2.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        self.mav.heartbeat_send(mavlink2.MAV_TYPE_OCTOROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, base,
                                self.mode_number, mavlink2.MAV_STATE_STANDBY)

    def statustext(self, text: str, severity: int = mavlink2.MAV_SEVERITY_CRITICAL) -> None:
        self.mav.statustext_send(severity, text.encode())

    def send_telemetry(self) -> None:
        t_ms = int(self.clock.now() * 1000)
        health = mavlink2.MAV_SYS_STATUS_PREARM_CHECK if self.ready else 0
        self.mav.sys_status_send(0, 0, health, 200, 22200, 500, 87, 0, 0, 0, 0, 0, 0)
        self.mav.gps_raw_int_send(t_ms * 1000, 3 if self.ready else 1, int(self.position[0] * 1e7),
                                  int(self.position[1] * 1e7), int(self.position[2] * 1000), 100, 100, 0, 0, 12)
        self.mav.ekf_status_report_send(READY_EKF if self.ready else mavlink2.EKF_ATTITUDE, 0, 0, 0, 0, 0)
        lat, lon, amsl, rel = self.position
        self.mav.global_position_int_send(t_ms, int(round(lat * 1e7)), int(round(lon * 1e7)), int(amsl * 1000),
                                          int(rel * 1000), 0, 0, 0, 0)

    def home_position(self) -> None:
        self.mav.home_position_send(int(HOME.lat_deg * 1e7), int(HOME.lon_deg * 1e7), int(HOME.alt_m * 1000),
                                    0, 0, 0, [1, 0, 0, 0], 0, 0, 0)

    # --- the loop
    def tick(self) -> None:
        """Answer what arrived, then send the heartbeat and telemetry when due (1 Hz)."""
        data = self.end.read()
        for msg in (self.parser.parse_buffer(data) or []) if data else []:
            if msg.get_type() != "BAD_DATA":
                self.received.append(msg)
                self._answer(msg)
        if self.clock.now() >= self._next_hb:
            self.heartbeat()
            if self.telemetry:
                self.send_telemetry()
            self._next_hb += 1.0

    def _answer(self, msg) -> None:
        kind = msg.get_type()
        if kind == "COMMAND_LONG" and msg.target_system == self.sysid:
            custom = self.answers.get(msg.command)
            result, text, text_first = custom(msg) if custom else self._default_answer(msg)
            if text and text_first:
                self.statustext(text)
            if result is not None:
                self.mav.command_ack_send(msg.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
            if text and not text_first:
                self.statustext(text)
        elif kind in ("PARAM_SET", "PARAM_REQUEST_READ") and msg.target_system == self.sysid:
            name = msg.param_id
            if name not in self.params:
                return
            if kind == "PARAM_SET":
                self.params[name] = float(int(msg.param_value)) if name == "DISARM_DELAY" else msg.param_value
            self.mav.param_value_send(name.encode(), self.params[name], mavlink2.MAV_PARAM_TYPE_REAL32,
                                      len(self.params), list(self.params).index(name))

    def _default_answer(self, msg) -> tuple[int | None, str, bool]:
        accepted = mavlink2.MAV_RESULT_ACCEPTED
        if msg.command == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 == 1 and not self.ready:
                return mavlink2.MAV_RESULT_FAILED, "PreArm: Need 3D Fix", True
            self.armed = msg.param1 == 1
            return accepted, "", False
        if msg.command == mavlink2.MAV_CMD_DO_SET_MODE:
            if self.apply_modes:
                self.mode_number = int(msg.param2)
            return accepted, "", False
        if msg.command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            self.mode_number = 6
            return accepted, "", False
        if msg.command == mavlink2.MAV_CMD_REQUEST_MESSAGE:
            if msg.param1 == mavlink2.MAVLINK_MSG_ID_HOME_POSITION and self.send_home:
                self.home_position()
                return accepted, "", False
            return mavlink2.MAV_RESULT_FAILED, "", False
        return accepted, "", False

    def sent_by_link(self, kind: str, command: int | None = None) -> list:
        """Messages of ``kind`` received from the link (COMMAND_LONGs filtered by ``command``)."""
        return [m for m in self.received if m.get_type() == kind and (command is None or m.command == command)]


@dataclass
class Rig:
    """A link and a fake ArduCopter on one manual clock."""

    clock: ManualClock
    link: VehicleLink
    fake: FakeArduCopter

    def run(self, seconds: float, dt: float = 0.05, until: Callable[[], bool] | None = None) -> None:
        """Alternate fake.tick / link.poll while advancing the clock by ``dt``."""
        t0 = self.clock.now()
        for i in range(1, int(round(seconds / dt)) + 1):
            self.fake.tick()
            self.link.poll()
            if until is not None and until():
                return
            self.clock.set(round(t0 + i * dt, 9))


def make_rig(config: LinkConfig | None = None, **fake_kwargs) -> Rig:
    a, b = byte_pipe()
    clock = ManualClock(0.0)
    link = VehicleLink.over_pipe(a, config or LinkConfig(), monotonic=clock.now)
    return Rig(clock, link, FakeArduCopter(b, clock, **fake_kwargs))
