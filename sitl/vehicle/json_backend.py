"""ArduPilot's JSON physics interface (``--model JSON:IP``): the wire format and the lock-step loop.

ArduPilot's SITL can leave its physics to an external backend (``../shared/ardupilot/
JSON-interface.md``). Each physics frame it sends one UDP datagram to port ``9002 + 10 * instance``
of the backend: ``<HHI16H`` little-endian (magic 18458, the frame rate in Hz, a frame counter, 16
servo PWMs in µs; magic 29569 with 32 PWMs when SERVO_32_ENABLE is set). It then *waits* for the
reply (lock-step): one line of JSON sent back to the datagram's source, with the physics time, the
IMU (gyro and specific force, FRD body), position and velocity (NED, metres from its ``--home``)
and the attitude (roll, pitch, yaw of the FRD body in NED). The frame counter resets when SITL
restarts; a frame not answered within 10 s is sent again with the same counter.

Observed with the ArduCopter 4.7-dev build in ``../shared/ardupilot`` (``start_sitl.sh I 10
JSON:127.0.0.1``): 1200 frames per physics second by default (SIM_RATE_HZ); its parser looks for
``"key":`` with no space after the colon, so the reply must be compact JSON, or SITL logs "No JSON
sensor message received, resending servos" and never advances; a Python backend answering a
copter at rest keeps about 5x real time on one loaded core. SIM_RATE_HZ must be at least 1.8x the
loop rate (pre-arm "Gyro 0 rate 400Hz < loop ratex1.8 720Hz"): 400 frames/s needs SCHED_LOOP_RATE
200, ArduCopter's own 400 Hz loop needs 720.

This module is the format (:func:`parse_servo_packet`, :class:`SensorFrame`) and the lock-step
loop (:class:`JsonPhysicsServer`) with the physics passed in as a callable. Frames are converted
here only: :meth:`SensorFrame.from_enu` takes the simulator's ENU position and velocity.
"""

from __future__ import annotations

import logging
import math
import socket
import struct
from dataclasses import dataclass
from typing import Callable

import numpy as np

from chaser_bt.geo import enu_to_ned
from sitl.vehicle.airframe import GRAVITY

__all__ = ["JSON_PORT_BASE", "JsonPhysicsServer", "SensorFrame", "ServerCounters", "ServoPacket", "json_port",
           "parse_servo_packet", "resting_on_the_ground"]

log = logging.getLogger(__name__)

JSON_PORT_BASE = 9002  # ArduPilot sends to 9002 + 10 * instance
_MAGIC_16, _MAGIC_32 = 18458, 29569
_HEADER = struct.Struct("<HHI")
_REPLY = ('\n{"timestamp":%r,"imu":{"gyro":[%r,%r,%r],"accel_body":[%r,%r,%r]},"position":[%r,%r,%r],'
          '"velocity":[%r,%r,%r],"attitude":[%r,%r,%r]}\n')


def json_port(instance: int) -> int:
    """The UDP port SITL instance ``instance`` sends its servo frames to."""
    return JSON_PORT_BASE + 10 * int(instance)


@dataclass(frozen=True)
class ServoPacket:
    """One frame from ArduPilot: the step it asks for (1 / ``frame_rate_hz``), its counter, the PWMs."""

    frame_rate_hz: int
    frame_count: int
    pwm_us: tuple[int, ...]

    @property
    def dt_s(self) -> float:
        return 1.0 / self.frame_rate_hz


def parse_servo_packet(data: bytes) -> ServoPacket:
    """Decode a servo datagram (16 or 32 channels).

    Raises:
        ValueError: an unknown magic, a length that does not match it, or a frame rate of 0.
    """
    if len(data) < _HEADER.size:
        raise ValueError(f"servo packet of {len(data)} bytes is shorter than its {_HEADER.size}-byte header")
    magic, rate, count = _HEADER.unpack_from(data)
    channels = {_MAGIC_16: 16, _MAGIC_32: 32}.get(magic)
    if channels is None:
        raise ValueError(f"servo packet magic {magic}: expected {_MAGIC_16} (16 channels) or {_MAGIC_32} (32)")
    if len(data) != _HEADER.size + 2 * channels:
        raise ValueError(f"servo packet of {len(data)} bytes: {channels} channels need {_HEADER.size + 2 * channels}")
    if rate <= 0:
        raise ValueError("servo packet frame rate 0 Hz")
    return ServoPacket(rate, count, struct.unpack_from(f"<{channels}H", data, _HEADER.size))


