"""ArduPilot's ArduCopter flying inside our world, and the mission's link to it, stepped lock-step.

The counterpart of :class:`~sitl.bench.in_process.InProcessVehicle` for ``rehearse --autopilot
ardupilot``: the simulator is an :class:`~sitl.ardupilot.simulator.ArduPilotSimulator` (ArduCopter's
SITL on our physics and surroundings) and the mission's :class:`VehicleLink` is a plain TCP
connection to ArduCopter's SERIAL0, as ``chaser-bt run --connect`` would open it. One :meth:`step`
answers ArduCopter's physics frames for 20 ms of its time and then lets the link read what it sent.

Booting: ArduCopter needs about 40 s of its own time before it is ready to arm (EKF on GPS). The
vehicle steps it on the ground until it reports ready and its home, then starts the world's clock
(:meth:`ArduPilotSimulator.start_world`); the mission clock, the vehicle's boot time from telemetry,
is counted from the same moment, so radar scans, camera frames and ticks share one time base and a
run's figures do not include the boot.

The intruders' own MAVLink reaches the mission on a second radio (:meth:`attach_target_telemetry`),
not through ArduCopter.

The scenario's faults and ground-station mode changes strike on the world's clock from a second
ground station on ArduCopter's SERIAL1 (:mod:`sitl.ardupilot.faults`, held by the simulator, so
they go on while a rehearsal flies out a failsafe without the mission); with a ``link_loss``
scripted, the link opened here runs through the simulator's relay (``sim.url`` names it).
"""

from __future__ import annotations

import logging
from pathlib import Path

from pymavlink import mavutil

from chaser_bt.clock import FunctionClock
from chaser_bt.target_telemetry import TargetTelemetry
from chaser_bt.vehicle import LinkConfig, VehicleLink
from chaser_bt.vehicle.connection import open_connection
from sitl.ardupilot.simulator import ArduPilotSimulator, ArduPilotStopped
from sitl.bench.in_process import LockStepVehicle
from sitl.world.scenario import Scenario

__all__ = ["ArduPilotVehicle", "BOOT_TIMEOUT_S"]

log = logging.getLogger(__name__)

BOOT_TIMEOUT_S = 120.0  # ArduCopter's time to wait for it to be ready to arm (about 40 s observed)
_VEHICLE_SYSID = 1  # ArduCopter's SYSID_THISMAV default


class ArduPilotVehicle(LockStepVehicle):
    """ArduCopter SITL in the scenario's world and a :class:`VehicleLink` to it (see the module docstring).

    Args:
        scenario, seed: as for the built-in simulator.
        link_config: the mission link's configuration (default: vehicle system id 1).
        airframe: the rotor body ArduCopter flies (``s1000``, ``quad``).
        ardupilot: the folder holding ``arducopter`` (default ``$CHASER_BT_ARDUPILOT`` or ``../shared/ardupilot``).

    Raises:
        ArduPilotMissing: no binary.
        ArduPilotStopped: ArduCopter exited, or was not ready to arm within :data:`BOOT_TIMEOUT_S`.
    """

    def __init__(self, scenario: Scenario, seed: int, link_config: LinkConfig | None = None, *,
                 airframe: str = "s1000", ardupilot: str | Path | None = None) -> None:
        self.sim = ArduPilotSimulator(scenario, seed, airframe=airframe, ardupilot=ardupilot)
        self._radio = mavutil.mavlink.MAVLink(None)  # the intruders' own telemetry, decoded as a ground receiver would
        self._radio.robust_parsing = True
        self._radio_listeners: list = []
        try:
            config = link_config or LinkConfig(target_sysid=_VEHICLE_SYSID)
            conn = open_connection(self.sim.url, source_system=config.gcs_sysid, source_component=config.gcs_compid,
                                   timeout_s=config.connect_timeout_s)  # SERIAL0 listens before the first physics frame
            self.link = VehicleLink(conn, config, monotonic=lambda: self.sim.physics_time_s)
            self.clock = FunctionClock(self._mission_time)
            self._boot()
        except BaseException:
            self.close()
            raise

    def _mission_time(self) -> float:
        """The vehicle's boot time from telemetry, counted from the world's start."""
        epoch = self.sim.epoch_s or 0.0
        return self.link.state.t_boot_s - epoch

    def _boot(self) -> None:
        sim, state = self.sim, self.link.state
        while not (state.ready_to_arm and self.link.frame is not None):
            if sim.physics_time_s > BOOT_TIMEOUT_S:
                raise ArduPilotStopped(f"ArduCopter was not ready to arm after {BOOT_TIMEOUT_S:.0f} s of its time "
                                       f"(prearm {state.prearm_ok}, EKF {state.ekf_ok}, GPS fix {state.gps_fix_type}):\n"
                                       f"{sim.process.log_tail()}")
            self._step_link()
        sim.start_world()
        log.info("ArduCopter ready to arm after %.1f s of its time", sim.physics_time_s)

    def _step_link(self) -> None:
        self.sim.step()
        self.link.poll()
        reported = self.sim.autopilot
        reported.mode = self.link.state.mode
        reported.battery_remaining_pct = self.link.state.battery_remaining_pct

    def step(self) -> None:
        self._step_link()
        data = self.sim.intruder_telemetry()
        if data and self._radio_listeners:
            for msg in self._radio.parse_buffer(data) or ():
                for listener in self._radio_listeners:
                    listener(msg)

    def attach_target_telemetry(self) -> TargetTelemetry:
        """The intruders' telemetry from their own radios (their bytes never pass through ArduCopter)."""
        tel = TargetTelemetry(self.clock.now, lambda: self.link.target_sysid)
        self._radio_listeners.append(tel.on_message)
        return tel

    def close(self) -> None:
        """Close the link and stop ArduCopter."""
        link = getattr(self, "link", None)
        if link is not None:
            link.close()
        self.sim.close()
