"""Campaigns: one mission tree rehearsed over many scenarios and seeds, in parallel, resumable, with a report.

``chaser-bt campaign TREE --scenarios DIR_OR_FILE --seeds 1-50 --workers N --out DIR`` runs one
:func:`sitl.bench.rehearsal.rehearse` per (scenario, seed) in worker processes (``spawn``; each worker
pins torch and the BLAS libraries to one thread, since runs are already parallel), or on a Ray
cluster with ``--ray ADDRESS`` (a run flown there names its node: ``worker_node``, ``worker_host``).
Every finished run is written at once as ``DIR/runs/<scenario>/seed_<n>.json`` (and its trace as ``.npz``) by an atomic rename, so a campaign
killed midway resumes where it stopped: a run whose JSON exists for the same tree and scenario
contents is not flown again (unless it ended in ``error``: those are retried). At the end the runs are aggregated (success rate; median, IQR and
p10-p90 of every DESIGN §7 key beside the paper's values) into ``campaign.json``, ``campaign.md``
and the paper's figures (overhead tracks, relative geometry, belief maps, CDFs).

A run **succeeds** (:class:`SuccessRule`) when it ends well (``landed``, ``following`` or
``completed``: not crashed, failsafe, timed out or in error) and, where the mission had a target
(its trace saw one, or a FOV share was scored), vision acquired it and kept it in the camera's FOV for at
least ``min_followed_s`` seconds after acquisition, and the object followed at the end is the one the
mission designated (``custody_at_end``: following someone else is no success); where a run reports
``sar_found`` (not None), it must be true. A scenario's scheduled retasks (``retask``) must all have
been taken, and a chase retasked to a search is held to both: the chase until the retask, the find after.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import inspect
import json
import logging
import math
import multiprocessing
import os
import re
import signal
import socket
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np

from chaser_bt.cli_args import add_autopilot_arguments, output_dir, positive_int, scenario_set, tree_file
from chaser_bt.log.trace import FlightTrace
from sitl.bench.out_lock import OutDirError, lock_out_dir

__all__ = [
    "CampaignConfig",
    "CampaignError",
    "CampaignResult",
    "RunSpec",
    "SuccessRule",
    "METRIC_KEYS",
    "VARYING_KEYS",
    "add_command",
    "aggregate",
    "find_scenarios",
    "false_success",
    "followed_s",
    "lock_out_dir",
    "parse_seeds",
    "retasks_missed",
    "run_campaign",
    "run_one",
]

log = logging.getLogger(__name__)

#: Report keys summarised over a campaign (DESIGN §7; None values are left out of each summary).
METRIC_KEYS: tuple[str, ...] = (
    "t_airborne_s", "t_acquire_s", "target_in_fov_frac", "detection_frac", "radar_assoc_frac",
    "wrong_assoc_frac", "custody_frac", "target_switches", "envelope_frac", "landed_dist_m", "followed_s",
    "sim_time_s", "wall_time_s",
)

#: Keys whose median each scenario's line of the report gives (the chase's custody and view).
SCENARIO_KEYS: tuple[str, ...] = ("t_acquire_s", "target_in_fov_frac", "detection_frac", "custody_frac")

#: Row keys that depend on the machine that flew a run and on its load, not on the run: the same run
#: flown again, here, in a worker process or on a Ray node, has the same row but for these.
VARYING_KEYS: tuple[str, ...] = (
    "wall_time_s", "realtime_factor", "tick_ms_median", "sensors_wall_s", "worker_node", "worker_host",
)

#: ``--quick``: each run's simulated time is capped here (enough to launch, acquire and follow a while).
QUICK_TIME_LIMIT_S = 120.0
#: ``final_state`` values that a standing-by pilot would have to rescue (sitl.bench.safe_end).
UNSAFE_STATES = ("crashed", "moving", "falling")
SETTLE_NOTE = "judged 10 s of simulated time after the mission stopped"

_OK_OUTCOMES = ("landed", "following", "completed")

#: The most seeds one ``--seeds`` may name: each is a whole rehearsal (seconds to minutes), so more
#: would take years, and the list of runs alone would grow without bound (``1-100000000``).
MAX_SEEDS = 100_000
#: Seeds are the simulator's, as ``rehearse --seed`` takes them: integers in [0, 2^32).
SEED_LIMIT = 2**32


class CampaignError(ValueError):
    """Bad campaign input (seeds, paths, tree, scenario); the message names what and where."""


# -- inputs ---------------------------------------------------------------------------------------


def parse_seeds(text: str) -> list[int]:
    """Seeds from ``"1-50"``, ``"1,3,7"`` or ``"1-10,20"``: ascending, each once.

    Raises:
        CampaignError: on an empty item, a non-integer, a negative seed, a seed past 2^32 - 1, a
            range whose end is below its start (naming the item), a seed named twice, or more
            than :data:`MAX_SEEDS` seeds in all.
    """
    seeds: set[int] = set()
    repeated: set[int] = set()
    if not text.strip():
        raise CampaignError("--seeds: empty; expected e.g. 1-50, 1,3,7 or 1-10,20")
    count = 0
    for item in text.split(","):
        item = item.strip()
        match = re.fullmatch(r"([0-9]+)(?:-([0-9]+))?", item)
        if match is None:
            if item.startswith("-") or re.search(r"(^|-)-[0-9]", item):
                raise CampaignError(f"--seeds: seeds are integers >= 0: {item!r} names a negative one")
            raise CampaignError(f"--seeds: {item!r} is not a seed or a range N-M of integers >= 0 (e.g. 1-50, 1,3,7)")
        if any(len(digits) > 10 for digits in match.groups(default="")):
            raise CampaignError(f"--seeds: {item!r}: seeds are integers in [0, 2^32)")
        a = int(match[1])
        b = int(match[2]) if match[2] is not None else a
        if max(a, b) >= SEED_LIMIT:
            raise CampaignError(f"--seeds: {item!r}: seeds are integers in [0, 2^32)")
        if b < a:
            raise CampaignError(f"--seeds: {item!r}: the range ends below its start")
        count += b - a + 1
        if count > MAX_SEEDS:
            raise CampaignError(f"--seeds: {text!r} names more than {MAX_SEEDS} seeds; each is a whole rehearsal: "
                                "split the campaign")
        repeated.update(seeds.intersection(range(a, b + 1)))
        seeds.update(range(a, b + 1))
    if repeated:
        raise CampaignError(f"--seeds: {text!r} names seed(s) {', '.join(map(str, sorted(repeated)))} more than once")
    return sorted(seeds)


def find_scenarios(path: str | Path) -> list[Path]:
    """A scenario file, or every ``*.yaml`` in a folder (sorted by name)."""
    path = Path(path)
    if path.is_file():
        return [path]
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix in (".yaml", ".yml") and p.is_file())
        if not files:
            raise CampaignError(f"--scenarios {path}: no .yaml scenario files in this folder")
        return files
    raise CampaignError(f"--scenarios {path}: no such file or folder")


def _seed_list(text: str) -> list[int]:
    """``--seeds`` for argparse: :func:`parse_seeds`, its error as argparse's (``argument --seeds: ...``)."""
    try:
        return parse_seeds(text)
    except CampaignError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--seeds: ")) from None


