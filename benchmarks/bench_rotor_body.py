"""The motor-level rotor body's speed: physics steps per wall second, per airframe.

ArduCopter's JSON backend asks for SIM_RATE_HZ steps per simulated second (400 in the rehearsal), and
waits for each answer, so steps per second over 400 is the most speed-up the body allows.

Prints one JSON line: {"name": "rotor_body", "<airframe>_steps_per_s": bare ``RotorBody.step``,
"<airframe>_frames_per_s": ``RotorBody.physics`` plus encoding the reply (what
:class:`~sitl.vehicle.json_backend.JsonPhysicsServer` does per frame, less the socket),
"<airframe>_x_realtime_at_400hz": frames per second / 400}. Each is the best of ``--repeats`` runs
of ``--steps`` steps, flying a slight roll demand aloft (the machine is shared).
Run: .venv/bin/python benchmarks/bench_rotor_body.py
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from sitl.vehicle.json_backend import ServoPacket  # noqa: E402
from sitl.vehicle.rotor_body import AIRFRAMES, RotorBody  # noqa: E402
from record import Benchmark, add_record_flag, emit  # noqa: E402

RATE_HZ = 400
BENCHMARK = Benchmark(
    "rotor_body", __doc__,
    against="the motor-level rotor body alone (sitl/vehicle/rotor_body.py), no socket, one core",
    units={
        "rate_hz": "physics steps per simulated s ArduCopter's JSON backend asks for",
        "*_steps_per_s": "bare RotorBody.step calls per wall s (best of the repeats)",
        "*_frames_per_s": "RotorBody.physics plus encoding the reply, per wall s (best of the repeats)",
        "*_x_realtime_at_400hz": "frames per second over 400: the most speed-up the body allows",
    },
    headline=("s1000_x_realtime_at_400hz", "quad_x_realtime_at_400hz"),
)


def _pwm(body: RotorBody) -> tuple[int, ...]:
    """Hover, with a small roll demand on alternate motors, padded to 16 channels."""
    hover = round(body.params.hover_pwm_us)
    motors = tuple(hover + (5 if i % 2 else -5) for i in range(body.params.frame.motors))
    return motors + (1000,) * (16 - len(motors))


def best_rate(name: str, steps: int, repeats: int, frames: bool) -> float:
    """Best steps (or encoded frames) per wall second over ``repeats`` runs."""
    best = 0.0
    for _ in range(repeats):
        body = RotorBody.named(name, position_ned=(0.0, 0.0, -1000.0))
        packet = ServoPacket(RATE_HZ, 0, _pwm(body))
        pwm, dt = packet.pwm_us, packet.dt_s
        start = time.perf_counter()
        if frames:
            for k in range(steps):
                body.physics(packet, k * dt).encode()
        else:
            for _ in range(steps):
                body.step(pwm, dt)
        best = max(best, steps / (time.perf_counter() - start))
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=3)
    add_record_flag(ap)
    args = ap.parse_args()
    out: dict[str, object] = {"name": "rotor_body", "rate_hz": RATE_HZ}
    for name in AIRFRAMES:
        out[f"{name}_steps_per_s"] = round(best_rate(name, args.steps, args.repeats, frames=False))
        frames = best_rate(name, args.steps, args.repeats, frames=True)
        out[f"{name}_frames_per_s"] = round(frames)
        out[f"{name}_x_realtime_at_400hz"] = round(frames / RATE_HZ, 1)
    emit(out, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
