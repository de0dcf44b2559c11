"""The autopilot's safety settings, read at connect: each one off is named, with what to set."""

from __future__ import annotations

from chaser_bt.mission.preflight import SAFETY_SETTINGS, safety_warnings

# ArduCopter's defaults for these (Copter parameters.cpp, AP_BattMonitor_Params, AC_Fence):
ARDUCOPTER_DEFAULTS = {"FS_GCS_ENABLE": 0, "BATT_FS_LOW_ACT": 0, "BATT_LOW_VOLT": 0, "FENCE_ENABLE": 0, "RTL_ALT": 1500}
FIELD_READY = {"FS_GCS_ENABLE": 1, "BATT_FS_LOW_ACT": 2, "BATT_LOW_VOLT": 21.0, "FENCE_ENABLE": 1, "RTL_ALT": 3000}


def test_arducopters_defaults_leave_four_of_five_off():
    names = [w.split(" ")[0] for w in safety_warnings(ARDUCOPTER_DEFAULTS)]
    assert names == ["FS_GCS_ENABLE", "BATT_FS_LOW_ACT", "BATT_LOW_VOLT", "FENCE_ENABLE"]


def test_a_field_ready_vehicle_has_no_warning():
    assert safety_warnings(FIELD_READY) == []


def test_low_rtl_alt_and_unread_values_are_warned_about():
    params = dict(FIELD_READY, RTL_ALT=500)
    del params["FENCE_ENABLE"]
    warnings = safety_warnings(params)
    assert warnings[0].startswith("FENCE_ENABLE unread")
    assert warnings[1].startswith("RTL_ALT = 500: RTL_ALT under 15 m")
    assert safety_warnings(dict(FIELD_READY, RTL_ALT=0)) == []  # 0: return at the current altitude


def test_every_setting_is_one_the_simulator_and_arducopter_know():
    from sitl.vehicle.params import PARAM_SPECS

    known = {p.name for p in PARAM_SPECS}
    assert {s.name for s in SAFETY_SETTINGS} <= known


class _Vehicle:
    """A link to a vehicle that answers only the parameter names it has (``known``)."""

    def __init__(self, known: dict[str, float]) -> None:
        self.known, self.params, self.asked = known, {}, []

    def request_param(self, name: str):
        self.asked.append(name)
        if name in self.known:
            self.params[name] = self.known[name]
        return type("Cmd", (), {"done": name in self.known})()

    def wait(self, predicate, timeout_s):
        assert predicate(), "the read waits although every setting has its answer"


def test_a_renamed_setting_is_read_under_its_new_name_in_the_old_units():
    from chaser_bt.mission.preflight import read_safety_settings

    newer = dict(FIELD_READY)
    del newer["RTL_ALT"]
    newer["RTL_ALT_M"] = 30.0  # ArduCopter 4.7+: RTL_ALT moved to RTL_ALT_M, in metres
    vehicle = _Vehicle(newer)
    assert read_safety_settings(vehicle) == FIELD_READY and "RTL_ALT" in vehicle.asked


def test_the_fence_is_read_from_the_simulated_vehicle_and_cuts_the_envelope_down():
    """The built-in simulator answers PARAM_REQUEST_READ with its FENCE_* values (ArduCopter's
    defaults, the fence switched on here): the link's envelope becomes 300 - 2 m, 100 - 2 m."""
    from chaser_bt.geo import GeoPoint
    from chaser_bt.mission.preflight import read_fence
    from chaser_bt.vehicle.envelope import FENCE_PARAMS
    from sitl.bench.in_process import InProcessVehicle
    from sitl.world.scenario import BootParams, Scenario

    scenario = Scenario("fence", GeoPoint(42.5445, -71.6105, 80.0), boot=BootParams(1.0, 2.0, 3.0),
                        params={"FENCE_ENABLE": 1.0})
    v = InProcessVehicle(scenario, seed=1)
    assert v.run_until(lambda: v.link.frame is not None, 10)
    v.link.wait = lambda predicate, timeout_s: v.run_until(predicate, timeout_s)
    env = read_fence(v.link)
    assert all(name in v.link.params for name in FENCE_PARAMS)
    assert (env.max_distance_m, env.max_alt_m) == (298.0, 98.0)