def _digest(*paths: Path) -> str:
    """The contents of ``paths``, in order, as 16 hex digits (their names do not count)."""
    h = hashlib.sha256()
    for path in paths:
        h.update(hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()[:16]


@dataclass(frozen=True)
class RunSpec:
    """One rehearsal of a campaign. Paths are strings so specs pickle to any worker."""

    tree: str
    scenario: str
    seed: int
    camera: bool = True
    quick: bool = False
    fingerprint: str = ""
    autopilot: str = "builtin"  # who flies (sitl.bench.rehearsal.AutopilotChoice)
    airframe: str = "s1000"
    ardupilot: str | None = None  # contents of the tree, its includes and the scenario: a stored result counts only if it matches
    chaos: bool = False  # one random fault drawn from the seed (sitl.bench.chaos)

    @property
    def scenario_stem(self) -> str:
        return Path(self.scenario).stem

    @property
    def key(self) -> str:
        return f"{self.scenario_stem}/seed_{self.seed:04d}"


@dataclass(frozen=True)
class SuccessRule:
    """What counts as a successful run (see the module docstring)."""

    min_followed_s: float = 20.0
    ok_outcomes: tuple[str, ...] = _OK_OUTCOMES

    def __call__(self, row: Mapping[str, Any]) -> bool:
        if row.get("outcome") not in self.ok_outcomes or retasks_missed(row):
            return False
        found = row.get("sar_found")
        if found is not None and not found:  # a search and rescue: the person must be found
            return False
        # A chase (a validated radar track launched it: t_airborne_s), also one retasked to a search
        # later: the target must be acquired and followed. A search alone has no radar track.
        if _had_target(row) and (found is None or row.get("t_airborne_s") is not None):
            if row.get("t_acquire_s") is None or row.get("custody_at_end") is False:
                return False
            followed = row.get("followed_s")
            return followed is None or followed >= self.min_followed_s
        return True


def retasks_missed(row: Mapping[str, Any]) -> int:
    """How many of the run's scheduled retasks were not taken (refused, or never offered before the run ended)."""
    taken = sum(1 for r in row.get("retasks") or () if r.get("accepted"))
    return max(0, int(row.get("retasks_scheduled") or 0) - taken)


def _had_target(row: Mapping[str, Any]) -> bool:
    """Whether the run had a target to chase: the trace saw one, or a FOV share was scored."""
    if row.get("has_target") is not None:
        return bool(row["has_target"])
    return any(row.get(k) is not None for k in ("target_in_fov_frac", "target_in_fov_frac_flight"))


@dataclass
class CampaignConfig:
    """A campaign: the tree, the scenarios, the seeds and where the results go."""

    tree: Path
    scenarios: list[Path]
    seeds: list[int]
    out_dir: Path
    workers: int = 1
    ray_address: str | None = None
    camera: bool = True
    quick: bool = False
    fresh: bool = False  # ignore stored results and fly every run again
    report_only: bool = False  # fly nothing: report the runs stored so far
    success: SuccessRule = field(default_factory=SuccessRule)
    autopilot: str = "builtin"  # who flies: "builtin" or "ardupilot" (on ``airframe``, binary in ``ardupilot``)
    airframe: str = "s1000"
    ardupilot: Path | None = None
    chaos: bool = False  # one random fault per run (sitl.bench.chaos)

    def specs(self) -> list[RunSpec]:
        from chaser_bt.tree.documents import tree_files

        tree_digest = _digest(*tree_files(self.tree))  # the tree and every file it includes
        flown_by = "" if self.autopilot == "builtin" else f"-{self.autopilot}-{self.airframe}"
        folder = None if self.ardupilot is None else str(self.ardupilot)
        return [
            RunSpec(str(self.tree.resolve()), str(sc.resolve()), seed, self.camera, self.quick,
                    f"{tree_digest}-{_digest(sc)}-{'cam' if self.camera else 'nocam'}{'-quick' if self.quick else ''}{flown_by}"
                    f"{'-chaos' if self.chaos else ''}",
                    self.autopilot, self.airframe, folder, self.chaos)
            for sc in self.scenarios for seed in self.seeds
        ]


@dataclass
class CampaignResult:
    """What :func:`run_campaign` did: the rows of every run, the aggregates and the files written."""

    rows: list[dict]
    aggregates: dict
    executed: int  # runs flown by this call (the others were found on disk)
    files: dict[str, Path]


# -- one run (in a worker) ------------------------------------------------------------------------


def followed_s(trace: FlightTrace | None, t_acquire_event: str = "acquired") -> float | None:
    """Seconds with the target in the camera's FOV from the first ``acquired`` event on (None without one).

    Each tick counts for the time to the next tick (the last tick for the median step).
    """
    if trace is None or not len(trace):
        return None
    ev = trace.first_event(t_acquire_event)
    if ev is None:
        return 0.0 if np.isfinite(trace.in_fov).any() else None
    t = np.asarray(trace.t, float)
    dt = np.diff(t, append=t[-1] + (float(np.median(np.diff(t))) if len(t) > 1 else 0.0))
    mask = (np.nan_to_num(trace.in_fov, nan=0.0) > 0.5) & (t >= ev.t)
    return float(dt[mask].sum())


def _worker_init() -> None:
    """A worker process: one thread for torch, BLAS and OpenCV (the runs are the parallelism), MAVLink 2.

    Set before torch is imported (it reads ``OMP_NUM_THREADS`` then), and again on torch itself
    in case it already was. OpenCV's own pool (the renderer's warps) would otherwise start a thread
    per core in every worker, and the workers would take the cores from each other.
    """
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = "1"
    os.environ.setdefault("MAVLINK20", "1")
    import cv2

    cv2.setNumThreads(1)
    torch = sys.modules.get("torch")
    if torch is not None and torch.get_num_threads() != 1:
        torch.set_num_threads(1)


def _in_worker(runner: Callable[[RunSpec], dict], spec: RunSpec) -> dict:
    """What a worker process or a Ray task runs: pin the threads, fly ``spec``."""
    _worker_init()
    return runner(spec)


def _rehearse_kwargs(rehearse: Callable, spec: RunSpec) -> dict:
    """Keyword arguments for the options this ``rehearse`` accepts (trace, sensors).

    The search-and-rescue scores (``sar_found`` ...) come with the rehearsal's own report.
    """
    params = inspect.signature(rehearse).parameters
    kwargs: dict[str, Any] = {}
    if "trace" in params:
        kwargs["trace"] = True
    if "sensors" in params and not spec.camera:
        from sitl.bench import (
            sensors as sensors_mod,  # the rehearsal's sensor options (camera on by default)
        )

        kwargs["sensors"] = sensors_mod.SensorOptions(camera=False)
    if spec.autopilot != "builtin":
        from sitl.bench.rehearsal import AutopilotChoice

        kwargs["autopilot"] = AutopilotChoice(spec.autopilot, spec.airframe, spec.ardupilot)
    return kwargs


def run_one(spec: RunSpec) -> dict:
    """Fly one rehearsal; its report row plus ``trace`` (a FlightTrace or None). Never raises."""
    os.environ.setdefault("MAVLINK20", "1")
    from sitl.bench.rehearsal import rehearse
    from sitl.world.scenario import load_scenario

    started = time.perf_counter()
    try:
        scenario = load_scenario(spec.scenario)
        if spec.quick:
            scenario = dataclasses.replace(scenario, time_limit_s=min(scenario.time_limit_s, QUICK_TIME_LIMIT_S))
        fault = None
        if spec.chaos:
            from sitl.bench.chaos import with_random_fault

            scenario, fault = with_random_fault(scenario, spec.seed)
        report = rehearse(spec.tree, scenario, spec.seed, **_rehearse_kwargs(rehearse, spec))
        row = report.to_dict()
        if fault is not None:
            row.update(chaos_fault=fault["kind"], chaos_at_s=fault["at_s"])
        trace = getattr(report, "trace", None)
        row.pop("trace", None)
    except Exception as exc:  # a run that cannot even start is an error row, not a dead campaign
        log.exception("run %s failed", spec.key)
        row = {"outcome": "error", "message": f"{type(exc).__name__}: {exc}", "seed": spec.seed,
               "wall_time_s": round(time.perf_counter() - started, 3)}
        trace = None
    if trace is not None:
        for k, v in (("tree", Path(spec.tree).name), ("scenario", spec.scenario_stem), ("seed", spec.seed)):
            trace.meta.setdefault(k, v)
    followed = followed_s(trace)
    row.setdefault("followed_s", None if followed is None else round(followed, 2))
    if trace is not None and len(trace):
        row.setdefault("has_target", bool(np.isfinite(trace.target_enu).any()))
    row.update(key=spec.key, scenario_file=spec.scenario_stem, tree_path=spec.tree, scenario_path=spec.scenario,
               seed=spec.seed, fingerprint=spec.fingerprint)
    return {"row": row, "trace": trace}


# -- storage --------------------------------------------------------------------------------------


def _result_path(out_dir: Path, spec: RunSpec) -> Path:
    return out_dir / "runs" / spec.scenario_stem / f"seed_{spec.seed:04d}.json"


def _load_row(out_dir: Path, spec: RunSpec, retry_errors: bool = False) -> dict | None:
    """The stored row for ``spec``, or None if absent, unreadable or from another tree/scenario.

    ``retry_errors``: also None for a run that ended in ``error`` (a missing file, a bug since fixed:
    a resumed campaign flies those again).
    """
    path = _result_path(out_dir, spec)
    try:
        row = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if row.get("fingerprint") != spec.fingerprint or (retry_errors and row.get("outcome") == "error"):
        return None
    return row


def _store(out_dir: Path, spec: RunSpec, result: Mapping[str, Any]) -> dict:
    """Write a run's trace, then its JSON (its presence means done), each by an atomic rename."""
    path = _result_path(out_dir, spec)
    path.parent.mkdir(parents=True, exist_ok=True)
    row = dict(result["row"])
    trace = result.get("trace")
    if trace is not None and len(trace):
        npz = path.with_suffix(".npz")
        tmp = npz.with_name(f".{npz.stem}.tmp.npz")
        trace.save(tmp)
        tmp.replace(npz)
        row["trace_file"] = str(npz.relative_to(out_dir))
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(row, indent=1, default=_json_default) + "\n")
    tmp.replace(path)
    return row


