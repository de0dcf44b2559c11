"""Tick-period jitter with the detector running: the camera pipeline inline vs in its own thread.

A :class:`~chaser_bt.mission.runner.MissionRunner` on a wall clock ticks a small tree (VisionPipeline,
then TargetInView) at 5 and 10 Hz, ``--seconds`` each after a ``--warmup``, in the loop :meth:`MissionRunner.run` uses
(poll, tick when due, sleep 2 ms). The camera: 640x480 frames of the follow sequence
(``sitl.bench.camera_sequences``, an s1000 at 6-18 m) rendered once and replayed at 30 frames/s like a
live camera that always has its newest frame; the shipped detector (``tiny_yolo``, one intra-op
thread, OpenCV on one thread as on a flight) with the pipeline's defaults (detector every 3rd
frame, MOSSE + MedianFlow between, focus, box refiner). The vehicle is a stand-in that reports the
sequence's ownship pose at the clock's time (no MAVLink), so the figures are the tick loop's own.

Per rate and mode (``inline``: the pipeline inside the tick; ``thread``: a PerceptionWorker beside it):
``tick_*`` the period between tick starts, ``command_*`` between tick ends (where the tree's last
command has left), each as mean and std (ms) and as the p95 and max of |period - nominal| / nominal
(``*_jitter_p95``, ``*_jitter_max``: the issue's target is < 0.10 threaded); ``age_ms_*`` the age of the
estimate written at the tick, at the tick's end (inline: the tick's own duration; threaded: the
frame's age); ``estimate_share`` the share of ticks that wrote one; ``frames_processed`` (threaded).
Prints one JSON line. Usage: python benchmarks/bench_tick_jitter.py [--seconds 10] [--warmup 1] [--frames 90]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass

import cv2
import numpy as np
import py_trees

from chaser_bt.clock import WallClock
from chaser_bt.mission.runner import MissionRunner
from chaser_bt.tree import load_tree_text
from chaser_bt.vehicle.state import VehicleState
from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detector.inference import shipped_detector
from chaser_bt.vision.frame_source import Frame
from chaser_bt.vision.perception import PerceptionWorker
from chaser_bt.vision.pipeline import CameraSensor, PipelineConfig, VisionPipeline
from sitl.bench.camera_sequences import follow_sequence

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from record import Benchmark, add_record_flag, emit  # noqa: E402

FPS = 30.0
BENCHMARK = Benchmark(
    "tick_jitter", "Tick-period jitter with the detector running: the camera pipeline inline vs in its own thread.",
    against="a wall clock on this machine: replayed rendered frames, the shipped detector, a stand-in vehicle (no MAVLink)",
    units={
        "seconds": "s of counted ticking per rate and mode", "backend": "the detector's backend",
        "*_mean_ms": "ms, mean period", "*_std_ms": "ms, period standard deviation",
        "*_jitter_p95": "p95 of |period - nominal| / nominal (target < 0.10 threaded)",
        "*_jitter_max": "max of |period - nominal| / nominal",
        "ticks": "ticks counted", "estimate_share": "share of ticks that wrote an estimate",
        "age_ms_*": "ms, the estimate's age at the tick's end (mean, p95)",
        "tick_ms_median": "ms, median tick duration", "frames_processed": "frames the perception thread processed",
        "load_avg_1m": "the machine's 1-minute load average at the end (the machine is shared)",
        "target_met": "threaded command jitter p95 < 0.10 at 5 and 10 Hz",
    },
    headline=("thread_5hz.command_jitter_p95", "thread_10hz.command_jitter_p95", "inline_10hz.command_jitter_p95",
              "target_met", "load_avg_1m"),
)
TREE = """version: 1
trees:
  Jitter:
    Sequence:
      children:
        - VisionPipeline: {}
        - TargetInView: {}
