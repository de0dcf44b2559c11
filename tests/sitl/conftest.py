"""Fixtures for the simulator tests: autopilots on a calm field with a fast boot."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from chaser_bt.geo import GeoPoint
from sitl.vehicle.airframe import AirframeParams
from sitl.vehicle.autopilot import Autopilot
from sitl.vehicle.physics import WindParams
from sitl.world.scenario import BootParams, Fault, Scenario

FIELD = GeoPoint(42.5445, -71.6105, 80.0)
FAST_BOOT = BootParams(gps_fix_s=1.0, ekf_ready_s=2.0, prearm_ok_s=3.0)
DT = 0.02


def _run_for(ap: Autopilot, seconds: float, each: Callable[[Autopilot], None] | None = None) -> None:
    """Step ``ap`` for ``seconds`` at 50 Hz, calling ``each(ap)`` before every step."""
    for _ in range(int(round(seconds / DT))):
        if each is not None:
            each(ap)
        ap.step(DT)


@pytest.fixture
def run_for() -> Callable[..., None]:
    """``run_for(ap, seconds, each=None)``: advance an autopilot."""
    return _run_for


@pytest.fixture
def make_ap() -> Callable[..., Autopilot]:
    """Factory: an autopilot on the calm test field (keyword overrides for the scenario)."""

    def make(params: dict[str, float] | None = None, wind: WindParams | None = None,
             boot: BootParams = FAST_BOOT, faults: tuple[Fault, ...] = (), seed: int = 0,
             heading_deg: float = 0.0, airframe: AirframeParams | None = None) -> Autopilot:
        sc = Scenario(name="test", home=FIELD, home_heading_deg=heading_deg,
                      wind=wind or WindParams(), params=params or {}, boot=boot, faults=faults,
                      airframe=airframe or AirframeParams())
        return Autopilot(sc, np.random.default_rng(seed))

    return make


@pytest.fixture
def airborne(make_ap: Callable[..., Autopilot]) -> Callable[..., Autopilot]:
    """Factory: booted, armed in GUIDED and hovering ``alt`` m above home (default 20)."""

    def make(alt: float = 20.0, **kw) -> Autopilot:
        ap = make_ap(**kw)
        _run_for(ap, 4.0)
        assert ap.request_mode(4).accepted
        assert ap.request_arm(True).accepted
        assert ap.request_takeoff(alt).accepted
        _run_for(ap, alt / 2.5 + 8.0)
        assert abs(ap.truth.pos_enu[2] - alt) < 0.5
        ap.pop_statustexts()
        return ap

    return make
