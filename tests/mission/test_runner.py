"""The mission runner against the simulator: tick rate on vehicle time, state wiring, clean stops."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import py_trees
import pytest

from chaser_bt.mission.runner import VEHICLE_STATE_KEY, MissionRunner, RunStatus
from chaser_bt.tree import Registry, default_registry, input_port, load_tree_text
from chaser_bt.vehicle import VehicleState
from sitl.bench.in_process import InProcessVehicle
from sitl.world.scenario import load_scenario

Status = py_trees.common.Status
SCENARIO = Path(__file__).resolve().parents[2] / "sitl" / "scenarios" / "patrol.yaml"


class Spin(py_trees.ports.BehaviourWithPorts):
    """RUNNING forever; remembers its ticks and how it was terminated."""

    INPUT_PORTS: dict = {}
    OUTPUT_PORTS: dict = {}
    ticks = 0
    terminated: list = []

    def update(self):
        Spin.ticks += 1
        return Status.RUNNING

    def terminate(self, new_status):
        Spin.terminated.append(new_status)


class Boom(py_trees.ports.BehaviourWithPorts):
    """Raises on its first tick, like a leaf with a bug."""

    INPUT_PORTS: dict = {}
    OUTPUT_PORTS: dict = {}

    def update(self):
        raise RuntimeError("leaf bug")


class SeesState(py_trees.ports.BehaviourWithPorts):
    """SUCCESS when the state port holds a VehicleState with a vehicle time."""

    INPUT_PORTS = {"state": input_port(VehicleState, "vehicle state", default_key=VEHICLE_STATE_KEY)}
    OUTPUT_PORTS: dict = {}

    def update(self):
        state = self.get_input("state")
        return Status.SUCCESS if state.t_boot_s > 0 else Status.FAILURE


@pytest.fixture
def registry() -> Registry:
    reg = default_registry().copy()
    for cls in (Spin, Boom, SeesState):
        reg.register(cls)
    Spin.ticks, Spin.terminated = 0, []
    return reg


@pytest.fixture
def vehicle() -> InProcessVehicle:
    v = InProcessVehicle(load_scenario(SCENARIO), seed=11)
    assert v.run_until(lambda: v.link.state.t_boot_s > 1.0, 10)
    return v


def runner(vehicle, registry, root: str, rate_hz: float = 10.0) -> MissionRunner:
    tree = load_tree_text(f"version: 1\ntrees:\n  T:\n    {root}\n", source="<test>", registry=registry)
    return MissionRunner(tree, vehicle.link, vehicle.clock, rate_hz=rate_hz)


def test_ticks_at_the_configured_rate_in_vehicle_time(vehicle, registry):
    r = runner(vehicle, registry, "Spin", rate_hz=5.0)
    start = vehicle.sim.time_s
    vehicle.run_until(lambda: (r.tick_if_due(), False)[1], 10.0)
    assert vehicle.sim.time_s - start == pytest.approx(10.0, abs=0.05)
    assert Spin.ticks in (50, 51)  # 5 Hz for 10 s of vehicle time, whatever the wall clock did


def test_vehicle_state_reaches_leaves_through_the_blackboard(vehicle, registry):
    r = runner(vehicle, registry, "SeesState")
    assert vehicle.fly(r, 2.0) == Status.SUCCESS
    assert py_trees.blackboard.Blackboard.get(VEHICLE_STATE_KEY) is vehicle.link.state


def test_run_returns_success_when_the_root_succeeds(vehicle, registry):
    result = runner(vehicle, registry, "AlwaysSuccess").run(idle=vehicle.sim.step)
    assert result.status is RunStatus.SUCCESS


def test_a_leaf_that_raises_ends_the_run_in_error(vehicle, registry):
    result = runner(vehicle, registry, "Boom").run(idle=vehicle.sim.step)
    assert result.status is RunStatus.ERROR
    assert "leaf bug" in result.message


def test_ctrl_c_halts_running_leaves(vehicle, registry):
    r = runner(vehicle, registry, "Spin")
    steps = iter(range(300))

    def idle():
        vehicle.sim.step()
        if next(steps) == 299:
            raise KeyboardInterrupt

    result = r.run(idle=idle)
    assert result.status is RunStatus.INTERRUPTED
    assert Spin.ticks > 0 and Spin.terminated[-1] == Status.INVALID


def test_stop_leaves_a_flying_vehicle_hovering(vehicle, registry):
    r = runner(vehicle, registry, "ArmAndTakeoff: {altitude_m: 12}")
    assert vehicle.fly(r, 150) == Status.SUCCESS
    go = runner(vehicle, registry, "GoTo: {waypoint: [400, 0, 12]}")
    vehicle.fly(go, 8.0)
    assert np.linalg.norm(vehicle.sim.truth.vel_enu) > 3.0  # under way
    go.stop("test")
    vehicle.run_until(lambda: False, 12.0)
    assert np.linalg.norm(vehicle.sim.truth.vel_enu) < 0.5


def test_a_silent_vehicle_ends_the_run_with_a_clear_error(vehicle, registry):
    r = runner(vehicle, registry, "Spin")
    vehicle.sim.link_up = False  # the radio dies
    result = r.run(idle=vehicle.sim.step)
    assert result.status is RunStatus.ERROR
    assert "5" in result.message or "quiet" in result.message.lower()


def test_tick_log_records_each_status_change_once(vehicle, registry):
    r = runner(vehicle, registry, "Sequence: {name: seq, children: [AlwaysSuccess: {name: ok}, Spin: {name: spin}]}")
    seen = []
    r.on_tick(seen.append)
    vehicle.run_until(lambda: r.tick_if_due() and r.ticks == 3, 5.0)
    first = [(c.node, c.old, c.new) for c in r.tick_log]
    # Worked out by hand: the first tick starts everything; later ticks change nothing.
    assert sorted(first) == [("ok", "INVALID", "SUCCESS"), ("seq", "INVALID", "RUNNING"), ("spin", "INVALID", "RUNNING")]
    assert [len(changes) for changes in seen] == [3, 0, 0]
    r.stop("test")
    halted = {(c.node, c.old, c.new) for c in r.tick_log[3:]}
    assert halted == {("seq", "RUNNING", "INVALID"), ("spin", "RUNNING", "INVALID"), ("ok", "SUCCESS", "INVALID")}


class NeedsRadar(py_trees.ports.BehaviourWithPorts):
    """Keeps what setup() handed it."""

    INPUT_PORTS: dict = {}
    OUTPUT_PORTS: dict = {}
    got: dict = {}

    def setup(self, **kwargs):
        NeedsRadar.got = kwargs

    def update(self):
        return Status.SUCCESS


def test_resources_reach_every_behaviours_setup(vehicle, registry):
    registry.register(NeedsRadar)
    tree = load_tree_text("version: 1\ntrees:\n  T:\n    NeedsRadar\n", source="<test>", registry=registry)
    feed = object()
    MissionRunner(tree, vehicle.link, vehicle.clock, resources={"radar": feed}).setup()
    assert NeedsRadar.got["radar"] is feed and NeedsRadar.got["link"] is vehicle.link


def test_resources_cannot_replace_the_link_or_clock(vehicle, registry):
    tree = load_tree_text("version: 1\ntrees:\n  T:\n    AlwaysSuccess\n", source="<test>", registry=registry)
    with pytest.raises(ValueError, match="link"):
        MissionRunner(tree, vehicle.link, vehicle.clock, resources={"link": None})


class FirstSight(py_trees.ports.BehaviourWithPorts):
    """Remembers what the vehicle state and the link knew at its first tick."""

    INPUT_PORTS = {"state": input_port(VehicleState, "vehicle state", default_key=VEHICLE_STATE_KEY)}
    OUTPUT_PORTS: dict = {}
    seen: dict = {}

    def setup(self, **kwargs):
        self.link = kwargs["link"]

    def update(self):
        if not FirstSight.seen:
            s = self.get_input("state")
            FirstSight.seen = {"battery": s.battery_remaining_pct, "mode": s.mode, "frame": self.link.frame,
                               "position": s.position_enu.copy()}
        return Status.SUCCESS


def _fresh_vehicle(**boot) -> InProcessVehicle:
    """A vehicle just booted, as `chaser-bt run` meets an ArduCopter started a moment ago."""
    import dataclasses

    from sitl.vehicle.setup import BootParams

    scenario = load_scenario(SCENARIO)
    if boot:
        scenario = dataclasses.replace(scenario, boot=BootParams(**boot))
    return InProcessVehicle(scenario, seed=11)


def test_the_first_tick_waits_for_heartbeat_sys_status_and_a_position(registry):
    registry.register(FirstSight)
    FirstSight.seen = {}
    v = _fresh_vehicle()
    r = runner(v, registry, "FirstSight")
    assert len(r.waiting_for()) == 4  # nothing heard yet
    result = r.run(idle=v.sim.step)
    assert result.status is RunStatus.SUCCESS and r.ticks == 1
    seen = FirstSight.seen
    # The patrol scenario's battery is full and its GPS fix (hence home) comes 5 s after boot.
    assert seen["battery"] == pytest.approx(100.0, abs=1.0) and seen["mode"] != ""
    assert seen["frame"] is not None and np.all(np.isfinite(seen["position"]))
    assert np.linalg.norm(seen["position"][:2]) < 1.0 and v.sim.time_s >= 5.0


def test_a_vehicle_that_never_sets_home_ends_the_run_naming_what_is_missing(registry):
    registry.register(FirstSight)
    FirstSight.seen = {}
    v = _fresh_vehicle(gps_fix_s=1e9, ekf_ready_s=1e9, prearm_ok_s=1e9)  # no GPS fix: no home
    tree = load_tree_text("version: 1\ntrees:\n  T:\n    FirstSight\n", source="<test>", registry=registry)
    r = MissionRunner(tree, v.link, v.clock, telemetry_timeout_s=8.0)
    result = r.run(idle=v.sim.step)
    assert result.status is RunStatus.ERROR and r.ticks == 0 and FirstSight.seen == {}
    assert "no HOME_POSITION" in result.message and "within 8 s" in result.message
    assert "SYS_STATUS" not in result.message  # what did arrive is not blamed
    assert 8.0 <= v.sim.time_s < 8.5
