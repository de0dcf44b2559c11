"""Conditions read the vehicle state the runner publishes; checked on the ground and in the air."""

from __future__ import annotations

import py_trees
import pytest

from flight_helpers import fly, take_off

Status = py_trees.common.Status


def check(vehicle, body: str) -> Status:
    status, _ = fly(vehicle, body, timeout_s=2)
    return status


@pytest.fixture
def on_ground(vehicle):
    assert vehicle.run_until(lambda: vehicle.link.state.mode != "", 10)
    return vehicle


def test_on_the_ground_nothing_is_armed_or_airborne(on_ground):
    assert check(on_ground, "Armed") == Status.FAILURE
    assert check(on_ground, "Airborne") == Status.FAILURE
    assert check(on_ground, "ModeIs: {mode: GUIDED}") == Status.FAILURE
    assert check(on_ground, f"ModeIs: {{mode: {on_ground.sim.autopilot.mode}}}") == Status.SUCCESS


def test_in_the_air_armed_airborne_guided(vehicle):
    take_off(vehicle, 10)
    assert check(vehicle, "Armed") == Status.SUCCESS
    assert check(vehicle, "Airborne") == Status.SUCCESS
    assert check(vehicle, "ModeIs: {mode: GUIDED}") == Status.SUCCESS
    assert check(vehicle, "ModeIs: {mode: RTL}") == Status.FAILURE


def test_battery_above_compares_with_reported_remaining(vehicle):
    # The climb draws the pack below full (99 %), so a percentage above the level exists (0..100).
    take_off(vehicle, 10)
    level = vehicle.link.state.battery_remaining_pct
    assert 0 < level < 100
    assert check(vehicle, f"BatteryAbove: {{percent: {level - 5:.1f}}}") == Status.SUCCESS
    assert check(vehicle, f"BatteryAbove: {{percent: {level:.1f}}}") == Status.SUCCESS  # "at least"
    assert check(vehicle, "BatteryAbove: {percent: 100}") == Status.FAILURE
