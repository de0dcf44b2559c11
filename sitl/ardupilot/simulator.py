"""ArduCopter SITL inside our world: our physics behind its JSON interface, our surroundings around it.

ArduPilot's SITL waits for a physics reply at every one of its physics frames (lock-step,
``sitl/vehicle/json_backend.py``), so its clock is ours: :meth:`ArduPilotSimulator.step` answers
frames (the rotor body under its motor PWMs, in the scenario's wind) until one built-in physics
step (20 ms) has passed, then moves the scenario's intruders and radar (:class:`Surroundings`, the
same as the built-in simulator's) and sends the safety pilot's RC. Between two frames ArduCopter
does not run, so everything the mission sends in a tick reaches it before its next step.

The world's clock, :attr:`ArduPilotSimulator.time_s`, starts when :meth:`start_world` is called: a
real crew powers the aircraft up and waits for its EKF before the intruder shows up, and ArduCopter
needs about 40 s of its own time for that. Before it, the vehicle stands on the ground at home and
nothing else moves. The mission's clock must count from the same moment (:attr:`epoch_s` is the
physics time it was called at).

The scenario's ``faults`` and ``ground_station`` mode changes are struck on the world's clock by
a second ground station on ArduCopter's SERIAL1 (:class:`~sitl.ardupilot.faults.FaultInjector`:
a forced disarm, SIM_GPS1_ENABLE, SIM_BATT_VOLTAGE, SIM_RC_FAIL with the pilot's RC silent, a mode
change) and, for ``link_loss``, by a relay on the mission's link (:class:`~sitl.ardupilot.faults.LinkRelay`).
What is not modelled on this path (the built-in simulator has them): the scenario's ``boot`` times
(ArduCopter boots as it does), the intruders' own MAVLink (they have their own radios:
:meth:`intruder_telemetry` hands their bytes to whoever listens) and our battery model (ArduCopter's
SITL reports its own).
"""

from __future__ import annotations

import logging
import math
import socket
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.geo import enu_to_ned, ned_to_enu
from sitl.ardupilot.faults import SERIAL1_OFFSET, FaultInjector, LinkRelay
from sitl.ardupilot.process import ArduCopterProcess, find_ardupilot, instance_free, mavlink_port, rc_port
from sitl.vehicle.autopilot import TruthState
from sitl.vehicle.json_backend import JsonPhysicsServer, SensorFrame, ServoPacket
from sitl.vehicle.physics import PHYSICS_DT, NormalStream, Wind
from sitl.vehicle.rotor_body import AIRFRAMES, RotorBody
from sitl.vehicle.setup import PilotScript
from sitl.world.scenario import Scenario
from sitl.world.surroundings import InSurroundings, Surroundings

__all__ = ["ArduPilotSimulator", "ArduPilotStopped", "ReportedAutopilot", "DEFAULT_SIM_RATE_HZ", "pilot_rc"]

log = logging.getLogger(__name__)

DEFAULT_SIM_RATE_HZ = 800  # ArduCopter pre-arm wants the gyro at >= 1.8x its 400 Hz loop (720 Hz)
_FIRST_INSTANCE = 20  # instances below are left to people starting SITL by hand (start_sitl.sh)
_ARMED_PWM = 1050  # a motor output above this: the motors spin (disarmed ArduCopter sends its minimum, 1000)
# AP_RCProtocol_UDP's defaults (SITL with no transmitter): sticks centred, throttle down, ch5/ch8 high.
_RC_DEFAULT = (1500, 1500, 1000, 1500, 1800, 1000, 1000, 1800) + (1500,) * 8
_RC_PACKET = struct.Struct("<16H")


class ArduPilotStopped(RuntimeError):
    """ArduCopter exited or stopped answering; the message ends with its own last lines."""


@dataclass
class ReportedAutopilot:
    """What scoring asks of the autopilot, for one we cannot look inside.

    ``armed`` is read from its motor outputs (truth: spinning motors); ``mode`` and the battery are
    what it reports over MAVLink (set by whoever holds the link: a mode is the autopilot's own
    statement, not a fact of the world).
    """

    mode: str = ""
    battery_remaining_pct: float = math.nan
    motor_pwm: tuple[int, ...] = ()

    @property
    def armed(self) -> bool:
        return any(p > _ARMED_PWM for p in self.motor_pwm)

    def battery(self) -> _Battery:
        return _Battery(self.battery_remaining_pct)


