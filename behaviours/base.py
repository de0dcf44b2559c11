"""What every flight behaviour shares: the vehicle link, the clock, the vehicle-state port, hover on exit.

Behaviours are py_trees leaves with typed ports (``py_trees.ports``). The runner hands them the
:class:`~chaser_bt.vehicle.VehicleLink` and the mission :class:`~chaser_bt.clock.Clock`
through ``setup(link=..., clock=...)`` and writes the vehicle state to ``/vehicle/state`` before
every tick; the ``state`` port reads it from there unless a tree wires it elsewhere.

:class:`CommandingBehaviour` adds DESIGN §3's rule: a behaviour that commands the aircraft never
leaves that command in force when it fails or is halted; it sends the hover command instead.
"""

from __future__ import annotations

import enum
import functools
from typing import Any, Callable

import py_trees
from pymavlink import mavutil

from chaser_bt.clock import Clock
from chaser_bt.control.progress import ClosingWatch, ProgressWatch
from chaser_bt.tree import input_port
from chaser_bt.vehicle import UnsafeCommand, VehicleLink, VehicleState

__all__ = ["CommandingBehaviour", "FlightMode", "VehicleBehaviour", "stall_message", "state_port"]

Status = py_trees.common.Status

#: ArduCopter's flight modes by name, as pymavlink maps them (so YAML says ``mode: RTL``).
FlightMode = enum.Enum("FlightMode", {name: name for name in mavutil.mode_mapping_acm.values()})


def state_port() -> Any:
    """The vehicle-state input port every flight behaviour declares."""
    return input_port(
        VehicleState,
        "Vehicle state from telemetry (the runner writes it before each tick)",
        default_key="/vehicle/state",
    )


class VehicleBehaviour(py_trees.ports.BehaviourWithPorts):
    """A leaf that reads the vehicle state and may talk to the vehicle link.

    Subclasses declare ``INPUT_PORTS`` (including ``"state": state_port()``) and
    ``OUTPUT_PORTS`` and implement ``update()``.
    """

    INPUT_PORTS: dict[str, Any]
    OUTPUT_PORTS: dict[str, Any]

    def __init__(self, name: str, **kwargs: Any) -> None:
        super().__init__(name=name, **kwargs)
        self.link: VehicleLink | None = None
        self.clock: Clock | None = None

    def setup(self, **kwargs: Any) -> None:
        """Take the link and clock the runner distributes; both are required to fly."""
        try:
            self.link = kwargs["link"]
            self.clock = kwargs["clock"]
        except KeyError as missing:
            raise KeyError(f"{self.name}: setup() needs {missing} (the mission runner passes it)") from None

    @property
    def state(self) -> VehicleState:
        """The vehicle state for this tick."""
        return self.get_input("state")

    def _link(self) -> VehicleLink:
        assert self.link is not None, f"{self.name}: setup() was not called"
        return self.link

    def _now(self) -> float:
        assert self.clock is not None, f"{self.name}: setup() was not called"
        return self.clock.now()


class CommandingBehaviour(VehicleBehaviour):
    """A leaf that sends set-points or mode commands: hover when it fails or is halted.

    A set-point the link refuses before sending (:class:`~chaser_bt.vehicle.UnsafeCommand`: outside
    the command envelope, not finite) fails the leaf with the reason, from ``initialise`` or
    ``update`` alike; the hover of its exit then holds the aircraft where it is.
    """

    #: Set False by leaves whose command is itself a safe end state (RTL, LAND).
    HOVER_ON_HALT = True

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "initialise" in cls.__dict__:
            cls.initialise = _noting_unsafe(cls.__dict__["initialise"])  # type: ignore[method-assign]
        if "update" in cls.__dict__:
            cls.update = _failing_on_unsafe(cls.__dict__["update"])  # type: ignore[method-assign]

    def terminate(self, new_status: Status) -> None:
        halted = new_status == Status.INVALID and self.status == Status.RUNNING
        if self.link is not None and (new_status == Status.FAILURE or (halted and self.HOVER_ON_HALT)):
            if self.link.hover():  # nothing is sent to a disarmed aircraft, or one its autopilot flies (RTL, LOITER ...)
                self.feedback_message = f"{self.feedback_message} (hover sent)".strip()


def _noting_unsafe(initialise: Callable[[Any], None]) -> Callable[[Any], None]:
    @functools.wraps(initialise)
    def guarded(self: Any) -> None:
        self._unsafe = None
        try:
            initialise(self)
        except UnsafeCommand as exc:
            self._unsafe = exc  # update() fails with it: initialise() has no status to return
    return guarded


def _failing_on_unsafe(update: Callable[[Any], Status]) -> Callable[[Any], Status]:
    @functools.wraps(update)
    def guarded(self: Any) -> Status:
        unsafe = getattr(self, "_unsafe", None)
        try:
            if unsafe is None:
                return update(self)
        except UnsafeCommand as exc:
            unsafe = exc
        self._unsafe = None
        self.feedback_message = f"command not sent: {unsafe}"
        return Status.FAILURE
    return guarded


def optional_input(node: py_trees.ports.PortsMixin, port: str) -> Any:
    """The port's value, or None while nothing has been written to its blackboard key yet."""
    try:
        return node.get_input(port)
    except Exception:  # nothing written to the key yet
        return None


_NOTICE = 5  # MAV_SEVERITY_NOTICE: the autopilot's warnings and worse, not its chatter ("Arming motors")


def stall_message(watch: ProgressWatch | ClosingWatch, now: float, distance_m: float, state: VehicleState) -> str:
    """Why a movement failed: how long without progress, how far to go, and what the autopilot said meanwhile."""
    since = watch.since_s(now)
    said = [text for t, severity, text in state.statustexts if t >= state.t_boot_s - since and severity <= _NOTICE]
    if said:
        why = f"the autopilot said: {said[-1]}"
    elif state.fence_enabled:
        why = "the autopilot's fence is on: GUIDED refuses a target outside it"
    else:
        why = "the autopilot is not flying the target (wind? a lost command?)"
    return f"no progress for {since:.0f} s with {distance_m:.0f} m to go: {why}"


def send_speed_after_target(link: VehicleLink, speed_mps: float) -> bool:
    """Ask for ``speed_mps`` of horizontal speed (0: keep the vehicle's WPNAV_SPEED); True once asked.

    Call it right after a position target, never before the leg's first: ArduCopter's GUIDED sets the
    speed back to WPNAV_SPEED when it enters position control from velocity control or the take-off
    (mode_guided.cpp, ``pva_control_start``), so a DO_CHANGE_SPEED sent first is lost.
    """
    if speed_mps > 0:
        link.set_speed(speed_mps)
        return True
    return False
