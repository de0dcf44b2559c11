"""A hostile peer on the vehicle's link, for the fuzz tests and ``benchmarks/bench_fuzz.py``.

Each case flies ``trees/patrol.yaml`` on the built-in simulator (seed = case) while, from 60 s on,
one kind of hostile input (drawn from the seed) is written into the link beside the vehicle's own:

- ``fields``: the vehicle's telemetry messages with random values (NaN, infinities, a zero
  quaternion, latitudes past the pole, a home thousands of kilometres away), under its ids;
- ``bytes``: random bytes between the vehicle's frames;
- ``clone``: a second sender under the vehicle's ids saying "LAND, disarmed";
- ``home``: one HOME_POSITION 2,147 km below the sea.

Every set-point the mission sends is checked against the default command envelope from the
simulator's true home (not the one the link believed). :func:`run_case` returns what happened.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from chaser_bt.vehicle import CommandEnvelope
from sitl.bench.rehearsal import rehearse
from sitl.world.scenario import load_scenario

__all__ = ["KINDS", "SAFE_END", "run_case"]

ROOT = Path(__file__).resolve().parents[2]
KINDS = ("fields", "bytes", "clone", "home")
START_S = 60.0  # the patrol is airborne on its first leg
#: Where a run may leave the aircraft: on the ground, holding, or flown home or down by its autopilot.
SAFE_END = ("landed", "holding", "under the autopilot (RTL)", "under the autopilot (LAND)")


def _wild(rng: np.random.Generator) -> float:
    return float(rng.choice([math.nan, math.inf, -math.inf, 0.0, 1e30, -1e30, rng.normal() * 10 ** rng.integers(0, 9)]))


def _int(rng: np.random.Generator, bits: int) -> int:
    return int(rng.integers(-(2 ** (bits - 1)), 2 ** (bits - 1)))


def _hostile_message(rng: np.random.Generator, t_ms: int):
    kind = rng.integers(0, 5)
    if kind == 0:
        return mavlink2.MAVLink_attitude_quaternion_message(t_ms, *[_wild(rng) for _ in range(7)])
    if kind == 1:
        return mavlink2.MAVLink_attitude_message(t_ms, *[_wild(rng) for _ in range(6)])
    if kind == 2:
        return mavlink2.MAVLink_global_position_int_message(t_ms, _int(rng, 32), _int(rng, 32), _int(rng, 32),
                                                            _int(rng, 32), _int(rng, 16), _int(rng, 16), _int(rng, 16), 0)
    if kind == 3:
        return mavlink2.MAVLink_home_position_message(_int(rng, 32), _int(rng, 32), _int(rng, 32), 0, 0, 0,
                                                      [1, 0, 0, 0], 0, 0, 0)
    return mavlink2.MAVLink_sys_status_message(0, 0, 0, 0, int(rng.integers(0, 65536)), -1,
                                               int(rng.integers(-128, 128)), 0, 0, 0, 0, 0, 0)


class _Hostile:
    """Writes one kind of hostile input into the vehicle's side of the link while the run flies."""

    def __init__(self, kind: str, seed: int) -> None:
        self.kind, self.rng = kind, np.random.default_rng([seed, 0xF022])
        self.mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)  # the vehicle's ids, its own counter
        self.mav.seq = int(self.rng.integers(0, 256))
        self.injected = 0
        self.vehicle = None

    def attach(self, vehicle) -> None:
        self.vehicle = vehicle
        step = vehicle.step

        def hostile_step() -> None:
            self._inject()
            step()

        vehicle.step = hostile_step

    def _inject(self) -> None:
        sim, rng = self.vehicle.sim, self.rng
        if sim.time_s < START_S:
            return
        end, t_ms = self.vehicle.vehicle_end, int(sim.time_s * 1000)
        if self.kind == "home":
            if self.injected == 0:
                home = sim.autopilot.frame.to_geodetic((0.0, 0.0, 0.0))
                end.write(mavlink2.MAVLink_home_position_message(
                    round(home.lat_deg * 1e7), round(home.lon_deg * 1e7), -2_147_483_000, 0, 0, 0, [1, 0, 0, 0],
                    0, 0, 0).pack(self.mav))
                self.injected = 1
            return
        if rng.random() > 0.3:  # about 15 a simulated second at 50 Hz physics
            return
        if self.kind == "fields":
            end.write(_hostile_message(rng, t_ms).pack(self.mav))
        elif self.kind == "bytes":
            end.write(rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8).tobytes())
        else:  # clone: LAND, disarmed
            end.write(self.mav.heartbeat_encode(mavlink2.MAV_TYPE_OCTOROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                                mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 9,
                                                mavlink2.MAV_STATE_STANDBY).pack(self.mav))
        self.injected += 1


class _EnvelopeAudit:
    """Every set-point the mission sends, checked against the envelope from the true home."""

    def __init__(self, vehicle, envelope: CommandEnvelope) -> None:
        self.vehicle, self.envelope, self.unsafe = vehicle, envelope, []

    def __call__(self, msg) -> None:
        kind = msg.get_type()
        try:
            if kind == "SET_POSITION_TARGET_GLOBAL_INT":
                sim = self.vehicle.sim
                east, north, _ = sim.autopilot.frame.to_enu(msg.lat_int * 1e-7, msg.lon_int * 1e-7, sim.autopilot.home.alt_m)
                home = sim.autopilot.home_enu
                self.envelope.check_position(east - home[0], north - home[1], msg.alt)
            elif kind == "SET_POSITION_TARGET_LOCAL_NED":
                self.envelope.check_velocity([msg.vy, msg.vx, -msg.vz])
        except Exception as exc:  # UnsafeCommand, or a target no frame can place
            self.unsafe.append(f"{kind}: {exc}")


def run_case(seed: int) -> dict:
    kind = KINDS[seed % len(KINDS)]
    hostile, audit = _Hostile(kind, seed), {}

    def on_start(runner, vehicle, resources) -> None:
        hostile.attach(vehicle)
        audit["audit"] = _EnvelopeAudit(vehicle, CommandEnvelope())
        vehicle.link.add_listener(on_send=audit["audit"])
        audit["state"] = vehicle.link.state

    scenario = load_scenario(ROOT / "sitl" / "scenarios" / "patrol.yaml")
    report = rehearse(ROOT / "trees" / "patrol.yaml", scenario, seed=seed, on_start=on_start)
    raised = report.outcome == "error" and report.message.split(":")[0].endswith(("Error", "Exception"))
    return {"seed": seed, "kind": kind, "injected": hostile.injected, "mission_outcome": report.mission_outcome,
            "final_state": report.final_state, "raised": raised, "message": report.message,
            "unsafe_commands": audit["audit"].unsafe, "dropped": dict(audit["state"].telemetry_rejected)}
