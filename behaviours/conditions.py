"""Conditions on the vehicle state: SUCCESS when true, FAILURE when false, never RUNNING."""

from __future__ import annotations

import abc
import math

import py_trees

from behaviours.base import FlightMode, VehicleBehaviour, state_port
from chaser_bt.tree import NodeKind, input_port, register_behaviour
from chaser_bt.vehicle import VehicleState

Status = py_trees.common.Status


class _Condition(VehicleBehaviour):
    """A check of the vehicle state; subclasses implement :meth:`check` -> (holds, why)."""

    NODE_KIND = NodeKind.CONDITION

    @abc.abstractmethod
    def check(self, state: VehicleState) -> tuple[bool, str]:
        """Whether the condition holds, and a short reason for the feedback message."""

    def update(self) -> Status:
        holds, self.feedback_message = self.check(self.state)
        return Status.SUCCESS if holds else Status.FAILURE


@register_behaviour
class Airborne(_Condition):
    """The vehicle is armed and flying (taking off, in the air or landing)."""

    INPUT_PORTS = {"state": state_port()}
    OUTPUT_PORTS: dict = {}

    def check(self, state: VehicleState) -> tuple[bool, str]:
        return state.airborne, f"{state.landed_state.name.lower()}, {state.alt_rel_m:.1f} m"


@register_behaviour
class Armed(_Condition):
    """The motors are armed."""

    INPUT_PORTS = {"state": state_port()}
    OUTPUT_PORTS: dict = {}

    def check(self, state: VehicleState) -> tuple[bool, str]:
        return state.armed, "armed" if state.armed else "disarmed"


@register_behaviour
class ModeIs(_Condition):
    """The autopilot reports ``mode`` (an ArduCopter mode name such as GUIDED or RTL)."""

    INPUT_PORTS = {"mode": input_port(FlightMode, "ArduCopter mode name"), "state": state_port()}
    OUTPUT_PORTS: dict = {}

    def check(self, state: VehicleState) -> tuple[bool, str]:
        return state.mode == self.get_input("mode").name, f"mode {state.mode or 'unknown'}"


@register_behaviour
class BatteryAbove(_Condition):
    """Battery remaining is at least ``percent`` and the autopilot's own battery failsafe has not fired
    (it fires on voltage, which the percentage can hide); an unknown level counts as false (fail safe)."""

    INPUT_PORTS = {
        "percent": input_port(float, "Minimum remaining capacity (%)", minimum=0, maximum=100),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def check(self, state: VehicleState) -> tuple[bool, str]:
        level = state.battery_remaining_pct
        if state.battery_failsafe:
            return False, f"the autopilot's battery failsafe ({level:.0f}% left)"
        if math.isnan(level):
            return False, "battery level unknown"
        return level >= self.get_input("percent"), f"battery {level:.0f}%"
