"""Fixtures: each behaviour is flown against the simulator inside a tiny tree built around it."""

from __future__ import annotations

from pathlib import Path

import pytest

from sitl.bench.in_process import InProcessVehicle
from sitl.world.scenario import load_scenario

SCENARIO = Path(__file__).resolve().parents[2] / "sitl" / "scenarios" / "patrol.yaml"


@pytest.fixture(scope="session")
def scenario():
    return load_scenario(SCENARIO)


@pytest.fixture
def vehicle(scenario) -> InProcessVehicle:
    return InProcessVehicle(scenario, seed=7)
