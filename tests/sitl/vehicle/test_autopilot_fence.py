"""The simulated ArduCopter's geofence: presence from FENCE_TYPE, breaches, and FENCE_ACTION.

References: ArduPilot's AC_Fence (present(): circle or altitude fence configured, or a polygon
with points; nothing checked while FENCE_ENABLE is 0; AC_FENCE_GIVE_UP_DISTANCE 100 m) and
ArduCopter's fence.cpp (a new breach while armed: "Fence Breached" and, for FENCE_ACTION 1, RTL,
or LAND when RTL is impossible or the vehicle is more than 100 m outside).
"""

from __future__ import annotations

import pytest

from sitl.vehicle.fence import (
    FENCE_ALT_MAX,
    FENCE_CIRCLE,
    fence_breaches,
    fence_enabled,
    fence_present,
)
from sitl.vehicle.params import ParamStore

RTL, LAND = 6, 9


def _p(**kw: float) -> dict[str, float]:
    return ParamStore(kw).values


def test_arducopter_defaults_configure_a_fence_that_is_off():
    p = _p()  # FENCE_TYPE 7 (max altitude, circle, polygon), FENCE_ENABLE 0
    assert fence_present(p) and not fence_enabled(p)
    assert fence_breaches(p, 1e6, 1e6) == 0  # disabled: nothing is checked


@pytest.mark.parametrize(("kinds", "points", "present"), [
    (0, 0, False), (4, 0, False), (4, 3, True), (2, 0, True), (1, 0, True), (8, 0, True),
])
def test_presence_follows_fence_type_and_polygon_points(kinds, points, present):
    assert fence_present(_p(FENCE_TYPE=kinds), points) is present


def test_circle_and_altitude_breaches():
    p = _p(FENCE_ENABLE=1, FENCE_RADIUS=50, FENCE_ALT_MAX=30)
    assert fence_breaches(p, 49.9, 29.9) == 0
    assert fence_breaches(p, 50.0, 10.0) == FENCE_CIRCLE
    assert fence_breaches(p, 0.0, 30.5) == FENCE_ALT_MAX
    assert fence_breaches(p, 60.0, 31.0) == FENCE_CIRCLE | FENCE_ALT_MAX


def _push(ap, run_for, velocity_enu, seconds: float) -> None:
    """Fly a GUIDED velocity, re-sent every half second while in GUIDED (GUIDED refuses positions outside the fence)."""
    for _ in range(int(seconds / 0.5)):
        if ap.mode != "GUIDED":
            break
        assert ap.set_velocity_target(velocity_enu)
        run_for(ap, 0.5)


def test_guided_refuses_a_target_outside_the_fence_and_keeps_the_old_one(airborne, run_for):
    # ModeGuided::set_destination -> AC_Fence::check_destination_within_fence
    ap = airborne(10.0, params={"FENCE_ENABLE": 1, "FENCE_RADIUS": 20, "FENCE_ALT_MAX": 30})
    hx, hy, hz = ap.home_enu
    assert ap.set_position_target([hx + 15.0, hy, hz + 10.0])  # inside
    assert not ap.set_position_target([hx + 40.0, hy, hz + 10.0])  # beyond the circle
    assert not ap.set_position_target([hx, hy, hz + 35.0])  # above the ceiling
    run_for(ap, 15.0)
    assert ap.fence_breaches == 0 and ap.mode == "GUIDED"
    assert abs(ap.truth.pos_enu[0] - (hx + 15.0)) < 2.0  # flew the accepted target and held it


def test_a_circle_breach_sends_the_vehicle_home_in_rtl(airborne, run_for):
    ap = airborne(10.0, params={"FENCE_ENABLE": 1, "FENCE_RADIUS": 20})
    _push(ap, run_for, [6.0, 0.0, 0.0], 6.0)
    run_for(ap, 9.0)
    assert ap.mode_number == RTL
    assert (5, "Fence Breached") in ap.pop_statustexts()
    assert ap.fence_breaches & FENCE_CIRCLE or ap.truth.pos_enu[0] < 20.0  # on its way back


def test_report_only_announces_the_breach_and_keeps_the_mode(airborne, run_for):
    ap = airborne(10.0, params={"FENCE_ENABLE": 1, "FENCE_ALT_MAX": 12, "FENCE_ACTION": 0})
    _push(ap, run_for, [0.0, 0.0, 2.0], 3.0)
    run_for(ap, 3.0)
    assert ap.fence_breaches == FENCE_ALT_MAX
    assert ap.mode == "GUIDED"
    assert (5, "Fence Breached") in ap.pop_statustexts()


def test_far_outside_the_fence_the_vehicle_lands_instead(airborne, run_for):
    # the ceiling lowered to -100 m under a vehicle at 10 m: 110 m outside, beyond the give-up distance
    ap = airborne(10.0, params={"FENCE_ENABLE": 1, "FENCE_RADIUS": 1000})
    ap.params.set("FENCE_ALT_MAX", -100.0)
    run_for(ap, 0.5)
    assert ap.mode_number == LAND


def test_disarmed_a_breach_is_recorded_but_nothing_is_done(make_ap, run_for):
    ap = make_ap(params={"FENCE_ENABLE": 1, "FENCE_ALT_MAX": -1})
    run_for(ap, 4.0)
    assert ap.fence_breaches == FENCE_ALT_MAX
    assert ap.mode == "STABILIZE" and not ap.armed
    assert all(text != "Fence Breached" for _, text in ap.pop_statustexts())