@dataclass(frozen=True)
class SensorFrame:
    """The reply: what the vehicle's sensors feel, in ArduPilot's frames (NED earth, FRD body).

    Attributes:
        timestamp_s: absolute physics time (not the step).
        gyro_frd: body rates (rad/s).
        accel_frd: specific force (m/s², what an accelerometer reads: -g on z at rest).
        position_ned: metres from the SITL's home.
        velocity_ned: m/s.
        attitude_rpy: roll, pitch, yaw (rad) of the FRD body in NED.
    """

    timestamp_s: float
    gyro_frd: tuple[float, float, float]
    accel_frd: tuple[float, float, float]
    position_ned: tuple[float, float, float]
    velocity_ned: tuple[float, float, float]
    attitude_rpy: tuple[float, float, float]

    @classmethod
    def from_enu(cls, timestamp_s: float, position_enu, velocity_enu, attitude_rpy, gyro_frd, accel_frd) -> SensorFrame:
        """From the simulator's ENU position and velocity (attitude, gyro and accel already FRD/NED)."""
        return cls(float(timestamp_s), _triple(gyro_frd), _triple(accel_frd), _triple(enu_to_ned(position_enu)),
                   _triple(enu_to_ned(velocity_enu)), _triple(attitude_rpy))

    def encode(self) -> bytes:
        """The JSON line SITL parses: compact (no spaces), between newlines, every number finite."""
        values = tuple(map(float, (self.timestamp_s, *self.gyro_frd, *self.accel_frd, *self.position_ned,
                                   *self.velocity_ned, *self.attitude_rpy)))
        if not all(map(math.isfinite, values)):
            raise ValueError(f"sensor frame at t={self.timestamp_s}: every value must be finite")
        # Formatted by hand, not json.dumps: this is sent SIM_RATE_HZ times a simulated second and the
        # dict and encoder cost twice the formatting. A finite float's repr is its JSON.
        return (_REPLY % values).encode("ascii")


def _triple(v) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=float).ravel()
    if a.shape != (3,):
        raise ValueError(f"expected 3 values, got {a.shape[0]}")
    return float(a[0]), float(a[1]), float(a[2])


def resting_on_the_ground(t_s: float, heading_rad: float = 0.0) -> SensorFrame:
    """A vehicle standing still on the ground at home: the accelerometer reads 1 g up."""
    return SensorFrame(t_s, (0.0, 0.0, 0.0), (0.0, 0.0, -GRAVITY), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                       (0.0, 0.0, heading_rad))


@dataclass
class ServerCounters:
    """Frames answered, and the counter's irregularities (resends, losses, SITL restarts)."""

    frames: int = 0
    resent: int = 0  # same counter again: SITL waited 10 s for an answer
    lost: int = 0  # counters skipped
    restarts: int = 0  # the counter went back: SITL restarted
    bad_packets: int = 0


class JsonPhysicsServer:
    """Answers ArduPilot's servo frames in lock-step with ``physics(packet, t) -> SensorFrame``.

    ``t`` is the physics time after the step (the sum of the steps asked for since the counter
    last restarted), so the physics and ArduPilot share one clock. Binds loopback only.

    Args:
        instance: the SITL instance (port ``9002 + 10 * instance``).
        physics: steps the vehicle by ``packet.dt_s`` under ``packet.pwm_us``; returns what its
            sensors feel.
    """

    def __init__(self, instance: int, physics: Callable[[ServoPacket, float], SensorFrame], *,
                 host: str = "127.0.0.1") -> None:
        self.physics = physics
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, json_port(instance)))
        self.counters = ServerCounters()
        self.time_s = 0.0
        self._last_count: int | None = None
        self._last_reply: bytes | None = None

    def serve_one(self, timeout_s: float = 1.0) -> bool:
        """Answer one frame; False when none came within ``timeout_s``."""
        self.sock.settimeout(timeout_s)
        try:
            data, addr = self.sock.recvfrom(1024)
        except socket.timeout:
            return False
        try:
            packet = parse_servo_packet(data)
        except ValueError as e:
            self.counters.bad_packets += 1
            log.debug("dropped a servo packet: %s", e)
            return True
        last = self._last_count
        if last is not None and packet.frame_count == last and self._last_reply is not None:
            self.counters.resent += 1  # SITL did not get our answer: the same one again, no step
            self.sock.sendto(self._last_reply, addr)
            return True
        if last is not None and packet.frame_count < last:
            self.counters.restarts += 1
            self.time_s = 0.0
        elif last is not None and packet.frame_count > last + 1:
            self.counters.lost += packet.frame_count - last - 1
        self._last_count = packet.frame_count
        self.time_s += packet.dt_s
        self._last_reply = self.physics(packet, self.time_s).encode()
        self.sock.sendto(self._last_reply, addr)
        self.counters.frames += 1
        return True

    def close(self) -> None:
        self.sock.close()