def _json_default(obj: Any) -> Any:
    if hasattr(obj, "item"):
        return obj.item()
    return str(obj)


# -- executing runs -------------------------------------------------------------------------------


def _execute_inline(specs: Sequence[RunSpec], runner: Callable[[RunSpec], dict]) -> Iterator[tuple[RunSpec, dict]]:
    for spec in specs:
        yield spec, runner(spec)


def _execute_processes(specs: Sequence[RunSpec], runner: Callable[[RunSpec], dict], workers: int) -> Iterator[tuple[RunSpec, dict]]:
    """Runs in ``workers`` spawned processes, yielded as each finishes; unfinished ones are cancelled on exit."""
    ctx = multiprocessing.get_context("spawn")  # no fork: torch, threads and the simulator's state stay per process
    # Workers ignore Ctrl-C: the driver alone decides to stop, keeps what finished and ends the workers.
    before = set(multiprocessing.active_children())  # the pool's workers are the children started after this
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_ignore_interrupts)
    pending: dict[Future, RunSpec] = {}
    try:
        queue = iter(specs)
        for spec in queue:  # keep the queue short so a stop does not leave many runs submitted
            pending[pool.submit(_in_worker, runner, spec)] = spec
            if len(pending) >= 2 * workers:
                break
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                spec = pending.pop(fut)
                nxt = next(queue, None)
                if nxt is not None:
                    pending[pool.submit(_in_worker, runner, nxt)] = nxt
                yield spec, fut.result()
    finally:
        if pending:  # stopped early (Ctrl-C, an error): end the runs in flight now rather than wait for them
            for process in set(multiprocessing.active_children()) - before:
                process.terminate()
        pool.shutdown(wait=not pending, cancel_futures=True)