"""


@dataclass
class _Replay:
    """The rendered frames at ``FPS`` from ``t0`` on, looped: read(t) gives the newest one at t."""

    views: list
    t0: float

    def index(self, t: float) -> int:
        return int(max(t - self.t0, 0.0) * FPS)

    def read(self, t: float) -> Frame:
        k = self.index(t)
        return Frame(t, self.views[k % len(self.views)].image, k)

    def close(self) -> None:
        pass


class _StillLink:
    """Stand-in vehicle: the replayed sequence's ownship pose at the clock's time; commands go nowhere."""

    def __init__(self, replay: _Replay, clock: WallClock) -> None:
        self.replay, self.clock = replay, clock

    @property
    def state(self) -> VehicleState:
        v = self.replay.views[self.replay.index(self.clock.now()) % len(self.replay.views)]
        return VehicleState(position_enu=v.position_enu, velocity_enu=v.velocity_enu, attitude=v.attitude_measured)

    def poll(self) -> None:
        pass

    def hover(self) -> None:
        pass

    def add_listener(self, **listeners) -> None:
        """Nothing is ever received or sent: no listener is ever called."""


def _stats(times: list[float], period: float) -> dict:
    p = np.diff(np.asarray(times))
    dev = np.abs(p - period) / period
    return {"mean_ms": round(float(p.mean()) * 1e3, 2), "std_ms": round(float(p.std()) * 1e3, 2),
            "jitter_p95": round(float(np.percentile(dev, 95)), 4), "jitter_max": round(float(dev.max()), 4)}


def run(mode: str, rate_hz: float, seconds: float, warmup: float, views: list, detector) -> dict:
    clock = WallClock()
    replay = _Replay(views, clock.now())
    sensor = CameraSensor(replay, VisionPipeline(CameraModel(width_px=640, height_px=480), detector, PipelineConfig()))
    camera = sensor if mode == "inline" else PerceptionWorker(sensor, clock, max_fps=FPS)
    runner = MissionRunner(load_tree_text(TREE, source="<bench>"), _StillLink(replay, clock), clock, rate_hz=rate_hz,
                           resources={"camera": camera})
    bb = py_trees.blackboard.Client(name="bench")
    bb.register_key("/target/estimate", access=py_trees.common.Access.READ)
    starts, ends, ages = [], [], []
    last = None
    runner.setup()
    begin = clock.now() + warmup  # the worker's first frames and the trackers' start are not counted
    end = begin + seconds
    try:
        while clock.now() < end:  # MissionRunner.run's loop
            runner.link.poll()
            start = time.perf_counter()
            if runner.tick_if_due() and clock.now() >= begin:
                ends.append(time.perf_counter())
                starts.append(start)
                est = bb.get("/target/estimate") if bb.exists("/target/estimate") else None
                if est is not None and est is not last:
                    ages.append(clock.now() - est.t)
                    last = est
            time.sleep(0.002)
    finally:
        if isinstance(camera, PerceptionWorker):
            processed = camera.stats().frames_processed
            camera.close()
        runner.stop("benchmark over")
    period = 1.0 / rate_hz
    tick, command = _stats(starts, period), _stats(ends, period)
    out = {f"tick_{k}": v for k, v in tick.items()} | {f"command_{k}": v for k, v in command.items()}
    out |= {"ticks": len(starts), "estimate_share": round(len(ages) / max(len(starts), 1), 3),
            "age_ms_mean": round(float(np.mean(ages)) * 1e3, 1) if ages else None,
            "age_ms_p95": round(float(np.percentile(ages, 95)) * 1e3, 1) if ages else None,
            "tick_ms_median": round(float(np.median(np.subtract(ends, starts))) * 1e3, 2)}
    if mode == "thread":
        out["frames_processed"] = processed
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="ticking time per rate and mode, s (default 10)")
    parser.add_argument("--warmup", type=float, default=1.0, help="ticking before the counted seconds, s (default 1)")
    parser.add_argument("--frames", type=int, default=90, help="frames rendered and replayed in a loop (default 90)")
    parser.add_argument("--seed", type=int, default=1, help="follow sequence seed (default 1)")
    add_record_flag(parser)
    args = parser.parse_args()
    os.environ.setdefault("MAVLINK20", "1")
    cv2.setNumThreads(1)
    views = list(follow_sequence(CameraModel(width_px=640, height_px=480), args.frames, args.seed))
    detector = shipped_detector("tiny_yolo")  # threads=1
    for v in views[:5]:
        detector(v.image)  # warm up
    out: dict = {"name": "tick_jitter", "seconds": args.seconds, "backend": detector.backend, "load_avg_1m": None}
    for rate in (5.0, 10.0):
        for mode in ("inline", "thread"):
            out[f"{mode}_{rate:g}hz"] = run(mode, rate, args.seconds, args.warmup, views, detector)
    out["load_avg_1m"] = round(os.getloadavg()[0], 2)
    out["target_met"] = all(out[f"thread_{r}hz"]["command_jitter_p95"] < 0.10 for r in (5, 10))
    emit(out, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