@dataclass(frozen=True)
class _Battery:
    remaining_pct: float


def pilot_rc(pilot: PilotScript | None, t_s: float, *, airborne: bool) -> tuple[int, ...]:
    """The 16 RC channels the safety pilot's transmitter sends at world time ``t_s``.

    Without a pilot: SITL's own defaults (sticks centred, throttle down). A pilot standing by holds
    the throttle down on the ground (ArduCopter will not arm with it raised: "Throttle (RC3) is not
    neutral") and centred in the air (a mode change then holds altitude), and sets the autonomy
    switch as the scenario's script says.
    """
    pwm = list(_RC_DEFAULT)
    if pilot is not None:
        if airborne:
            pwm[2] = 1500
        pwm[pilot.gate_channel - 1] = pilot.gate_pwm(t_s)
    return tuple(pwm)


class ArduPilotSimulator(InSurroundings):
    """ArduCopter SITL flying the rotor body in the scenario's world (see the module docstring).

    Args:
        scenario: the field, wind, intruders, radar, the pilot's switch and ArduCopter parameters.
        seed: seeds the surroundings and the gusts, as in the built-in simulator.
        airframe: a rotor body of :data:`sitl.vehicle.rotor_body.AIRFRAMES` (``"s1000"``, ``"quad"``).
        ardupilot: the folder holding ``arducopter`` (:func:`sitl.ardupilot.process.find_ardupilot`).
        sim_rate_hz: ArduCopter's physics frame rate (SIM_RATE_HZ).

    Raises:
        ArduPilotMissing: no binary where it was looked for.
        ArduPilotStopped: no free instance, or the binary exited at start.
    """

    def __init__(self, scenario: Scenario, seed: int, *, airframe: str = "s1000", ardupilot: str | Path | None = None,
                 sim_rate_hz: int = DEFAULT_SIM_RATE_HZ) -> None:
        if airframe not in AIRFRAMES:
            raise ValueError(f"airframe {airframe!r}: expected one of {', '.join(sorted(AIRFRAMES))}")
        folder = find_ardupilot(ardupilot)
        self.scenario = scenario.placed(seed)
        self.surroundings = Surroundings(self.scenario, seed)
        self.dt = PHYSICS_DT
        self.airframe = AIRFRAMES[airframe]
        heading = math.radians(self.scenario.home_heading_deg)
        self.body = RotorBody(self.airframe, attitude=Rotation.from_euler("z", heading))  # nose along the home heading
        self._wind = Wind(scenario.wind, NormalStream(np.random.default_rng([seed, 0x817d])))
        self.autopilot = ReportedAutopilot()
        self.epoch_s: float | None = None
        self.server, instance = self._claim_instance()
        pilot = self.scenario.pilot
        params = {"SIM_RATE_HZ": float(sim_rate_hz), **self.airframe.ardupilot_params()}
        if pilot is not None:
            params[f"RC{pilot.gate_channel}_OPTION"] = 0.0  # the pilot's switch is the mission's, not an autopilot function
        params.update(self.scenario.params)
        home = self.scenario.home
        self.process = ArduCopterProcess(folder, instance, (home.lat_deg, home.lon_deg, home.alt_m,
                                                            self.scenario.home_heading_deg), params)
        self._rc_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._rc_addr = ("127.0.0.1", rc_port(instance))
        faults, events = self.scenario.faults, self.scenario.ground_station
        self.faults = FaultInjector(faults, events, ("127.0.0.1", mavlink_port(instance) + SERIAL1_OFFSET),
                                    target_sysid=int(params.get("SYSID_THISMAV", 1))) if faults or events else None
        self._link_faults = tuple(f for f in faults if f.kind == "link_loss")
        self.relay = LinkRelay(("127.0.0.1", mavlink_port(instance))) if self._link_faults else None
        self.process.start()
        if not self.process.alive():
            self.close()
            raise ArduPilotStopped(f"ArduCopter exited at start:\n{self.process.log_tail()}")

    def _claim_instance(self) -> tuple[JsonPhysicsServer, int]:
        for instance in range(_FIRST_INSTANCE, _FIRST_INSTANCE + 100):
            if not instance_free(instance):
                continue
            try:  # binding the physics port claims the instance against other workers
                return JsonPhysicsServer(instance, self._physics), instance
            except OSError:
                continue
        raise ArduPilotStopped(f"no free ArduPilot instance among {_FIRST_INSTANCE}..{_FIRST_INSTANCE + 99}")

    # -- what a rehearsal reads, as from the built-in Simulator -----------------------------------
    @property
    def url(self) -> str:
        """The mission's connection string: ArduCopter's SERIAL0 (through :attr:`relay` when a ``link_loss`` is scripted)."""
        return self.process.url if self.relay is None else self.relay.url

    @property
    def link_up(self) -> bool:
        """Whether the mission's radio carries bytes now (scripted ``link_loss`` faults, on the world's clock)."""
        return self.epoch_s is None or not any(f.active(self.time_s) for f in self._link_faults)

    @property
    def physics_time_s(self) -> float:
        """ArduCopter's clock: physics seconds since its boot."""
        return self.server.time_s

    @property
    def time_s(self) -> float:
        """The world's clock: seconds since :meth:`start_world` (0 before it)."""
        return 0.0 if self.epoch_s is None else self.server.time_s - self.epoch_s

    @property
    def truth(self) -> TruthState:
        """Ground truth for scoring only: the rotor body's state."""
        b = self.body
        return TruthState(pos_enu=np.asarray(ned_to_enu(b.position_ned), float),
                          vel_enu=np.asarray(ned_to_enu(b.velocity_ned), float), euler_ned=b.euler_ned(),
                          on_ground=b.on_ground, crashed=b.crashed)

    def intruder_telemetry(self) -> bytes:
        """The intruders' own MAVLink due now (bytes for a second radio), or ``b""``."""
        return self.surroundings.intruder_telemetry(self.time_s) if self.epoch_s is not None else b""

    # -- stepping ----------------------------------------------------------------------------------
    def start_world(self) -> None:
        """Start the world's clock now: from here on the intruders fly and the radar scans."""
        if self.epoch_s is None:
            self.epoch_s = self.server.time_s
            log.info("world started at ArduCopter time %.2f s", self.epoch_s)

    def step(self, timeout_s: float = 10.0) -> None:
        """Answer ArduCopter's frames for one world step (20 ms), then step the surroundings and send RC.

        Raises:
            ArduPilotStopped: ArduCopter exited, or sent no frame within ``timeout_s`` of wall time.
        """
        self._step_wind()
        if self.relay is not None:
            self.relay.pump(self.link_up)  # the mission's last commands, before ArduCopter's next frames
        server = self.server
        until = server.time_s + self.dt - 1e-6
        while server.time_s < until:
            if not server.serve_one(timeout_s):
                why = "exited" if not self.process.alive() else f"sent no physics frame for {timeout_s:g} s"
                raise ArduPilotStopped(f"ArduCopter {why}:\n{self.process.log_tail()}")
        if self.epoch_s is not None:
            self.surroundings.step(self.time_s, self.dt, lambda: self.truth)
            if self.faults is not None:
                self.faults.step(self.time_s)
        if self.relay is not None:
            self.relay.pump(self.link_up)  # its telemetry, before the mission's next poll
        self._send_rc()

    def run_until(self, t_s: float) -> None:
        """Step until the world's clock reaches ``t_s`` (to within half a step)."""
        while self.time_s < t_s - 0.5 * self.dt:
            self.step()

    def _physics(self, packet: ServoPacket, t_s: float) -> SensorFrame:
        self.autopilot.motor_pwm = packet.pwm_us[: self.airframe.frame.motors]
        return self.body.physics(packet, t_s)

    def _send_rc(self) -> None:
        if self.faults is not None and self.epoch_s is not None and self.faults.rc_silent(self.time_s):
            return  # an rc_loss: the transmitter is silent
        pwm = pilot_rc(self.scenario.pilot, self.time_s, airborne=not self.body.on_ground)
        self._rc_sock.sendto(_RC_PACKET.pack(*pwm), self._rc_addr)

    def _step_wind(self) -> None:
        east, north, up = self._wind.step(self.dt)
        self.body.wind_ned = np.asarray(enu_to_ned((east, north, up)), float)

    def close(self) -> None:
        """Stop ArduCopter and release the ports."""
        if self.faults is not None:
            self.faults.close()
        if self.relay is not None:
            self.relay.close()
        self.process.stop()
        self.server.close()
        self._rc_sock.close()
