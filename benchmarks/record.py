"""The record of measurements: a benchmark run with ``--record`` appends its JSON line, and how it was measured.

Each benchmark declares itself once (:class:`Benchmark`: its name, what it measures, what its figures are
measured against, the units or definitions of its keys and its headline keys) and ends with :func:`emit`,
which prints its one JSON line on stdout as before and, with ``--record``, appends one record to
``benchmarks/results/<name>.jsonl`` (newest last):

- ``benchmark``, ``script``, ``what``, ``against``, ``units``, ``headline``: the declaration;
- ``command``: the command line as run, from the repository root;
- ``commit`` and ``dirty``: ``git rev-parse HEAD`` when the run started (this module's import), and whether
  tracked files differed from it then or at the end, or another commit was checked out by the end (the
  store itself and the page made from it aside): a run spans minutes, and code changed under it is not
  the commit's;
- ``started_utc``, ``date_utc``: when the run started and ended, ISO 8601 to the second;
- ``machine``: ``cpu`` (model), ``cores``, ``gpu`` (``nvidia-smi``'s names, or ``none``), ``os``, ``python``;
- ``result``: the JSON line, as an object.

:func:`emit` then writes docs/results.md again from the whole store (``tools/results_page.py``, also
``make results``), so the committed page is the record's.
"""

from __future__ import annotations

import argparse
import datetime as dt
import importlib.util
import json
import logging
import os
import platform
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
PAGE = ROOT / "docs" / "results.md"
NOT_CODE = ("benchmarks/results", "docs/results.md")  # what a record changes: not what makes a tree dirty
log = logging.getLogger("benchmarks.record")


def _utc_now() -> str:
    return dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


@dataclass(frozen=True)
class Benchmark:
    """A benchmark's declaration: what its figures are, and what they are measured against.

    ``name`` names the store (``benchmarks/results/<name>.jsonl``); ``what`` says what it measures (a
    docstring is cut to its first paragraph); ``against`` what the figures are measured against, in the
    benchmark's own words ("built-in simulator", "ArduCopter SITL"); ``units`` a unit or definition per key:
    a key (``plan_ms``, wherever it appears in the line), a dotted path into the line
    (``hard.*.success_frac``), either with ``fnmatch`` wildcards that stay within one part (``ap50_*``);
    ``headline`` the keys (dotted paths allowed) a run's history shows.
    """

    name: str
    what: str
    against: str
    units: dict[str, str] = field(default_factory=dict)
    headline: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "what", first_paragraph(self.what))


def first_paragraph(text: str) -> str:
    """A docstring's first paragraph on one line."""
    return " ".join(text.strip().split("\n\n")[0].split())


def add_record_flag(parser: argparse.ArgumentParser) -> None:
    """``--record``: also append the line and its provenance to benchmarks/results/<name>.jsonl."""
    parser.add_argument("--record", action="store_true",
                        help="also append the line, with how it was measured, to benchmarks/results/<name>.jsonl, "
                             "and write docs/results.md again from those")


def emit(line: dict, benchmark: Benchmark, record: bool, *, script: str | None = None, argv: list[str] | None = None,
         ensure_ascii: bool = True, results: Path = RESULTS, page: Path | None = PAGE) -> dict | None:
    """Print ``line`` as the benchmark's one JSON line; with ``record``, append its record to ``results``, write
    ``page`` again from the store (None: not) and return the record.

    ``script`` (default: the running program) and ``argv`` (default ``sys.argv``) make the command line.
    """
    print(json.dumps(line, ensure_ascii=ensure_ascii), flush=True)
    if not record:
        return None
    entry = make_record(line, benchmark, script=script, argv=argv)
    path = append(entry, results)
    log.info("recorded %s in %s", benchmark.name, path)
    if page is not None:
        write_page(results, page)
    return entry


