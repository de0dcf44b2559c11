"""Errors raised by the vehicle link.

A mission catches :class:`VehicleError` to trigger its safety path; the subclasses say what went
wrong in the field's terms: never reached, reached but gone quiet, or refused a command.
"""

from __future__ import annotations

__all__ = ["VehicleError", "VehicleUnreachable", "VehicleQuiet", "CommandRejected", "LinkTimeout"]


class VehicleError(Exception):
    """Base class of everything the vehicle link raises."""


class VehicleUnreachable(VehicleError):
    """No autopilot answered on the connection (bad address, nobody listening, no heartbeat)."""


class VehicleQuiet(VehicleError):
    """The autopilot was heard before but nothing has arrived for longer than the quiet timeout."""


class CommandRejected(VehicleError):
    """A command finished without being accepted (refused by the autopilot, or never answered)."""


class LinkTimeout(VehicleError, TimeoutError):
    """:meth:`VehicleLink.wait` ran out of time before its command finished or its condition held."""
