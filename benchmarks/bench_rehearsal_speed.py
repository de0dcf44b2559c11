"""Camera-on rehearsal speed: the chase in its default camera world, real-time factor.

Flies trees/chase.yaml on sitl/scenarios/chase.yaml (the ``any`` camera world: seed 1 is farmland)
``--repeats`` times as ``chaser-bt rehearse`` flies it: the camera a frame behind the tick, drawn in
a render process beside it (``SensorOptions(render_process=True)``). Beside each run, in the same
process: the same flight drawn in-process (``in_process``: what the render process buys) and a
reference (every frame rendered whole and processed inside its tick: what a rehearsal did before
regions of interest and the render process). The machine is shared, so the figures to compare
between machines or commits are the ratios, measured back to back; the real-time factor is the
median of the runs.

A run's wall time is its flight's, as a rehearsal report's ``wall_time_s`` is: setting the sensors
up (the radar's calibration, the detector's load, the camera's world built, in the render process or
here) is its ``setup_s``; ``with_setup_realtime_factor`` counts both. The warm-up run before the timed
ones loads the detector and calibrates seed 1's radar once for the process, so ``setup_s`` is mostly
the camera's world.

Each run also says where a camera frame's wall time went (``parts_ms``, per frame): ``render_wait``
(the tick waiting for the render process's frame, the copy out included), ``render_child`` (the
child's drawing), ``detector`` (the detector's calls, its box refiner included) and ``trackers``
(the tracker bank's corrections and advances, the refiner on tracked boxes included), ``frames``
counted; the rest of a tick is the simulator, the tree and the scoring.

Prints one JSON line: {"name": "rehearsal_speed", "realtime_factor_median", "with_setup_realtime_factor_median",
"in_process_realtime_factor_median",
"speedup_render_process", "reference_realtime_factor_median", "speedup_vs_reference", "tick_ms_median",
"parts_ms", "sim_time_s", "runs": [...], "opencv_threads", "detector_threads", "load_avg_1m"}. The detector runs
as each mode runs it in a rehearsal (``sitl.bench.sensors.detector_threads``: two threads beside a render
process, one in-process, unless ``OMP_NUM_THREADS`` says otherwise).
Run: .venv/bin/python benchmarks/bench_rehearsal_speed.py [--seed 1] [--sim-s 300] [--repeats 3] [--no-reference]
[--opencv-threads 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
from record import Benchmark, add_record_flag, emit  # noqa: E402

BENCHMARK = Benchmark(
    "rehearsal_speed", "Camera-on rehearsal speed: the chase in its default camera world, real-time factor.",
    against="built-in simulator: trees/chase.yaml rehearsed with every sensor on (radar, rendered camera, shipped detector)",
    units={
        "seed": "the scenario's seed", "sim_time_s": "simulated s per run",
        "*realtime_factor*": "simulated s per wall s",
        "realtime_factor_median": "simulated s per wall s, render process (as chaser-bt rehearse flies), median of runs",
        "with_setup_realtime_factor_median": "the same, the sensors' set-up counted",
        "in_process_realtime_factor_median": "simulated s per wall s, the camera drawn in-process",
        "reference_realtime_factor_median": "simulated s per wall s, every frame rendered whole inside its tick",
        "speedup_render_process": "realtime factor with the render process over in-process, back to back",
        "speedup_vs_reference": "realtime factor over the reference's, back to back",
        "tick_ms_median": "ms, median tick wall time",
        "parts_ms": "ms of wall time per camera frame, by part (median of runs)",
        "render_wait": "ms per frame, the tick waiting for the render process's frame",
        "render_child": "ms per frame, the render process drawing",
        "detector": "ms per frame, the detector's calls", "trackers": "ms per frame, the tracker bank",
        "frames": "camera frames per run",
        "wall_time_s": "s of wall time, the flight", "setup_s": "s of wall time, the sensors' set-up",
        "opencv_threads": "OpenCV's threads", "detector_threads": "the detector's threads in each mode",
        "load_avg_1m": "the machine's 1-minute load average at the end (the machine is shared)",
    },
    headline=("realtime_factor_median", "in_process_realtime_factor_median", "speedup_render_process",
              "speedup_vs_reference", "load_avg_1m"),
)


class PartTimer:
    """Wall time spent in a few methods, summed while :attr:`on`: wraps them in place for the process."""

    def __init__(self) -> None:
        self.on = False
        self.ms: dict[str, float] = {}
        self.count: dict[str, int] = {}

    def wrap(self, owner: type, method: str, part: str) -> None:
        inner = getattr(owner, method)
        timer = self

        def timed(*args, **kwargs):
            if not timer.on:
                return inner(*args, **kwargs)
            t = time.perf_counter()
            out = inner(*args, **kwargs)
            timer.ms[part] = timer.ms.get(part, 0.0) + 1e3 * (time.perf_counter() - t)
            timer.count[part] = timer.count.get(part, 0) + 1
            return out

        setattr(owner, method, timed)

    def start(self) -> None:
        self.ms, self.count, self.on = {}, {}, True

    def wrap_collect(self, owner: type) -> None:
        """``RenderProcess.collect``: the wait as ``render_wait``, the child's drawing as ``render_child``."""
        inner = owner.collect
        timer = self

        def timed(rp):
            t = time.perf_counter()
            out = inner(rp)
            if timer.on:
                timer.ms["render_wait"] = timer.ms.get("render_wait", 0.0) + 1e3 * (time.perf_counter() - t)
                timer.ms["render_child"] = timer.ms.get("render_child", 0.0) + out[3]
                timer.count["frames"] = timer.count.get("frames", 0) + 1
            return out

        owner.collect = timed

    def stop(self) -> dict:
        self.on = False
        frames = max(self.count.get("frames", 0), 1)
        out = {k: round(v / frames, 2) for k, v in sorted(self.ms.items())}
        return out | {"frames": self.count.get("frames", 0)}