def make_record(line: dict, benchmark: Benchmark, *, script: str | None = None, argv: list[str] | None = None,
                root: Path = ROOT) -> dict:
    """The record of one run: the declaration, the provenance and the line."""
    argv = list(sys.argv if argv is None else argv)
    script = script or (argv[0] if argv else "")
    commit, dirty = _AT_START[0] if root == ROOT else git_state(root)
    end_commit, end_dirty = git_state(root)
    dirty = None if dirty is None else bool(dirty or end_dirty or end_commit != commit)
    return {
        "benchmark": benchmark.name,
        "script": _from_root(script, root),
        "what": benchmark.what,
        "against": benchmark.against,
        "units": dict(benchmark.units),
        "headline": list(benchmark.headline),
        "command": command_line(argv, root),
        "commit": commit,
        "dirty": dirty,
        "started_utc": _AT_START[1],
        "date_utc": _utc_now(),
        "machine": machine(),
        "result": line,
    }


def append(entry: dict, results: Path = RESULTS) -> Path:
    """Append ``entry`` as one line to ``results/<benchmark>.jsonl``; the file's path."""
    results.mkdir(parents=True, exist_ok=True)
    path = results / f"{entry['benchmark']}.jsonl"
    with path.open("a", encoding="utf-8") as out:
        out.write(json.dumps(entry, ensure_ascii=False) + "\n")
    return path


def write_page(results: Path = RESULTS, page: Path = PAGE) -> bool:
    """Write ``page`` from the store (tools/results_page.py); whether it was written. A failure is logged, not
    raised: the run is recorded either way, and ``make results`` says what is wrong."""
    try:
        spec = importlib.util.spec_from_file_location("results_page", ROOT / "tools" / "results_page.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # its dataclasses look their module up
        spec.loader.exec_module(module)
        page.write_text(module.render(module.load(results)), encoding="utf-8")
    except Exception as exc:  # noqa: BLE001 - the measurement is kept whatever the page's trouble
        log.warning("%s not written: %s", page, exc)
        return False
    return True


def command_line(argv: list[str], root: Path = ROOT) -> str:
    """``argv`` as a shell command from the repository root: the interpreter, the script, its arguments."""
    python = _from_root(sys.executable, root)
    if not argv:
        return python
    return shlex.join([python, _from_root(argv[0], root), *argv[1:]])


def git_state(root: Path = ROOT) -> tuple[str | None, bool | None]:
    """(the commit checked out, whether tracked files differ from it); (None, None) outside git."""

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, check=True, timeout=30).stdout

    try:
        commit = git("rev-parse", "HEAD").strip()
        changed = git("status", "--porcelain", "--untracked-files=no", "--", ".",
                      *(f":(exclude){p}" for p in NOT_CODE)).strip()
    except (OSError, subprocess.SubprocessError) as exc:
        log.warning("no git state for the record: %s", exc)
        return None, None
    return commit, bool(changed)


def machine() -> dict:
    """The CPU model, its cores, the GPUs ``nvidia-smi`` names (or ``none``), the OS and Python."""
    return {"cpu": cpu_model(), "cores": os.cpu_count(), "gpu": gpu_names(), "os": f"{platform.system()} {platform.release()}",
            "python": platform.python_version()}


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo on Linux, else what the platform says)."""
    try:
        for text in Path("/proc/cpuinfo").read_text().splitlines():
            if text.lower().startswith(("model name", "hardware")):
                return text.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def gpu_names() -> str:
    """``nvidia-smi``'s GPU names and memory, comma-separated; ``none`` without it or without a GPU."""
    smi = shutil.which("nvidia-smi")
    if smi is None:
        return "none"
    try:
        done = subprocess.run([smi, "--query-gpu=name,memory.total", "--format=csv,noheader"], capture_output=True,
                              text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return "none"
    names = [" ".join(row.split()) for row in done.stdout.splitlines() if row.strip()]
    return "; ".join(names) if done.returncode == 0 and names else "none"


def _from_root(path: str, root: Path) -> str:
    """``path`` relative to the repository root where it lies inside it, else as given."""
    if not path or path == "-c":
        return path
    full = Path(path).absolute()
    try:
        return full.relative_to(root).as_posix()
    except ValueError:
        return path


_AT_START = (git_state(ROOT), _utc_now())  # the checkout a benchmark starts from, when it imports this module
