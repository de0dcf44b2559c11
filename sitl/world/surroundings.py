"""What a scenario puts around the vehicle: its intruders and its ground radar, on the vehicle's clock.

The built-in simulator (:mod:`sitl.simulator`) and ArduCopter flying inside our world
(:mod:`sitl.ardupilot`) both fly in the same surroundings: each physics step they hand the vehicle's
true state in, the intruders move, and at each radar scan the radar sees the vehicle (while
airborne, as ``ownship``), the scripted targets present and the intruders, and sends the scan as one
JSON datagram to every consumer (a UDP sender when the scenario names a port, the rehearsal's
in-process queue). Each intruder's pilot and the radar draw from their own random streams, seeded
from the run's seed, so the surroundings are the same whichever autopilot flies.

The scenario's ``birds`` fly here too (:class:`~sitl.world.intruders.BirdFlock`, each from a stream of
its own): the radar sees each flock as one object labelled ``bird-<near>-<index>``, and the rendered
camera draws its birds where they are (:meth:`Surroundings.bird_poses`). The radar knows each
object's own signature (``radar:`` of a target, an intruder or a bird entry).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from chaser_bt.geo import LocalFrame
from chaser_bt.radar.report import encode_scan
from sitl.world.camera.distractors import BirdPose
from sitl.world.intruders import BirdFlock, Intruder
from sitl.world.radar.config import RadarSignature
from sitl.world.radar.model import GroundRadar, ScanTruth
from sitl.world.radar.udp import RadarUdpSender
from sitl.world.scenario import Scenario

__all__ = ["Surroundings"]


class Surroundings:
    """The scenario's intruders and ground radar, stepped with the vehicle.

    Args:
        scenario: the scenario, already placed for the run's seed (``Scenario.placed``).
        seed: seeds the intruders' pilots and the radar's noise.
    """

    def __init__(self, scenario: Scenario, seed: int) -> None:
        self.scenario = scenario
        frame = LocalFrame(scenario.home)
        self.intruders = [Intruder(spec, np.random.default_rng([seed, 0x1d7, k]), frame)
                          for k, spec in enumerate(scenario.intruders)]
        anchors = {tgt.name: tgt.path for tgt in scenario.targets} | {i.name: i for i in self.intruders}
        self.birds = [BirdFlock(spec, f"bird-{spec.near}-{k}", anchors[spec.near], np.random.default_rng([seed, 0xb1d5, k]))
                      for k, spec in enumerate(scenario.birds)]
        self.radar: GroundRadar | None = None
        self.radar_truth: ScanTruth | None = None  # scoring only: the last scan's track -> object
        self._radar_consumers: list[Callable[[bytes], None]] = []
        self._next_scan_s = 0.0
        if scenario.radar is not None:
            self.radar = GroundRadar(scenario.radar, frame, np.random.default_rng([seed, 0x5ada7]), self._signatures())
            if scenario.radar.udp_port is not None:
                self._radar_consumers.append(RadarUdpSender(scenario.radar.udp_host, scenario.radar.udp_port))

    def _signatures(self) -> dict[str, RadarSignature]:
        """The objects with a radar signature of their own: object name -> signature."""
        sigs: dict[str, RadarSignature | None] = {tgt.name: tgt.radar for tgt in self.scenario.targets}
        sigs.update({i.name: i.spec.radar for i in self.intruders})
        sigs.update({b.label: b.spec.flock_signature for b in self.birds})
        return {k: v for k, v in sigs.items() if v is not None}

    def sign_radar_datagrams(self, sign: Callable[[bytes], bytes]) -> None:
        """Sign every datagram the radar sends over UDP with ``sign`` (in-process consumers get them plain)."""
        for consumer in self._radar_consumers:
            if isinstance(consumer, RadarUdpSender):
                consumer.sign = sign

    def add_radar_consumer(self, consumer: Callable[[bytes], None]) -> None:
        """Hand every radar datagram to ``consumer`` too (e.g. a ``QueueDatagramSource.push``)."""
        self._radar_consumers.append(consumer)

    def bird_poses(self, t: float) -> tuple[BirdPose, ...]:
        """The scenario's birds present at ``t``, for the camera (every bird of every flock)."""
        return tuple(pose for flock in self.birds if flock.present(t) for pose in flock.poses(t))

    def radar_objects(self, t: float, truth) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """What the radar can see at ``t``: the vehicle (``truth``) while airborne, the scripted targets present, the
        intruders, the scenario's birds present (one object a flock)."""
        objs = {}
        if not truth.on_ground:
            objs["ownship"] = (np.asarray(truth.pos_enu, float), np.asarray(truth.vel_enu, float))
        for tgt in self.scenario.targets:
            if tgt.present(t) and tgt.radar_visible:
                objs[tgt.name] = (tgt.path.position_enu(t), tgt.path.velocity_enu(t))
        for intruder in self.intruders:
            objs[intruder.name] = (intruder.pos.copy(), intruder.vel.copy())
        for flock in self.birds:
            if flock.present(t):
                objs[flock.label] = flock.centre(t)
        return objs

    def step(self, t: float, dt: float, truth: Callable[[], object]) -> None:
        """The step of ``dt`` that ends at ``t``: the intruders fly, then the radar scans if one is due.

        ``truth`` returns the vehicle's true state; it is asked only when the radar scans.
        """
        for intruder in self.intruders:
            intruder.step(t, dt)
        if self.radar is None or t < self._next_scan_s - 1e-9:
            return
        self._next_scan_s += self.radar.dt
        out = self.radar.scan(round(t, 6), self.radar_objects(t, truth()))
        if out is None:
            return
        scan, self.radar_truth = out
        datagram = encode_scan(scan)
        for consumer in self._radar_consumers:
            consumer(datagram)

    def intruder_telemetry(self, t: float) -> bytes:
        """The intruders' own MAVLink due at ``t`` (each on its own radio), encoded, or ``b""``."""
        if not self.intruders:
            return b""
        return b"".join(intruder.telemetry_bytes(round(t, 6)) for intruder in self.intruders)


class InSurroundings:
    """What a simulator flying in :class:`Surroundings` shows a rehearsal of them (the built-in
    :class:`sitl.simulator.Simulator` and :class:`sitl.ardupilot.simulator.ArduPilotSimulator`):
    set ``surroundings`` in ``__init__``."""

    surroundings: Surroundings

    @property
    def intruders(self) -> list[Intruder]:
        return self.surroundings.intruders

    @property
    def birds(self) -> list[BirdFlock]:
        return self.surroundings.birds

    @property
    def radar(self) -> GroundRadar | None:
        return self.surroundings.radar

    @property
    def radar_truth(self) -> ScanTruth | None:
        """Scoring only: the last radar scan's track -> object."""
        return self.surroundings.radar_truth

    def sign_radar_datagrams(self, sign: Callable[[bytes], bytes]) -> None:
        """Sign every datagram the radar sends over UDP with ``sign`` (in-process consumers get them plain)."""
        for consumer in self._radar_consumers:
            if isinstance(consumer, RadarUdpSender):
                consumer.sign = sign

    def add_radar_consumer(self, consumer: Callable[[bytes], None]) -> None:
        """Hand every radar datagram to ``consumer`` too (e.g. a ``QueueDatagramSource.push``)."""
        self.surroundings.add_radar_consumer(consumer)
