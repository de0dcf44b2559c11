"""The scripted safety pilot (autonomy switch on an RC channel) and the operator's ground station."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from sitl.vehicle.autopilot import Autopilot
from sitl.vehicle.modes import make_modes
from sitl.world.scenario import (
    GCS_MODES,
    GroundStationEvent,
    PilotEvent,
    PilotScript,
    Scenario,
    ScenarioError,
)

HOME = {"lat_deg": 42.5445, "lon_deg": -71.6105, "alt_m": 80.0}
FAST_BOOT = {"gps_fix_s": 1.0, "ekf_ready_s": 2.0, "prearm_ok_s": 3.0}


def _scenario(**extra) -> Scenario:
    return Scenario.from_dict({"name": "pilot", "home": HOME, "boot": FAST_BOOT, **extra}, source="pilot.yaml")


def _run(ap: Autopilot, seconds: float) -> None:
    for _ in range(int(round(seconds / 0.02))):
        ap.step(0.02)


def test_pilot_section_is_read_with_defaults_and_events_in_order():
    sc = _scenario(pilot={"gate_channel": 8, "gate": "off", "events": [{"at_s": 10, "gate": "on"},
                                                                      {"at_s": 20, "gate": False}]})
    assert sc.pilot == PilotScript(8, False, 1900, 1100, (PilotEvent(10.0, True), PilotEvent(20.0, False)))
    assert _scenario(pilot={}).pilot == PilotScript()  # channel 7, on, 1900/1100
    assert _scenario().pilot is None and _scenario().ground_station == ()


@pytest.mark.parametrize("pilot, where", [
    ({"gate_channel": 3}, "pilot.gate_channel"),  # a stick channel
    ({"gate": "maybe"}, "pilot.gate"),
    ({"on_pwm": 1700}, "pilot.on_pwm/off_pwm"),  # not above ArduPilot's 1800 high threshold
    ({"events": [{"at_s": 5, "gate": "off"}, {"at_s": 4, "gate": "on"}]}, "pilot.events[1].at_s"),
    ({"events": [{"at_s": 5, "gate": "off", "pwm": 1000}]}, "pilot.events[0].pwm"),
    ({"colour": "red"}, "pilot.colour"),
])
def test_bad_pilot_sections_name_the_key(pilot, where):
    with pytest.raises(ScenarioError, match=re.escape(f"pilot.yaml: {where}:")):
        _scenario(pilot=pilot)


def test_bad_ground_station_mode_is_refused_with_its_path():
    with pytest.raises(ScenarioError, match=r"ground_station\[0\]\.mode: expected one of STABILIZE"):
        _scenario(ground_station=[{"at_s": 1, "mode": "AUTO"}])


def test_ground_station_modes_are_the_simulated_autopilots():
    assert {m.name: n for n, m in make_modes().items()} == GCS_MODES


def test_gate_channel_follows_the_script_and_other_channels_stay_idle():
    sc = _scenario(pilot={"gate_channel": 7, "events": [{"at_s": 2.0, "gate": "off"}, {"at_s": 4.0, "gate": "on"}]})
    ap = Autopilot(sc, np.random.default_rng(0))
    seen = []
    for _ in range(300):  # 6 s
        ap.step(0.02)
        seen.append((round(ap.time_s, 2), ap.rc_channels()[6]))
    assert {pwm for t, pwm in seen if t < 2.0} == {1900}
    assert {pwm for t, pwm in seen if 2.0 <= t < 4.0} == {1100}
    assert {pwm for t, pwm in seen if t >= 4.0} == {1900}
    assert ap.rc_channels()[:6] == (1500,) * 6  # the pilot holds every stick centred, throttle too
    assert ap.rc_channels()[7] == 1500


def test_an_rc_override_of_the_gate_channel_still_wins_while_fresh():
    ap = Autopilot(_scenario(pilot={}), np.random.default_rng(0))
    ap.rc_override([65535] * 6 + [1000, 65535])
    assert ap.rc_channels()[6] == 1000
    _run(ap, 3.5)  # RC_OVERRIDE_TIME 3 s: back to the pilot's switch
    assert ap.rc_channels()[6] == 1900


def test_without_a_pilot_the_gate_channel_is_mid_switch_and_the_throttle_low():
    ap = Autopilot(_scenario(), np.random.default_rng(0))
    assert ap.rc_channels()[2] == 1000 and ap.rc_channels()[6] == 1500


def test_ground_station_changes_the_mode_at_its_time():
    sc = _scenario(ground_station=[{"at_s": 8.0, "mode": "LOITER"}])
    ap = Autopilot(sc, np.random.default_rng(0))
    _run(ap, 4.0)
    assert ap.request_mode(4).accepted and ap.request_arm(True).accepted and ap.request_takeoff(10.0).accepted
    _run(ap, 3.9)
    assert ap.mode == "GUIDED"
    _run(ap, 0.2)
    assert ap.mode == "LOITER"


def test_a_refused_ground_station_mode_is_reported_not_forced():
    # GUIDED while armed before the EKF has a position: ArduCopter refuses, and says so. (Disarmed
    # it would accept it: Copter::set_mode skips the checks then, so the vehicle is armed first, in
    # STABILIZE with ARMING_CHECK 0, which needs no position.)
    sc = dataclasses.replace(_scenario(params={"ARMING_CHECK": 0}),
                             ground_station=(GroundStationEvent(0.5, "GUIDED"),))
    ap = Autopilot(sc, np.random.default_rng(0))
    assert ap.request_arm(True).accepted and not ap.ekf_ok
    _run(ap, 1.0)
    assert ap.mode == "STABILIZE"
    assert any("ground station: GUIDED refused" in text for _, text in ap.pop_statustexts())
