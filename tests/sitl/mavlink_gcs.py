"""A minimal ground station for simulator tests: real encoded MAVLink over an in-memory pipe.

It encodes what it sends with pymavlink (sysid 255, compid 190 by default) and decodes everything
the simulator sends with an independent pymavlink parser, so the tests see exactly the bytes a
real client would, without sockets.
"""

from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"

from pymavlink.dialects.v20 import ardupilotmega as mavlink2  # noqa: E402

from chaser_bt.vehicle.pipe import byte_pipe  # noqa: E402

mav = mavlink2


class PipeGcs:
    """A GCS attached to a :class:`sitl.simulator.Simulator` through a byte pipe."""

    def __init__(self, sim, sysid: int = 255, compid: int = 190) -> None:
        self.sim = sim
        self.sim_end, self.end = byte_pipe()
        sim.attach(self.sim_end)
        self.mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.parser = mavlink2.MAVLink(None)
        self.parser.robust_parsing = True
        self.log: list = []  # (sim time when read, message)

    def send(self, msg) -> None:
        """Encode ``msg`` and put it on the wire to the simulator."""
        self.end.write(msg.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) & 0xFF

    def send_raw(self, data: bytes) -> None:
        self.end.write(data)

    def poll(self) -> list:
        """Decode everything that arrived; returns the new messages (also kept in :attr:`log`)."""
        msgs = self.parser.parse_buffer(self.end.read()) or []
        t = self.sim.time_s
        self.log.extend((t, m) for m in msgs)
        return msgs

    def run(self, seconds: float) -> list:
        """Step the simulator ``seconds`` of sim time (one poll per step); returns what arrived."""
        out = []
        end = self.sim.time_s + seconds - 0.5 * self.sim.dt
        while self.sim.time_s < end:
            self.sim.step()
            out.extend(self.poll())
        return out

    def wait_for(self, kind: str, timeout_s: float, predicate=lambda m: True):
        """Step until a message of ``kind`` satisfying ``predicate`` arrives; None on timeout."""
        end = self.sim.time_s + timeout_s
        while self.sim.time_s < end:
            self.sim.step()
            for m in self.poll():
                if m.get_type() == kind and predicate(m):
                    return m
        return None

    def heartbeat(self) -> None:
        self.send(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3))

    def command(self, command: int, *params: float, target: tuple[int, int] = (1, 1)) -> None:
        p = list(params) + [0.0] * (7 - len(params))
        self.send(mav.MAVLink_command_long_message(target[0], target[1], command, 0, *p))

    def command_ack(self, command: int, *params: float, timeout_s: float = 1.0, target=(1, 1)):
        """Send a COMMAND_LONG and return (ACK or None, messages seen meanwhile)."""
        start = len(self.log)
        self.command(command, *params, target=target)
        ack = self.wait_for("COMMAND_ACK", timeout_s, lambda m: m.command == command)
        return ack, [m for _, m in self.log[start:]]

    def set_mode(self, custom_mode: int):
        ack, _ = self.command_ack(
            mav.MAV_CMD_DO_SET_MODE, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, custom_mode
        )
        return ack

    def of_type(self, kind: str, since_s: float = -1.0) -> list:
        """Logged messages of ``kind`` read at or after sim time ``since_s``."""
        return [m for t, m in self.log if t >= since_s and m.get_type() == kind]


FIELD = {"lat_deg": 42.5, "lon_deg": -71.6, "alt_m": 80.0}


def quick_scenario(**overrides):
    """A calm field whose vehicle is ready to arm after 3 s (gps 1 s, EKF 2 s, pre-arm 3 s)."""
    from sitl.world.scenario import Scenario

    doc = {
        "name": "test",
        "home": dict(FIELD),
        "wind": {"speed_mps": 0.0, "gust_std_mps": 0.0},
        "boot": {"gps_fix_s": 1.0, "ekf_ready_s": 2.0, "prearm_ok_s": 3.0},
    }
    doc.update(overrides)
    return Scenario.from_dict(doc, source="<test>")


def ready_gcs(seed: int = 0, **overrides) -> PipeGcs:
    """A simulator past its boot checks (3.5 s) with a GCS attached that has seen its telemetry."""
    from sitl.simulator import Simulator

    gcs = PipeGcs(Simulator(quick_scenario(**overrides), seed))
    gcs.run(3.5)
    return gcs


def airborne_gcs(alt_m: float = 10.0, seed: int = 0, **overrides) -> PipeGcs:
    """Armed in GUIDED, taken off and settled at ``alt_m`` above home."""
    gcs = ready_gcs(seed, **overrides)
    assert gcs.set_mode(4).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.command_ack(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)[0].result == mav.MAV_RESULT_ACCEPTED
    assert gcs.command_ack(mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, alt_m)[0].result == mav.MAV_RESULT_ACCEPTED
    gcs.run(alt_m / 2.5 + 9.0)  # + ArduCopter's 2 s arming delay, spool-up and throttle ramp
    return gcs
