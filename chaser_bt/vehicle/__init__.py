"""The vehicle: MAVLink link to an ArduCopter (telemetry -> state, commands, modes).

``MAVLINK20`` is set here, before any submodule imports pymavlink (DESIGN §3).
"""

import os

os.environ["MAVLINK20"] = "1"

from chaser_bt.vehicle.commands import Command, CommandStatus, Setpoint  # noqa: E402
from chaser_bt.vehicle.envelope import CommandEnvelope, UnsafeCommand  # noqa: E402
from chaser_bt.vehicle.errors import (  # noqa: E402
    CommandRejected,
    LinkTimeout,
    VehicleError,
    VehicleQuiet,
    VehicleUnreachable,
)
from chaser_bt.vehicle.link import COPTER_MODES, DEFAULT_STREAM_RATES_HZ, LinkConfig, LinkCounters, VehicleLink  # noqa: E402
from chaser_bt.vehicle.pipe import PipeEnd, byte_pipe  # noqa: E402
from chaser_bt.vehicle.state import LandedState, VehicleState  # noqa: E402

__all__ = [
    "COPTER_MODES",
    "Command",
    "CommandEnvelope",
    "CommandRejected",
    "CommandStatus",
    "DEFAULT_STREAM_RATES_HZ",
    "LandedState",
    "LinkConfig",
    "LinkCounters",
    "LinkTimeout",
    "PipeEnd",
    "Setpoint",
    "UnsafeCommand",
    "VehicleError",
    "VehicleLink",
    "VehicleQuiet",
    "VehicleState",
    "VehicleUnreachable",
    "byte_pipe",
]