def _ignore_interrupts() -> None:
    """A worker process's initialiser: SIGINT (Ctrl-C reaches the whole process group) is the driver's."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _execute_ray(specs: Sequence[RunSpec], runner: Callable[[RunSpec], dict], address: str) -> Iterator[tuple[RunSpec, dict]]:
    """Runs as Ray tasks (one CPU each, spread over the nodes) on the cluster at ``address``
    (``local`` starts one on this machine).

    The driver's code folders travel with the job (``py_modules``), so cluster nodes need the
    dependencies but not chaser-bt itself; the tree, its includes and the scenarios travel with the
    tasks (:func:`_in_ray_task`). Results come back to the driver, which stores them.
    """
    try:
        import ray
    except ImportError:
        raise CampaignError("--ray: ray is not installed (pip install 'ray>=2.9')") from None
    import behaviours
    import chaser_bt
    import sitl

    modules = [str(Path(m.__file__).parent) for m in (chaser_bt, behaviours, sitl)]
    started_here = not ray.is_initialized()
    if started_here:  # "local" is ray.init's own: a new instance here even when a cluster runs on this machine
        ray.init(address=address, runtime_env={"py_modules": modules}, include_dashboard=False, log_to_driver=False)
    # SPREAD: a campaign's runs are alike and CPU-bound, so every node takes its share at once
    # (Ray's default fills the driver's node first).
    task = ray.remote(num_cpus=1, scheduling_strategy="SPREAD")(_in_ray_task)
    inputs = ray.put(_input_files(specs))
    refs = {task.remote(runner, spec, inputs): spec for spec in specs}
    try:
        while refs:
            done, _ = ray.wait(list(refs), num_returns=1)
            spec = refs.pop(done[0])
            yield spec, ray.get(done[0])
    finally:
        for ref in refs:
            ray.cancel(ref, force=True)
        if started_here:
            ray.shutdown()


def _input_files(specs: Sequence[RunSpec]) -> dict[str, bytes]:
    """The files the runs read, by resolved path: each tree with every file it includes, each scenario."""
    from chaser_bt.tree.documents import tree_files

    files: dict[str, bytes] = {}
    for spec in specs:
        for path in (*tree_files(spec.tree), Path(spec.scenario)):
            if str(path) not in files:
                files[str(path)] = path.read_bytes()
    return files


def _on_this_node(spec: RunSpec, inputs: Mapping[str, bytes], scratch: Path) -> RunSpec:
    """``spec`` as this node can fly it: in place where its files are here with the driver's contents
    (the driver's machine, a shared file system), else on copies written under ``scratch`` at their
    driver paths, so the tree's relative includes still resolve."""
    if all(_same_file(Path(name), data) for name, data in inputs.items()):
        return spec
    for name, data in inputs.items():
        copy = scratch / name.lstrip("/")
        copy.parent.mkdir(parents=True, exist_ok=True)
        copy.write_bytes(data)
    return dataclasses.replace(spec, tree=str(scratch / spec.tree.lstrip("/")), scenario=str(scratch / spec.scenario.lstrip("/")))


def _same_file(path: Path, data: bytes) -> bool:
    try:
        return path.read_bytes() == data
    except OSError:
        return False


def _in_ray_task(runner: Callable[[RunSpec], dict], spec: RunSpec, inputs: Mapping[str, bytes]) -> dict:
    """What a Ray task runs: fly ``spec`` (:func:`_on_this_node`), its row naming the driver's paths
    and the node that flew it (``worker_node``: the Ray node id; ``worker_host``: the host name)."""
    import ray

    with tempfile.TemporaryDirectory(prefix="chaser-bt-run-") as scratch:
        result = _in_worker(runner, _on_this_node(spec, inputs, Path(scratch)))
    row = result.get("row")
    if isinstance(row, dict):
        for key, value in (("tree_path", spec.tree), ("scenario_path", spec.scenario)):
            if key in row:
                row[key] = value
        row.update(worker_node=ray.get_runtime_context().get_node_id(), worker_host=socket.gethostname())
    return result


# -- the campaign ---------------------------------------------------------------------------------


def _check_inputs(config: CampaignConfig) -> None:
    from chaser_bt.tree import TreeError, load_tree
    from sitl.world.scenario import ScenarioError, load_scenario

    if config.workers < 1:
        raise CampaignError(f"--workers {config.workers}: need at least 1")
    if not config.seeds:
        raise CampaignError("--seeds: no seeds")
    if config.tree.is_dir():
        raise CampaignError(f"{config.tree}: is a folder, not a tree file")
    if not config.tree.is_file():
        raise CampaignError(f"{config.tree}: no such tree file")
    try:
        load_tree(config.tree)
    except TreeError as exc:
        raise CampaignError(f"{config.tree}: invalid tree\n{exc}") from None
    for sc in config.scenarios:
        try:
            load_scenario(sc)
        except ScenarioError as exc:
            raise CampaignError(str(exc)) from None
        except OSError as exc:
            raise CampaignError(f"{sc}: {exc.strerror or exc}") from None
    stems = Counter(sc.stem for sc in config.scenarios)
    if any(n > 1 for n in stems.values()):
        raise CampaignError(f"--scenarios: two scenario files share a name ({', '.join(s for s, n in stems.items() if n > 1)})")


def run_campaign(
    config: CampaignConfig,
    *,
    runner: Callable[[RunSpec], dict] = run_one,
    on_start: Callable[[int, int], None] | None = None,
    on_result: Callable[[int, int, dict], None] | None = None,
    report: bool = True,
) -> CampaignResult:
    """Fly every run of ``config`` not already stored, store each as it finishes, then write the report.

    Args:
        runner: flies one spec (picklable for worker processes; :func:`run_one` by default).
        on_start: called as ``on_start(total, stored)`` once the inputs are checked, before any run.
        on_result: called as ``on_result(done, total, row)`` after each run is stored (progress).
        report: write ``campaign.json``, ``campaign.md`` and the figures at the end.

    Raises:
        CampaignError: bad input (nothing is flown).
        OutDirError: another command is writing into ``config.out_dir`` (nothing is flown).
        KeyboardInterrupt: passed on after the runs finished so far are stored (re-run to resume).

    ``config.report_only`` takes no lock: it only reads the stored runs (each written whole by an atomic
    rename) and writes the report, so it can report a campaign still flying into the folder.
    """
    _check_inputs(config)
    out = config.out_dir
    out.mkdir(parents=True, exist_ok=True)
    if config.report_only:
        return _run_locked(config, runner, on_start, on_result, report)
    with lock_out_dir(out, "--out", "campaign"):
        return _run_locked(config, runner, on_start, on_result, report)


def _run_locked(config: CampaignConfig, runner: Callable[[RunSpec], dict], on_start: Callable[[int, int], None] | None,
                on_result: Callable[[int, int, dict], None] | None, report: bool) -> CampaignResult:
    """:func:`run_campaign` once the output folder is ours (or, for ``report_only``, without holding it)."""
    out = config.out_dir
    specs = config.specs()
    retry = not config.report_only
    stored = {} if config.fresh else {s.key: r for s in specs if (r := _load_row(out, s, retry)) is not None}
    if config.report_only:
        specs = [s for s in specs if s.key in stored]
        if not specs:
            hint = "" if config.quick else "; if they were flown with --quick, add --quick"
            raise CampaignError(f"--report-only: no stored runs of this tree and these scenarios and seeds in {out}{hint}")
    todo = [s for s in specs if s.key not in stored]
    log.info("campaign %s: %d runs, %d stored, %d to fly", config.tree, len(specs), len(stored), len(todo))
    done = len(stored)
    if on_start is not None:
        on_start(len(specs), done)
    if todo:
        if config.ray_address:
            stream = _execute_ray(todo, runner, config.ray_address)
        elif config.workers > 1 and len(todo) > 1:
            stream = _execute_processes(todo, runner, min(config.workers, len(todo)))
        else:
            stream = _execute_inline(todo, runner)
        try:
            for spec, result in stream:
                stored[spec.key] = _store(out, spec, result)
                done += 1
                if on_result is not None:
                    on_result(done, len(specs), stored[spec.key])
        finally:
            stream.close()  # stops the workers now, not when the traceback lets go of the generator
    rows = [stored[s.key] for s in specs]
    for row in rows:
        row["success"] = config.success(row)
    aggregates = aggregate(rows, config.success)
    files: dict[str, Path] = {}
    if report:
        files = write_campaign_report(config, rows, aggregates)
    return CampaignResult(rows, aggregates, len(todo), files)


# -- aggregation and the report -------------------------------------------------------------------


def summarise(values: Iterable[float]) -> dict[str, float | int | None]:
    """n, mean, min, p10, p25, median, p75, p90, max and IQR of ``values`` (numpy's linear percentiles)."""
    v = np.asarray([float(x) for x in values if x is not None and math.isfinite(float(x))])
    if not len(v):
        return {"n": 0, "mean": None, "min": None, "p10": None, "p25": None, "median": None, "p75": None, "p90": None, "max": None, "iqr": None}
    p10, p25, p50, p75, p90 = (float(x) for x in np.percentile(v, [10, 25, 50, 75, 90]))
    return {"n": int(len(v)), "mean": float(v.mean()), "min": float(v.min()), "p10": p10, "p25": p25, "median": p50,
            "p75": p75, "p90": p90, "max": float(v.max()), "iqr": p75 - p25}


def aggregate(rows: Sequence[Mapping[str, Any]], success: Callable[[Mapping[str, Any]], bool] = SuccessRule()) -> dict:
    """Campaign figures: success rate, outcomes, per-scenario success, and :func:`summarise` of each metric key.

    Each metric holds the paper's value (``paper``) and whether the median beats it (``median_beats_paper``).
    """
    from chaser_bt.log.figures import (
        PAPER_VALUES,  # matplotlib: imported when needed, not with the CLI
    )
    from sitl.bench.report import beats_paper

    n = len(rows)
    ok = [bool(success(r)) for r in rows]
    by_scenario: dict[str, dict] = {}
    scenario_rows: dict[str, list[Mapping[str, Any]]] = {}
    for r, s in zip(rows, ok):
        name = str(r.get("scenario_file", r.get("scenario", "?")))
        entry = by_scenario.setdefault(name, {"runs": 0, "success": 0})
        entry["runs"] += 1
        entry["success"] += int(s)
        scenario_rows.setdefault(name, []).append(r)
    for name, entry in by_scenario.items():
        entry["success_frac"] = entry["success"] / entry["runs"]
        for key in SCENARIO_KEYS:
            entry[f"{key}_median"] = summarise(r.get(key) for r in scenario_rows[name])["median"]
        switches = [r["target_switches"] for r in scenario_rows[name] if r.get("target_switches") is not None]
        entry["target_switches"] = sum(switches) if switches else None
    metrics = {}
    for key in METRIC_KEYS:
        stats = summarise(r.get(key) for r in rows)
        stats["paper"] = PAPER_VALUES.get(key)
        stats["median_beats_paper"] = beats_paper(key, stats["median"])
        metrics[key] = stats
    extra: dict[str, Any] = {}
    found = [bool(r["sar_found"]) for r in rows if r.get("sar_found") is not None]
    if found:
        extra["sar_found_frac"] = sum(found) / len(found)
        # a find reported in the wrong place (more than found_radius_m from everyone): the mission believed it
        extra["sar_wrong_finds"] = sum(1 for r in rows if r.get("sar_found") is False and r.get("sar_find_error_m") is not None)
    retasked = [r for r in rows if r.get("retasks_scheduled")]
    if retasked:
        offered = [t for r in retasked for t in r.get("retasks") or ()]
        extra["retasks"] = {
            "runs": len(retasked),
            "scheduled": sum(int(r["retasks_scheduled"]) for r in retasked),
            "taken": sum(1 for t in offered if t.get("accepted")),
            "missed": sum(retasks_missed(r) for r in retasked),
            "refusals": dict(Counter(str(t.get("message")) for t in offered if not t.get("accepted"))),
        }
    extra["false_successes"] = sum(1 for r in rows if false_success(r))
    extra["unsafe_ends"] = sum(1 for r in rows if r.get("final_state") in UNSAFE_STATES)
    if any(r.get("chaos_fault") for r in rows):
        extra["chaos_faults"] = dict(Counter(str(r["chaos_fault"]) for r in rows if r.get("chaos_fault")))
        extra["t_safe_s"] = summarise(r.get("t_safe_s") for r in rows if r.get("chaos_fault"))
    return {
        "runs": n,
        "success": sum(ok),
        "success_frac": (sum(ok) / n) if n else None,
        "outcomes": dict(Counter(str(r.get("outcome")) for r in rows)),
        "by_scenario": by_scenario,
        "metrics": metrics,
        **extra,
    }


def false_success(row: Mapping[str, Any]) -> bool:
    """The mission said ``completed`` while the truth shows a crash, a failsafe's landing, or an aircraft left unsafe."""
    return row.get("mission_outcome") == "completed" and (
        row.get("outcome") in ("crashed", "failsafe") or row.get("final_state") in UNSAFE_STATES)


def _load_traces(out_dir: Path, rows: Sequence[Mapping[str, Any]]) -> list[FlightTrace]:
    return [t for t, _ in _traces_with_rows(out_dir, rows)]


def _traces_with_rows(out_dir: Path, rows: Sequence[Mapping[str, Any]]) -> list[tuple[FlightTrace, Mapping[str, Any]]]:
    """The readable stored traces, each with its run's row (for the figures: which run to highlight)."""
    pairs = []
    for r in rows:
        if r.get("trace_file"):
            try:
                pairs.append((FlightTrace.load(out_dir / r["trace_file"]), r))
            except (OSError, ValueError, KeyError) as exc:
                log.warning("%s: cannot read its trace: %s", r.get("key"), exc)
    return pairs


def write_campaign_report(config: CampaignConfig, rows: Sequence[dict], aggregates: Mapping[str, Any]) -> dict[str, Path]:
    """``campaign.json`` (config, aggregates, rows), ``campaign.md`` and PNG figures in ``config.out_dir``."""
    from chaser_bt.log import figures
    from sitl.bench.report import markdown_table, write_json

    out = config.out_dir
    files = {"json": out / "campaign.json", "markdown": out / "campaign.md"}
    write_json(files["json"], {
        "tree": str(config.tree), "scenarios": [str(s) for s in config.scenarios], "seeds": config.seeds,
        "camera": config.camera, "quick": config.quick, "success_rule": dataclasses.asdict(config.success),
        "aggregates": aggregates, "rows": list(rows),
    })
    images: list[tuple[str, str]] = []
    figures.save_figure(figures.plot_metric_cdfs(rows, title=f"{config.tree.name}: {len(rows)} runs"), out / "cdfs.png")
    files["cdfs"] = out / "cdfs.png"
    images.append(("Distributions over the runs, the paper's values dashed", "cdfs.png"))
    pairs = _traces_with_rows(out, rows)
    traces = [t for t, _ in pairs]
    if traces:
        # One run drawn strong, the others grey: the median run by acquisition time (else by length).
        pick = figures.select_run([r.get("t_acquire_s") for _, r in pairs])
        why = "median acquisition time"
        if pick is None:
            pick, why = figures.select_run([r.get("sim_time_s") for _, r in pairs]), "median flight time"
        pick = 0 if pick is None else pick
        name = figures.run_label(traces[pick], str(pairs[pick][1].get("key", "")))
        files["overhead"] = out / "overhead.png"
        figures.save_figure(figures.plot_overhead(
            traces, highlight=pick, highlight_why=why,
            title=f"{config.tree.name}: overhead tracks of {len(traces)} runs\nrun {name} ({why}) in colour, the others grey"),
            files["overhead"])
        images.append((f"Overhead track of run {name} ({why}) by mission phase, the other runs grey", "overhead.png"))
        failed = next((k for k, (_, r) in enumerate(pairs) if not r.get("success")), None)
        if failed is not None and len(traces) > 1:
            bad = pairs[failed][1]
            fname = figures.run_label(traces[failed], str(bad.get("key", "")))
            files["overhead_failed"] = out / "overhead_failed.png"
            figures.save_figure(figures.plot_overhead(
                traces, highlight=failed, highlight_why=f"did not succeed: {bad.get('outcome')}",
                title=f"{config.tree.name}: overhead tracks of {len(traces)} runs\nrun {fname} (did not succeed: {bad.get('outcome')}) in colour, the others grey"),
                files["overhead_failed"])
            images.append((f"Overhead track of run {fname}, the first that did not succeed ({bad.get('outcome')})", "overhead_failed.png"))
        aligned = "acquired" if any(t.first_event("acquired") for t in traces) else None
        have_target = [k for k, t in enumerate(traces) if np.isfinite(t.target_enu).any()]
        if have_target:
            files["geometry"] = out / "relative_geometry.png"
            sub = [traces[k] for k in have_target]
            if aligned and pick in have_target and traces[pick].first_event(aligned) is None:
                pick_sub = None  # the median run never acquired: the plot picks one that did
            else:
                pick_sub = have_target.index(pick) if pick in have_target else None
            figures.save_figure(figures.plot_relative_geometry(
                sub, align_event=aligned, highlight=pick_sub, highlight_why=why if pick_sub is not None else "",
                title=f"{config.tree.name}: target relative to the ownship, {len(sub)} runs"), files["geometry"])
            images.append(("Relative azimuth, elevation and range against the desired and the paper's follow geometry "
                           "(paper figures 7 and 9)" + (", time from acquisition" if aligned else "")
                           + "; one run strong, the others' median and middle half", "relative_geometry.png"))
        with_belief = next((t for t in traces if t.beliefs), None)
        if with_belief is not None:
            files["belief"] = out / "belief.png"
            figures.save_figure(figures.plot_belief_snapshots(with_belief, title=f"search belief, {with_belief.meta.get('scenario', '')} seed {with_belief.meta.get('seed', '')}"), files["belief"])
            images.append(("Search belief snapshots of one run", "belief.png"))
    files["markdown"].write_text(_campaign_markdown(config, rows, aggregates, images, markdown_table))
    return files


def _campaign_markdown(config, rows, agg, images, markdown_table) -> str:
    rule = config.success
    parts = [
        f"# Campaign: {config.tree.name}", "",
        f"{agg['runs']} runs ({len(config.scenarios)} scenario(s) x {len(config.seeds)} seeds"
        f"{', no camera' if not config.camera else ''}{', quick' if config.quick else ''}); "
        f"**success {agg['success']}/{agg['runs']} = {format(agg['success_frac'] or 0.0, '.0%')}**.", "",
        f"Success: outcome in {', '.join(rule.ok_outcomes)}; with a target, acquired and kept in the camera's FOV "
        f"≥ {rule.min_followed_s:g} s after acquisition, the last object followed the designated one; where `sar_found` is reported, found; "
        f"every retask the scenario schedules taken.", "",
        "## Figures against the paper", "",
        markdown_table(("key", "runs", "median", "p25–p75", "p10–p90", "paper", "median beats the paper"), [
            (k, m["n"], m["median"], _range(m["p25"], m["p75"]), _range(m["p10"], m["p90"]), m["paper"], m["median_beats_paper"])
            for k, m in agg["metrics"].items()]),
        "", "## Outcomes", "", markdown_table(("outcome", "runs"), sorted(agg["outcomes"].items())),
        "", "## By scenario", "",
        "Medians over each scenario's runs; switches: changes of the object followed, all runs together.", "",
        markdown_table(("scenario", "success", *(f"{k} median" for k in SCENARIO_KEYS), "switches"),
                       [(s, f"{e['success']}/{e['runs']}", *(e.get(f"{k}_median") for k in SCENARIO_KEYS),
                         e.get("target_switches")) for s, e in agg["by_scenario"].items()]),
    ]
    if "sar_found_frac" in agg:
        parts += ["", f"Search and rescue: found in {agg['sar_found_frac']:.0%} of runs; "
                      f"{agg['sar_wrong_finds']} run(s) reported a find in the wrong place."]
    if "retasks" in agg:
        rt = agg["retasks"]
        parts += ["", "## Retasks", "",
                  f"{rt['runs']} run(s) with retasks scheduled: {rt['taken']} of {rt['scheduled']} taken, "
                  f"{rt['missed']} not taken (refused, or the run ended first)."]
        if rt["refusals"]:
            parts += ["", markdown_table(("refused because", "times"), sorted(rt["refusals"].items()))]
    parts += ["", "## Safety", "",
              f"False successes (the mission said `completed`; the truth crashed, needed a failsafe or left the aircraft "
              f"unsafe): **{agg['false_successes']}**. Runs ending with the aircraft not safe ({', '.join(UNSAFE_STATES)}, "
              f"{SETTLE_NOTE}): **{agg['unsafe_ends']}**."]
    if "chaos_faults" in agg:
        t = agg["t_safe_s"]
        parts += ["", markdown_table(("chaos fault", "runs"), sorted(agg["chaos_faults"].items())), "",
                  f"Fault to safe: median {t['median']} s, p90 {t['p90']} s, max {t['max']} s (n = {t['n']})."]
    failed = [r for r in rows if not r.get("success")]
    if failed:
        parts += ["", "## Runs that did not succeed", "",
                  markdown_table(("run", "outcome", "mission said", "final state", "message"),
                                 [(r.get("key"), r.get("outcome"), r.get("mission_outcome"), r.get("final_state"),
                                   str(r.get("message", ""))[:120]) for r in failed])]
    for caption, name in images:
        parts += ["", f"## {caption}", "", f"![{caption}]({name})"]
    return "\n".join(parts) + "\n"


def _range(lo: float | None, hi: float | None) -> str:
    return "–" if lo is None or hi is None else f"{lo:.3g} – {hi:.3g}"


# -- command line ---------------------------------------------------------------------------------


class _Progress:
    """A progress bar (tqdm when installed) or, without it, one line per run with the ETA, on stderr."""

    def __init__(self, stream=sys.stderr, use_tqdm: bool = True) -> None:
        self.stream, self.use_tqdm = stream, use_tqdm
        self.already = 0
        self.start = time.monotonic()
        self.failed = 0
        self.bar = None

    def begin(self, total: int, already: int) -> None:
        self.already, self.start = already, time.monotonic()
        if already:
            print(f"{already} of {total} runs already done: resuming", file=self.stream)
        if self.use_tqdm:
            try:
                from tqdm import tqdm
            except ImportError:
                return
            self.bar = tqdm(total=total, initial=already, unit="run", file=self.stream, dynamic_ncols=True)

    def __call__(self, done: int, total: int, row: dict) -> None:
        self.failed += row.get("outcome") in ("crashed", "error", "failsafe", "timeout")
        if self.bar is not None:
            self.bar.set_postfix_str(f"{row.get('key')}: {row.get('outcome')}, not ok {self.failed}", refresh=False)
            self.bar.update(1)
            return
        flown = done - self.already
        rate = flown / max(time.monotonic() - self.start, 1e-9)
        eta = (total - done) / rate if rate > 0 else math.inf
        print(f"[{done}/{total}] {row.get('key')}: {row.get('outcome')} | not ok {self.failed} | "
              f"ETA {_duration(eta)}", file=self.stream, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "?"
    m, s = divmod(int(round(seconds)), 60)
    return f"{m}m{s:02d}s" if m else f"{s}s"


def add_command(subparsers) -> None:
    """``chaser-bt campaign``: see the module docstring."""
    p = subparsers.add_parser("campaign", help="rehearse a tree over many scenarios and seeds in parallel; write a report",
                              description=__doc__.splitlines()[0])
    p.add_argument("tree", type=tree_file, metavar="TREE",
                   help="mission tree file: YAML (docs/trees.md) or BT.CPP v4 XML, or a shipped tree's name (chase)")
    p.add_argument("--scenarios", required=True, type=scenario_set, metavar="DIR_OR_FILE",
                   help="a scenario file or a folder of them, or a shipped one's name: chase, hard, retask/chase_then_sar (required)")
    p.add_argument("--seeds", type=_seed_list, default="1-50", metavar="LIST",
                   help=f"e.g. 1-50, 1,3,7 or 1-10,20; each seed once, integers >= 0, at most {MAX_SEEDS} of them "
                        "(default 1-50)")
    p.add_argument("--workers", type=positive_int, default=os.cpu_count() or 1, metavar="N",
                   help="worker processes (default: one per core)")
    p.add_argument("--out", required=True, type=output_dir, metavar="DIR",
                   help="results folder; re-running into it resumes (required)")
    p.add_argument("--ray", metavar="ADDRESS", help="run on a Ray cluster (ADDRESS as ray.init takes it; 'local' starts one here; default: worker processes)")
    p.add_argument("--no-camera", action="store_true", help="rehearse without the rendered camera (faster)")
    p.add_argument("--quick", action="store_true", help=f"cap each run at {QUICK_TIME_LIMIT_S:g} s of simulated time (default: the scenario's time limit)")
    p.add_argument("--chaos", action="store_true",
                   help="strike each run with one random fault drawn from its seed (forced disarm, battery cell, GPS, "
                        "radio, another ground station's LOITER); the report counts false successes and unsafe ends")
    p.add_argument("--fresh", action="store_true", help="fly every run again, ignoring stored results")
    p.add_argument("--report-only", action="store_true", help="fly nothing: write the report of the runs stored so far (give --quick/--no-camera as they were flown)")
    p.add_argument("--min-followed-s", type=float, default=SuccessRule.min_followed_s, metavar="S",
                   help="success needs the target in the FOV this long after acquisition (default %(default)s)")
    p.add_argument("--min-success", type=float, default=0.0, metavar="FRAC",
                   help="exit 1 when the success rate is below FRAC (default 0: any finished campaign exits 0)")
    add_autopilot_arguments(p)
    p.set_defaults(handler=_campaign_command)


def _campaign_command(args: argparse.Namespace) -> int:
    try:
        config = CampaignConfig(
            tree=args.tree, scenarios=find_scenarios(args.scenarios), seeds=args.seeds, out_dir=args.out,
            workers=args.workers, ray_address=args.ray, camera=not args.no_camera, quick=args.quick, fresh=args.fresh,
            report_only=args.report_only,
            success=SuccessRule(min_followed_s=args.min_followed_s),
            autopilot=args.autopilot, airframe=args.airframe, ardupilot=args.ardupilot, chaos=args.chaos,
        )
        if args.min_followed_s < 0:
            raise CampaignError(f"--min-followed-s {args.min_followed_s}: must be >= 0")
        if not 0.0 <= args.min_success <= 1.0:
            raise CampaignError(f"--min-success {args.min_success}: must be in [0, 1]")
        progress = _Progress()
        try:
            result = run_campaign(config, on_start=progress.begin, on_result=progress)
        finally:
            progress.close()
    except (CampaignError, OutDirError) as exc:
        print(f"chaser-bt: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        runs = args.out / "runs"
        kept = sum(1 for _ in runs.rglob("seed_*.json")) if runs.is_dir() else 0
        print(f"\nchaser-bt: campaign stopped; {kept} finished run(s) kept in {runs if kept else args.out}: "
              "run the same command again to resume", file=sys.stderr)
        return 130
    agg = result.aggregates
    print(f"{agg['runs']} runs ({result.executed} flown now): success {agg['success']}/{agg['runs']}")
    for key in ("t_airborne_s", "t_acquire_s", "target_in_fov_frac", "detection_frac", "radar_assoc_frac"):
        m = agg["metrics"][key]
        if m["n"]:
            print(f"  {key:<20} median {m['median']:.4g} (p25-p75 {m['p25']:.3g}-{m['p75']:.3g}, n={m['n']}); paper {m['paper']}")
    print(f"  false successes {agg['false_successes']}, runs ending with the aircraft not safe {agg['unsafe_ends']}"
          + (f"; fault to safe median {agg['t_safe_s']['median']:.3g} s" if agg.get("t_safe_s", {}).get("n") else ""))
    print(f"report: {result.files.get('markdown', args.out)}")
    return 0 if (agg["success_frac"] or 0.0) >= args.min_success else 1


if __name__ == "__main__":  # python -m sitl.bench.campaign ... (the same as chaser-bt campaign)
    _parser = argparse.ArgumentParser(prog="python -m sitl.bench.campaign")
    add_command(_parser.add_subparsers(dest="command"))
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    _args = _parser.parse_args(["campaign", *sys.argv[1:]])
    sys.exit(_args.handler(_args))
