"""Fixtures for the vehicle-link tests (the doubles themselves live in vehicle_fakes.py)."""

from __future__ import annotations

import pytest
from vehicle_fakes import Rig, make_rig


@pytest.fixture
def rig() -> Rig:
    """A link that has heard the fake ArduCopter (ready to arm, STABILIZE, home known)."""
    r = make_rig()
    r.run(1.2)
    return r
