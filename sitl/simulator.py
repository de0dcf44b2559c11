"""The simulator: one :class:`~sitl.vehicle.autopilot.Autopilot` behind one ArduCopter MAVLink endpoint, on ports.

A step is what one tick of a real flight controller's loop does: read everything that arrived on
every port, advance the vehicle by one physics step, send whatever telemetry is due to every port.
Nothing here reads a clock: time is the step count, so the same scenario and seed give the same
bytes on the wire, at any speed and in any process (a rehearsal runs it lock-step in-process, the
real-time server paces it against the wall clock from outside).

When the scenario has a ``radar:`` section the simulator also runs the ground radar
(:mod:`sitl.world.radar`): at each radar scan it shows the radar the vehicle (while airborne, as
``ownship``) and the scenario's scripted ``targets`` (not people: ``RADAR_BLIND_KINDS``), encodes the
scan as one JSON datagram and sends it over UDP (``radar.udp_port``) and to every in-process consumer
(:meth:`Simulator.add_radar_consumer`). The radar has its own random stream, so adding one does
not change the vehicle's noise.

The scenario's ``intruders`` (:mod:`sitl.world.intruders`: Phantom-like drones) fly here too, one step
with the vehicle; each sends its own MAVLink (its system id, HEARTBEAT and GLOBAL_POSITION_INT) to
every port after the vehicle's bytes of that step, on its own radio: the vehicle's ``link_loss``
faults do not silence it. The radar sees intruders like scripted targets. Each intruder's pilot
draws from its own random stream. The scenario's ``birds`` fly beside them (near a target or an
intruder, each from a stream of its own): the radar sees them, and the rendered camera draws them
where the radar has them (:mod:`sitl.world.surroundings`).

Scripted ``link_loss`` faults act here, where the radio is: while one is in force nothing is read
from or written to any port (bytes sent to the vehicle meanwhile are lost, as on a dead radio).
"""

from __future__ import annotations

import logging
from typing import Protocol

import numpy as np

from sitl.vehicle.autopilot import Autopilot
from sitl.vehicle.mavlink_endpoint import Channel, MavlinkEndpoint
from sitl.vehicle.physics import PHYSICS_DT
from sitl.world.scenario import Scenario
from sitl.world.surroundings import InSurroundings, Surroundings

__all__ = ["Port", "Simulator"]

log = logging.getLogger(__name__)


class Port(Protocol):
    """A byte link to one client: a :class:`chaser_bt.vehicle.pipe.PipeEnd` or a server socket."""

    def write(self, data: bytes) -> object: ...

    def read(self) -> bytes: ...


class Simulator(InSurroundings):
    """Steps the vehicle and serves MAVLink on every attached port.

    Args:
        scenario: the field, weather, airframe, parameters, boot times and faults.
        seed: seeds the autopilot's random generator (sensor noise, gusts): same seed, same run.
        physics_hz: physics rate; default ``1 / sitl.vehicle.physics.PHYSICS_DT`` (50 Hz).
    """

    def __init__(self, scenario: Scenario, seed: int, *, physics_hz: float | None = None) -> None:
        if physics_hz is not None and not physics_hz > 0.0:
            raise ValueError(f"physics_hz must be > 0, got {physics_hz}")
        self.scenario = scenario.placed(seed)  # scattered static targets (a person) put where this seed says
        self.dt = PHYSICS_DT if physics_hz is None else 1.0 / physics_hz
        self.autopilot = Autopilot(scenario, np.random.default_rng(seed))
        self.endpoint = MavlinkEndpoint(self.autopilot, start_unix_s=scenario.start_unix_s)
        self._ports: list[tuple[Port, Channel]] = []
        self._link_override: bool | None = None
        self._link_faults = tuple(f for f in scenario.faults if f.kind == "link_loss")
        self.surroundings = Surroundings(self.scenario, seed)

    @property
    def time_s(self) -> float:
        """Simulated seconds since boot."""
        return self.autopilot.time_s

    @property
    def truth(self):
        """Ground truth for scoring only (never on the wire): the autopilot's ``truth``."""
        return self.autopilot.truth

    @property
    def link_up(self) -> bool:
        """Whether the radio carries bytes now: scripted ``link_loss`` faults, unless overridden."""
        if self._link_override is not None:
            return self._link_override
        if not self._link_faults:
            return True
        t = round(self.autopilot.time_s, 6)  # a float sum of steps; match the ms the wire shows
        return not any(f.active(t) for f in self._link_faults)

    @link_up.setter
    def link_up(self, up: bool | None) -> None:
        """Force the link up or down (tests); ``None`` returns it to the scenario's script."""
        self._link_override = up

    def radar_objects(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """What the radar can see now: the vehicle while airborne and the scripted targets present."""
        return self.surroundings.radar_objects(self.autopilot.time_s, self.autopilot.truth)

    def attach(self, port: Port) -> None:
        """Serve MAVLink on ``port`` from the next step on."""
        self._ports.append((port, self.endpoint.open_channel()))

    def detach(self, port: Port) -> None:
        """Stop serving ``port`` (a client that went away)."""
        self._ports = [(p, c) for p, c in self._ports if p is not port]

    def step(self) -> None:
        """One physics step: ports -> endpoint, autopilot.step(dt), due telemetry -> ports."""
        endpoint = self.endpoint
        up = self.link_up
        for port, channel in self._ports:
            data = port.read()
            if up:
                endpoint.receive(data, channel)
        autopilot = self.autopilot
        autopilot.step(self.dt)
        t = autopilot.time_s
        self.surroundings.step(t, self.dt, lambda: autopilot.truth)
        endpoint.update()
        up = self.link_up  # the radio's state at the time the bytes are sent
        others = self.surroundings.intruder_telemetry(t)  # their own radios
        for port, channel in self._ports:
            out = endpoint.take_output(channel)  # each client its own link, as ArduCopter gives it
            if not up:
                out = b""
            out += others
            if out:
                port.write(out)

    def run_until(self, t_s: float) -> None:
        """Step until sim time reaches ``t_s`` (to within half a step)."""
        limit = t_s - 0.5 * self.dt
        while self.autopilot.time_s < limit:
            self.step()
