"""The simulator and the mission's vehicle link in one process, joined by encoded MAVLink.

A rehearsal, a search trial and a follow evaluation all fly the same way: the built-in simulator on
one end of an in-memory byte pipe, the :class:`VehicleLink` a real flight uses on the other, stepped
lock-step in one thread on simulated time.
"""

from __future__ import annotations

import abc
from typing import Any, Callable

import py_trees

from chaser_bt.clock import FunctionClock
from chaser_bt.mission.runner import MissionRunner
from chaser_bt.target_telemetry import TargetTelemetry
from chaser_bt.vehicle import LinkConfig, VehicleLink
from chaser_bt.vehicle.pipe import byte_pipe
from sitl.simulator import Simulator
from sitl.world.scenario import Scenario

__all__ = ["InProcessVehicle", "LockStepVehicle"]


class LockStepVehicle(abc.ABC):
    """What a rehearsal flies: ``sim`` (world clock ``sim.time_s``, truth), ``link``, ``clock`` and ``step()``."""

    sim: Any
    link: VehicleLink
    clock: FunctionClock

    @abc.abstractmethod
    def step(self) -> None:
        """Advance the simulator one physics step and let the link read what arrived."""

    def run_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Step until ``predicate()`` holds (True) or ``timeout_s`` of sim time pass (False)."""
        deadline = self.sim.time_s + timeout_s
        while not predicate():
            if self.sim.time_s >= deadline:
                return False
            self.step()
        return True

    def fly(self, runner: MissionRunner, timeout_s: float) -> py_trees.common.Status:
        """Tick ``runner`` lock-step until its root finishes or ``timeout_s`` pass; its last status."""
        self.run_until(lambda: runner.tick_if_due() and runner.finished, timeout_s)
        return runner.status

    def attach_target_telemetry(self) -> TargetTelemetry:
        """The intruders' own telemetry as the mission would receive it (on the vehicle's link here)."""
        return TargetTelemetry.attach(self.link, self.clock.now)

    def close(self) -> None:
        """Release what the vehicle holds (nothing in process)."""


class InProcessVehicle(LockStepVehicle):
    """The simulator and a :class:`VehicleLink` joined by an in-memory MAVLink pipe, run lock-step.

    ``step()`` advances physics by one step and lets the link read what arrived. The link's timers
    run on simulated time (the rehearsal's stand-in for the wall clock) and the mission clock is
    the vehicle's boot time as telemetry reports it, exactly as when flying the simulator remotely.
    """

    def __init__(
        self,
        scenario: Scenario,
        seed: int,
        link_config: LinkConfig | None = None,
        ground_tap: Callable[[bytes], None] | None = None,
    ) -> None:
        """``ground_tap``, when given, sees every chunk of bytes the mission's link sends to the vehicle."""
        self.sim = Simulator(scenario, seed)
        vehicle_end, ground_end = byte_pipe()
        self.sim.attach(vehicle_end)
        self.vehicle_end = vehicle_end  # the vehicle's side: a fuzz test writes here as (or beside) the vehicle
        end = ground_end if ground_tap is None else _TappedEnd(ground_end, ground_tap)
        # The pipe also carries the intruders' own telemetry: name the vehicle's system id, as a
        # ground station configured for one aircraft would, rather than lock onto whoever speaks first.
        config = link_config or LinkConfig(target_sysid=self.sim.endpoint.sysid)
        self.link = VehicleLink.over_pipe(end, config, monotonic=lambda: self.sim.time_s)
        self.clock = FunctionClock(lambda: self.link.state.t_boot_s)

    def step(self) -> None:
        self.sim.step()
        self.link.poll()


class _TappedEnd:
    """A pipe end that shows every chunk written to it to ``tap`` first (to compare what missions send)."""

    def __init__(self, end, tap: Callable[[bytes], None]) -> None:
        self._end, self._tap = end, tap

    def write(self, data: bytes) -> int:
        self._tap(bytes(data))
        return self._end.write(data)

    def read(self) -> bytes:
        return self._end.read()

    def pending(self) -> int:
        return self._end.pending()
