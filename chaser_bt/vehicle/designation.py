"""The operator's target designation over MAVLink: a ground station names the radar track to chase.

A ground station (Mission Planner, QGroundControl, a pymavlink script) sends a ``COMMAND_LONG`` or
``COMMAND_INT`` with command ``MAV_CMD_USER_1`` (31010) and the radar track id in ``param1``, to our
vehicle's system id and the component the link answers as (``MAV_COMP_ID_ONBOARD_COMPUTER``, 191, by
default). ArduPilot forwards it to the link's port once it has heard that component there, which is
why the link sends a HEARTBEAT as that component (docs/ground.md, "Designation over MAVLink").

A designation changes what the aircraft chases, so :func:`judge` believes one only when it is signed
with the link's key (MAVLink 2 signing, :mod:`chaser_bt.vehicle.signing`), unless
``allow_unsigned`` says otherwise for the bench. Unsigned and wrongly signed commands are dropped and
counted without an answer, as a signing ArduCopter drops them; a believed one is answered with
COMMAND_ACK: ACCEPTED, DENIED (a bad field, named in ``result_param2``, or one addressed to every
system) or UNSUPPORTED (another command addressed to our component). :class:`DesignationInbox`
keeps the accepted ones for the mission's ``GroundDesignation`` leaves.
"""

from __future__ import annotations

import enum
import logging
import math
import os
from collections import deque
from dataclasses import dataclass
from typing import Any

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from chaser_bt.vehicle.signing import SigningGate, Verdict  # noqa: E402

__all__ = [
    "DEFAULT_COMPID", "DESIGNATE_COMMAND", "MAX_TRACK_ID", "Auth", "DesignationCounters", "DesignationInbox",
    "Judgement", "MavlinkDesignation", "authenticity", "judge",
]

log = logging.getLogger(__name__)

DESIGNATE_COMMAND = mavlink2.MAV_CMD_USER_1  # 31010: user-defined, never acted on by ArduPilot
DEFAULT_COMPID = mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER  # 191
MAX_TRACK_ID = 2**24  # param1 is a float32: every integer up to 2^24 is exact
COMMAND_MESSAGES = frozenset({"COMMAND_LONG", "COMMAND_INT"})
_INT32_MAX = 2**31 - 1  # COMMAND_INT x/y: "not used"
_QUEUE = 32  # designations kept for the leaves at most (the newest)


class Auth(enum.Enum):
    """Whether a message is authenticated by the link's key."""

    SIGNED = "signed"  # good signature under the link's key, fresh timestamp
    UNSIGNED = "unsigned"  # no signature, or the link has no key to check one
    BAD_SIGNATURE = "bad_signature"  # another key, tampered, replayed or stale


def authenticity(msg: Any, gate: SigningGate | None) -> Auth:
    """How ``msg`` (decoded by a parser ``gate`` is attached to, if any) is authenticated."""
    if gate is None:
        return Auth.UNSIGNED
    verdict = gate.verdict(msg)
    if verdict is Verdict.SIGNED:
        return Auth.SIGNED
    return Auth.BAD_SIGNATURE if verdict is Verdict.BAD_SIGNATURE else Auth.UNSIGNED


@dataclass(frozen=True)
class Judgement:
    """What becomes of one command addressed to our component.

    ``outcome`` is ``accepted``, ``denied``, ``unsupported`` (answered), or ``unsigned``,
    ``bad_signature``, ``not_for_us`` (dropped, no answer); ``ack`` the MAV_RESULT to answer (None: no
    answer); ``bad_param`` the parameter (1-7) a DENIED names; ``reason`` says why in words.
    """

    outcome: str
    ack: int | None = None
    track_id: int | None = None
    bad_param: int = 0
    reason: str = ""


def _reserved(msg: Any) -> list[tuple[int, float]]:
    """The reserved parameters as (index, value): 2-7 (COMMAND_INT's x, y, z are 5, 6, 7)."""
    if msg.get_type() == "COMMAND_INT":
        x = 0.0 if msg.x == _INT32_MAX else float(msg.x)
        y = 0.0 if msg.y == _INT32_MAX else float(msg.y)
        return [(2, msg.param2), (3, msg.param3), (4, msg.param4), (5, x), (6, y), (7, msg.z)]
    return [(i, getattr(msg, f"param{i}")) for i in range(2, 8)]


