"""When each telemetry message is due: ArduPilot's stream groups and per-message intervals, on sim time.

ArduPilot sends telemetry in *streams* (``SRn_POSITION``, ``SRn_EXTRA1`` ...), each a group of
messages at one rate, and lets a client override any single message with
``MAV_CMD_SET_MESSAGE_INTERVAL`` (GCS_MAVLINK_Parameters.cpp, GCS_Common.cpp). This module keeps
both: a stream rate per group, and an optional interval per message that wins over its group.

Default rates: ArduCopter's firmware default for every ``SRn_*`` is 0 Hz, but nobody sees that in
practice, because MAVProxy (which ``sim_vehicle.py`` starts with every SITL) immediately asks for all
streams at 4 Hz with REQUEST_DATA_STREAM. A stock client that asks for nothing should still see a
live vehicle, so the defaults here are what ArduCopter SITL with MAVProxy sends: every stream at
4 Hz, HEARTBEAT at 1 Hz. Messages that ArduPilot only sends on request or on change
(ATTITUDE_QUATERNION, HOME_POSITION, AUTOPILOT_VERSION) start disabled.

Scheduling is on simulated seconds, so rates are the same at 1x and 100x real time.
"""

from __future__ import annotations

import math
import os

os.environ["MAVLINK20"] = "1"

from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

__all__ = ["STREAM_GROUPS", "DEFAULT_STREAM_RATE_HZ", "StreamScheduler"]

# MAV_DATA_STREAM id -> the message ids ArduCopter sends in it (only those this simulator produces).
STREAM_GROUPS: dict[int, tuple[int, ...]] = {
    mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS: (
        mavlink2.MAVLINK_MSG_ID_SYS_STATUS,
        mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT,
        mavlink2.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    ),
    mavlink2.MAV_DATA_STREAM_POSITION: (
        mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    ),
    mavlink2.MAV_DATA_STREAM_RC_CHANNELS: (mavlink2.MAVLINK_MSG_ID_RC_CHANNELS,),
    mavlink2.MAV_DATA_STREAM_EXTRA1: (mavlink2.MAVLINK_MSG_ID_ATTITUDE,),
    mavlink2.MAV_DATA_STREAM_EXTRA2: (mavlink2.MAVLINK_MSG_ID_VFR_HUD,),
    mavlink2.MAV_DATA_STREAM_EXTRA3: (
        mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME,
        mavlink2.MAVLINK_MSG_ID_EKF_STATUS_REPORT,
        mavlink2.MAVLINK_MSG_ID_BATTERY_STATUS,
    ),
}

DEFAULT_STREAM_RATE_HZ = 4.0
HEARTBEAT_INTERVAL_S = 1.0
_EPS_S = 1e-6  # sim time is a float sum of steps: a message due "now" must not slip a step

# Sent only when asked for (MAV_CMD_SET_MESSAGE_INTERVAL / REQUEST_MESSAGE) or on change.
ON_REQUEST_ONLY: tuple[int, ...] = (
    mavlink2.MAVLINK_MSG_ID_ATTITUDE_QUATERNION,
    mavlink2.MAVLINK_MSG_ID_HOME_POSITION,
    mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
)


class StreamScheduler:
    """Per-message send intervals in sim seconds; :meth:`due` says which are due at time ``t``.

    A message's interval is its own override if set (``set_interval``), else its stream group's rate.
    ``None`` means "not sent". Phase is kept (next due = last due + interval) so long-run rates are
    exact even when the physics step does not divide the interval.
    """

    def __init__(self) -> None:
        self._group_of: dict[int, int] = {}
        for stream_id, ids in STREAM_GROUPS.items():
            for msg_id in ids:
                self._group_of[msg_id] = stream_id
        self._stream_rate_hz: dict[int, float] = {s: DEFAULT_STREAM_RATE_HZ for s in STREAM_GROUPS}
        self._override_s: dict[int, float | None] = {}
        self._interval_s: dict[int, float | None] = {}
        self._next_due: dict[int, float] = {}
        self._earliest = math.inf
        for msg_id in self.known_ids():
            self._refresh(msg_id, now=0.0)

    @staticmethod
    def known_ids() -> tuple[int, ...]:
        """Every message id this scheduler can send."""
        grouped = tuple(i for ids in STREAM_GROUPS.values() for i in ids)
        return (mavlink2.MAVLINK_MSG_ID_HEARTBEAT, *grouped, *ON_REQUEST_ONLY)

    def default_interval(self, msg_id: int) -> float | None:
        """The interval ``msg_id`` has without a per-message override (its stream's rate)."""
        if msg_id == mavlink2.MAVLINK_MSG_ID_HEARTBEAT:
            return HEARTBEAT_INTERVAL_S
        stream = self._group_of.get(msg_id)
        if stream is None:
            return None
        rate = self._stream_rate_hz[stream]
        return 1.0 / rate if rate > 0.0 else None

    def interval(self, msg_id: int) -> float | None:
        """Current interval of ``msg_id`` in seconds, ``None`` when it is not sent."""
        return self._interval_s.get(msg_id)

    def set_interval(self, msg_id: int, interval_s: float | None, now: float) -> None:
        """Override one message: ``interval_s`` seconds, or ``None`` to stop it."""
        self._override_s[msg_id] = interval_s
        self._refresh(msg_id, now)

    def reset_interval(self, msg_id: int, now: float) -> None:
        """Drop the override of ``msg_id``: back to its stream's rate."""
        self._override_s.pop(msg_id, None)
        self._refresh(msg_id, now)

    def set_stream_rate(self, stream_id: int, rate_hz: float, now: float) -> None:
        """REQUEST_DATA_STREAM: set one group's rate (``MAV_DATA_STREAM_ALL`` = every group)."""
        streams = list(STREAM_GROUPS) if stream_id == mavlink2.MAV_DATA_STREAM_ALL else [stream_id]
        for stream in streams:
            if stream not in STREAM_GROUPS:
                continue
            self._stream_rate_hz[stream] = max(0.0, float(rate_hz))
            for msg_id in STREAM_GROUPS[stream]:
                self._refresh(msg_id, now)

    def due(self, now: float) -> list[int]:
        """Message ids due at ``now``, in a fixed order; advances their next due time."""
        now += _EPS_S
        if now < self._earliest:
            return []
        out = []
        earliest = math.inf
        for msg_id, t_due in self._next_due.items():
            if now >= t_due:
                out.append(msg_id)
                step = self._interval_s[msg_id]
                t_due += step
                if t_due <= now:  # fell behind (interval shorter than a physics step): no bursts
                    t_due = now + step
                self._next_due[msg_id] = t_due
            earliest = min(earliest, t_due)
        self._earliest = earliest
        return out

    def _refresh(self, msg_id: int, now: float) -> None:
        if msg_id in self._override_s:
            interval = self._override_s[msg_id]
        else:
            interval = self.default_interval(msg_id)
        self._interval_s[msg_id] = interval
        if interval is None:
            self._next_due.pop(msg_id, None)
        else:
            self._next_due[msg_id] = now
        self._earliest = min(self._next_due.values(), default=math.inf)