def _rtf(report, setup: bool = False) -> float:
    """Simulated over wall seconds, to three places (the report's own figure has one: too coarse for
    ratios); with ``setup``, the sensors' set-up (the camera's world among it) counted too."""
    return round(report.sim_time_s / max(report.wall_time_s + (report.sensors_wall_s if setup else 0.0), 1e-9), 3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--sim-s", type=float, default=300.0, help="simulated seconds per run (the scenario's 300 by default)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-reference", action="store_true", help="skip the whole-frame reference runs")
    parser.add_argument("--opencv-threads", type=int, default=0,
                        help="OpenCV's threads (1: a campaign worker's setting; 0: OpenCV's default)")
    add_record_flag(parser)
    args = parser.parse_args()
    if args.opencv_threads > 0:
        import cv2

        cv2.setNumThreads(args.opencv_threads)
    os.environ.setdefault("MAVLINK20", "1")
    from sitl.bench.rehearsal import rehearse
    from sitl.bench.sensors import SensorOptions, detector_threads
    from sitl.world.scenario import load_scenario
    from chaser_bt.vision.detector.inference import Detector
    from chaser_bt.vision.trackers import TrackerBank
    from sitl.world.camera.render_process import RenderProcess

    parts = PartTimer()
    parts.wrap_collect(RenderProcess)
    parts.wrap(Detector, "__call__", "detector")
    parts.wrap(TrackerBank, "correct", "trackers")
    parts.wrap(TrackerBank, "advance", "trackers")
    scenario = dataclasses.replace(load_scenario(ROOT / "sitl/scenarios/chase.yaml"), time_limit_s=args.sim_s)
    tree = ROOT / "trees/chase.yaml"
    for render_process in (False, True):  # loads (the detector as each mode runs it), compiles and caches before timing
        rehearse(tree, dataclasses.replace(scenario, time_limit_s=5.0), args.seed, sensors=SensorOptions(render_process=render_process))
    runs, here, refs = [], [], []
    for _ in range(args.repeats):
        parts.start()
        r = rehearse(tree, scenario, args.seed, sensors=SensorOptions(render_process=True))
        runs.append({"realtime_factor": _rtf(r), "wall_time_s": r.wall_time_s, "setup_s": r.sensors_wall_s,
                     "with_setup_realtime_factor": _rtf(r, setup=True), "tick_ms_median": r.tick_ms_median,
                     "outcome": r.outcome, "detection_frac": r.detection_frac, "parts_ms": parts.stop()})
        h = rehearse(tree, scenario, args.seed, sensors=SensorOptions(render_process=False))
        here.append({"realtime_factor": _rtf(h), "wall_time_s": h.wall_time_s, "setup_s": h.sensors_wall_s,
                     "detection_frac": h.detection_frac})
        if not args.no_reference:
            ref = rehearse(tree, scenario, args.seed, sensors=SensorOptions(whole_frames=True, camera_lag=False))
            refs.append({"realtime_factor": _rtf(ref), "wall_time_s": ref.wall_time_s, "setup_s": ref.sensors_wall_s,
                         "detection_frac": ref.detection_frac})
    rtf = statistics.median(r["realtime_factor"] for r in runs)
    here_rtf = statistics.median(r["realtime_factor"] for r in here)
    out = {"name": "rehearsal_speed", "seed": args.seed, "sim_time_s": args.sim_s, "realtime_factor_median": rtf,
           "with_setup_realtime_factor_median": statistics.median(r["with_setup_realtime_factor"] for r in runs),
           "in_process_realtime_factor_median": here_rtf, "speedup_render_process": round(rtf / here_rtf, 3),
           "tick_ms_median": statistics.median(r["tick_ms_median"] for r in runs),
           "parts_ms": {k: statistics.median(r["parts_ms"][k] for r in runs) for k in runs[0]["parts_ms"]},
           "runs": runs, "in_process_runs": here}
    if refs:
        ref_rtf = statistics.median(r["realtime_factor"] for r in refs)
        out |= {"reference_realtime_factor_median": ref_rtf, "speedup_vs_reference": round(rtf / ref_rtf, 3), "reference_runs": refs}
    out["opencv_threads"] = args.opencv_threads or "default"
    out["detector_threads"] = {"render_process": detector_threads(beside_renderer=True), "in_process": detector_threads()}
    out["load_avg_1m"] = round(os.getloadavg()[0], 2)
    emit(out, BENCHMARK, args.record)


if __name__ == "__main__":
    main()