def judge(msg: Any, *, sysid: int, compid: int, auth: Auth, allow_unsigned: bool = False) -> Judgement | None:
    """Judge a COMMAND_LONG/COMMAND_INT for component ``compid`` of vehicle ``sysid``; None: not ours.

    Commands for another component, and other commands sent to every system or component, are not
    ours. A designation for another vehicle is dropped (``not_for_us``). What is addressed to us is
    believed only when ``auth`` is SIGNED, or UNSIGNED with ``allow_unsigned``.
    """
    if msg.get_type() not in COMMAND_MESSAGES:
        return None
    to_sys, to_comp, command = msg.target_system, msg.target_component, msg.command
    if to_comp not in (0, compid):
        return None
    designation = command == DESIGNATE_COMMAND
    if to_sys not in (0, sysid):
        return Judgement("not_for_us", reason=f"for vehicle {to_sys}") if designation else None
    if not designation and (to_sys, to_comp) != (sysid, compid):
        return None  # a broadcast command: the autopilot's to answer
    if auth is Auth.BAD_SIGNATURE:
        return Judgement("bad_signature", reason="signature does not check out (another key, tampered or replayed)")
    if auth is Auth.UNSIGNED and not allow_unsigned:
        return Judgement("unsigned", reason="not signed with the link's key")
    if not designation:
        return Judgement("unsupported", mavlink2.MAV_RESULT_UNSUPPORTED, reason=f"command {command} unknown here")
    denied = mavlink2.MAV_RESULT_DENIED
    if to_sys == 0:
        return Judgement("denied", denied, reason=f"addressed to every system: address vehicle {sysid}")
    track = msg.param1
    if not (math.isfinite(track) and track == int(track) and 0 <= track <= MAX_TRACK_ID):
        return Judgement("denied", denied, bad_param=1,
                         reason=f"param1 {track!r}: expected a radar track id, an integer 0..{MAX_TRACK_ID}")
    for index, value in _reserved(msg):
        if value != 0 and not math.isnan(value):
            return Judgement("denied", denied, bad_param=index, reason=f"param{index} {value!r}: reserved, send 0")
    return Judgement("accepted", mavlink2.MAV_RESULT_ACCEPTED, track_id=int(track))


@dataclass(frozen=True)
class MavlinkDesignation:
    """One designation believed: the radar ``track_id``, who sent it, whether it was signed."""

    track_id: int
    sysid: int
    compid: int
    signed: bool


@dataclass
class DesignationCounters:
    """What became of every command addressed to our component."""

    accepted: int = 0
    denied: int = 0
    unsupported: int = 0
    unsigned: int = 0
    bad_signature: int = 0
    not_for_us: int = 0

    @property
    def dropped(self) -> int:
        """Not believed or not answered ACCEPTED."""
        return self.denied + self.unsupported + self.unsigned + self.bad_signature + self.not_for_us


class DesignationInbox:
    """The link's MAVLink designations: judges, counts and logs each command, keeps the accepted.

    Args:
        compid: the component the link answers as.
        allow_unsigned: believe unsigned designations too (bench use only; logged as a warning).
    """

    def __init__(self, compid: int = DEFAULT_COMPID, *, allow_unsigned: bool = False) -> None:
        self.compid = compid
        self.allow_unsigned = allow_unsigned
        self.counters = DesignationCounters()
        self._queued: deque[MavlinkDesignation] = deque(maxlen=_QUEUE)
        self._warned: set[str] = set()
        if allow_unsigned:
            log.warning("MAVLink designation: UNSIGNED designations are believed (bench use only): "
                        "anyone on the link can change the chase's target")

    def receive(self, msg: Any, *, sysid: int, auth: Auth) -> Judgement | None:
        """Judge ``msg`` for vehicle ``sysid`` (see :func:`judge`), count it, log it, keep it if accepted."""
        j = judge(msg, sysid=sysid, compid=self.compid, auth=auth, allow_unsigned=self.allow_unsigned)
        if j is None:
            return None
        setattr(self.counters, j.outcome, getattr(self.counters, j.outcome) + 1)
        sender = f"{msg.get_srcSystem()}/{msg.get_srcComponent()}"
        if j.outcome == "accepted":
            signed = auth is Auth.SIGNED
            self._queued.append(MavlinkDesignation(j.track_id, msg.get_srcSystem(), msg.get_srcComponent(), signed))
            if signed:
                log.info("MAVLink designation: track %d from %s (signed)", j.track_id, sender)
            else:
                log.warning("MAVLink designation: track %d from %s UNSIGNED, believed for the bench",
                            j.track_id, sender)
        elif j.outcome in ("unsigned", "bad_signature"):
            level = logging.DEBUG if j.outcome in self._warned else logging.WARNING
            self._warned.add(j.outcome)
            log.log(level, "MAVLink designation from %s dropped: %s (%d so far)", sender, j.reason,
                    getattr(self.counters, j.outcome))
        elif j.outcome == "not_for_us":
            log.debug("MAVLink designation from %s ignored: %s", sender, j.reason)
        else:
            log.warning("MAVLink command %d from %s answered %s: %s", msg.command, sender, j.outcome.upper(), j.reason)
        return j

    def take(self) -> list[MavlinkDesignation]:
        """The designations accepted since the last call, oldest first."""
        taken = list(self._queued)
        self._queued.clear()
        return taken

    def summary(self) -> str:
        """One line for a leaf's feedback."""
        c = self.counters
        bench = ", unsigned allowed" if self.allow_unsigned else ""
        return f"MAVLink: {c.accepted} designation(s), {c.dropped} dropped{bench}"
