"""The record of measurements and the results page made from it.

A small store written here by hand (two benchmarks, one with two runs out of date order) gives the page
these tests expect cell by cell; the same store gives the same bytes; a line that is not a record stops
the generator with one line naming the file and the line; ``--record`` appends the line with its
provenance; every benchmark declares itself and takes ``--record``; the committed page is the store's.
"""

from __future__ import annotations

import ast
import datetime as dt
import importlib.util
import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str, path: Path):
    """A script of tools/ or benchmarks/ as a module (neither is a package)."""
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


page = _load("results_page", ROOT / "tools" / "results_page.py")
record = _load("record", ROOT / "benchmarks" / "record.py")

MACHINE = {"cpu": "Test CPU 9000", "cores": 2, "gpu": "none", "os": "Linux 6.1", "python": "3.11.7"}
NEWER = {
    "benchmark": "demo", "script": "benchmarks/bench_demo.py", "what": "A demonstration benchmark.",
    "against": "built-in simulator",
    "units": {"success_frac": "share of runs that succeed", "t_*": "s, median time", "runs": "runs in all",
              "hard.*.runs": "runs per scenario",
              "plan_ms*": "ms per plan, by horizon", "pos_m": "m, position error"},
    "headline": ["success_frac", "hard.fast.success_frac", "RHC h=5 g=0.9.mean_gain"],
    "command": ".venv/bin/python benchmarks/bench_demo.py --quick --record",
    "commit": "0123456789abcdef0123456789abcdef01234567", "dirty": True, "date_utc": "2026-03-02T10:00:00Z",
    "machine": MACHINE,
    "result": {"name": "demo", "seeds": 4, "success_frac": 0.75, "t_s_median": 12.5, "quick": True, "note": None,
               "hard": {"fast": {"runs": 3, "success_frac": 0.667}, "far": {"runs": 3, "success_frac": 1.0}},
               "plan_ms": {"1": 0.5, "5": 9.25}, "plan_ms_p95": {"1": 0.75, "5": 12.0},
               "pose_err": {"pos_m": 1.5, "yaw_deg": 0.25}, "RHC h=5 g=0.9": {"mean_gain": 0.011, "runs": 2}},
}
OLDER = dict(NEWER, commit="fedcba9876543210fedcba9876543210fedcba98", dirty=False, date_utc="2026-03-01T09:30:00Z",
             command=".venv/bin/python benchmarks/bench_demo.py --seeds 1-50 --record",
             result={"name": "demo", "seeds": 50, "success_frac": 0.5, "t_s_median": 14.0})
ALPHA = dict(NEWER, benchmark="alpha", script="benchmarks/bench_alpha.py", what="", against="ArduCopter SITL",
             units={}, headline=[], command=".venv/bin/python benchmarks/bench_alpha.py --record",
             date_utc="2026-02-01T08:00:00Z", result={"rate_hz": 400, "x_realtime": 12.5, "label": "a|b"})


def _store(folder: Path, lines: dict[str, list]) -> Path:
    """Write a store by hand: file name -> its lines (records as dicts, or raw text)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, rows in lines.items():
        text = "".join((row if isinstance(row, str) else json.dumps(row)) + "\n" for row in rows)
        (folder / f"{name}.jsonl").write_text(text)
    return folder


@pytest.fixture
def store(tmp_path: Path) -> Path:
    return _store(tmp_path / "results", {"demo": [NEWER, OLDER], "alpha": [ALPHA]})


def _lines(text: str) -> list[str]:
    return text.splitlines()


# -- the page ---------------------------------------------------------------------------------------


def test_the_page_says_it_is_generated_and_indexes_every_benchmark(store):
    text = page.render(page.load(store))
    assert text.startswith("# Results\n")
    assert "`python tools/results_page.py` (`make results`)" in text
    lines = _lines(text)
    assert "| [alpha](#alpha) | ArduCopter SITL | 2026-02-01 08:00 | `0123456789+` | 1 |" in lines
    assert "| [demo](#demo) | built-in simulator | 2026-03-02 10:00 | `0123456789+` | 2 |" in lines
    assert text.index("\n## alpha\n") < text.index("\n## demo\n")  # by file name


def test_the_latest_run_is_shown_with_units_and_nested_blocks_as_their_own_tables(store):
    demo = page.render(page.load(store)).split("\n## demo\n")[1]
    lines = _lines(demo)
    assert "Run 2026-03-02T10:00:00Z, the latest of 2." in lines  # the newer run, though first in the file
    for row in ("| `seeds` | 4 |  |",
                "| `success_frac` | 0.75 | share of runs that succeed |",
                "| `t_s_median` | 12.5 | s, median time |",  # a pattern
                "| `quick` | true |  |",
                "| `note` | – |  |"):
        assert row in lines, row
    assert not any(line.startswith("| `name` |") for line in lines)  # the section's own name
    # hard: a row per scenario, a column per figure; the columns' meanings under it (path pattern, then key)
    at = lines.index("#### demo: `hard`")
    assert lines[at + 2:at + 6] == ["|  | `runs` | `success_frac` |", "|---|---|---|",
                                    "| `fast` | 3 | 0.667 |", "| `far` | 3 | 1.0 |"]
    assert lines[at + 7] == "`runs`: runs per scenario; `success_frac`: share of runs that succeed."
    # blocks with the same keys share one table, a row each with its meaning; `*` stays within a key
    at = lines.index("#### demo: `plan_ms`, `plan_ms_p95`")
    assert lines[at + 2:at + 8] == ["|  | `1` | `5` | unit / meaning |", "|---|---|---|---|",
                                    "| `plan_ms` | 0.5 | 9.25 | ms per plan, by horizon |",
                                    "| `plan_ms_p95` | 0.75 | 12.0 | ms per plan, by horizon |", "",
                                    "#### demo: `pose_err`"]  # no note for the columns `1`, `5`: plan_ms* is not plan_ms.1
    at = lines.index("#### demo: `pose_err`")
    assert lines[at + 4:at + 6] == ["| `pos_m` | 1.5 | m, position error |", "| `yaw_deg` | 0.25 |  |"]


def test_how_it_was_measured_and_the_runs_newest_first(store):
    demo = page.render(page.load(store)).split("\n## demo\n")[1]
    lines = _lines(demo)
    assert ("Script: [`benchmarks/bench_demo.py`](../benchmarks/bench_demo.py). "
            "Measured against: **built-in simulator**.") in lines
    for row in ("| command | `.venv/bin/python benchmarks/bench_demo.py --quick --record` |",
                "| commit | `0123456789abcdef0123456789abcdef01234567` (with uncommitted changes) |",
                "| date (UTC) | 2026-03-02T10:00:00Z |",
                "| machine | Test CPU 9000, 2 cores, GPU: none; Linux 6.1, Python 3.11.7 |",
                "| measured against | built-in simulator |"):
        assert row in lines, row
    at = lines.index("| date (UTC) | commit | options | machine | `success_frac` | `hard.fast.success_frac` | "
                     "`RHC h=5 g=0.9.mean_gain` |")
    assert lines[at + 2:at + 4] == [  # a key may hold dots itself
        "| 2026-03-02 10:00 | `0123456789+` | `--quick` | Test CPU 9000 ×2 | 0.75 | 0.667 | 0.011 |",
        "| 2026-03-01 09:30 | `fedcba9876` | `--seeds 1-50` | Test CPU 9000 ×2 | 0.5 | – | – |",  # no blocks then
    ]


def test_a_benchmark_without_headline_keys_shows_its_first_numbers_and_cells_stay_cells(store):
    alpha = page.render(page.load(store)).split("\n## alpha\n")[1].split("\n## ")[0]
    lines = _lines(alpha)
    assert "| `label` | a\\|b |  |" in lines  # a pipe would split the cell
    assert "| date (UTC) | commit | options | machine | `rate_hz` | `x_realtime` |" in lines
    assert "| 2026-02-01 08:00 | `0123456789+` | – | Test CPU 9000 ×2 | 400 | 12.5 |" in lines
    assert "A demonstration" not in alpha  # its own, empty, description


def test_the_same_store_gives_the_same_bytes(store, tmp_path):
    first = page.render(page.load(store))
    assert page.render(page.load(store)) == first
    again = _store(tmp_path / "again", {"alpha": [ALPHA], "demo": [NEWER, OLDER]})  # written in another order
    assert page.render(page.load(again)) == first
    out = tmp_path / "results.md"
    assert page.main(["--results", str(store), "--out", str(out)]) == 0
    written = out.read_bytes()
    assert page.main(["--results", str(store), "--out", str(out)]) == 0
    assert out.read_bytes() == written == first.encode()
    assert page.main(["--results", str(store), "--out", str(out), "--check"]) == 0
    _store(store, {"alpha": [ALPHA, dict(ALPHA, date_utc="2026-02-02T08:00:00Z")]})
    assert page.main(["--results", str(store), "--out", str(out), "--check"]) == 1  # the page is stale now


def test_an_empty_store_says_so(tmp_path):
    assert "No benchmark has been recorded yet." in page.render(page.load(tmp_path))


@pytest.mark.parametrize("bad,why", [
    ("{not json", "demo.jsonl:2: not JSON"),
    ("[1, 2]", "demo.jsonl:2: not a JSON object"),
    (json.dumps({k: v for k, v in OLDER.items() if k != "result"}), "demo.jsonl:2: not a record, no result"),
    (json.dumps(dict(OLDER, date_utc=20260301)), "demo.jsonl:2: 'date_utc' is not a JSON string"),
    (json.dumps(dict(OLDER, benchmark="other")), "demo.jsonl:2: a record of 'other' in demo.jsonl"),
], ids=["not json", "not an object", "no result", "a date not text", "another benchmark's"])
def test_a_line_that_is_not_a_record_stops_the_page_naming_file_and_line(tmp_path, capsys, bad, why):
    store = _store(tmp_path / "results", {"demo": [NEWER, bad, OLDER]})
    out = tmp_path / "results.md"
    assert page.main(["--results", str(store), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("results_page: error: ") and why in err, err
    assert not out.exists()
    with pytest.raises(page.ResultsError, match=why.split(":", 1)[0] + ":2"):
        page.load(store)


# -- the record -------------------------------------------------------------------------------------


def test_record_appends_the_line_and_its_provenance(tmp_path, capsys):
    bench = record.Benchmark("tiny", "A tiny benchmark: sums.\n\nMore that is not shown.", against="plain arithmetic",
                             units={"total": "the sum"}, headline=("total",))
    results, out = tmp_path / "results", tmp_path / "results.md"
    argv = [str(ROOT / "benchmarks" / "bench_tiny.py"), "--n", "3", "--record"]
    before = dt.datetime.now(dt.timezone.utc).replace(microsecond=0)
    for n in (3, 4):
        record.emit({"name": "tiny", "total": sum(range(n))}, bench, True, argv=argv, results=results, page=out)
    after = dt.datetime.now(dt.timezone.utc)
    printed = capsys.readouterr().out.splitlines()
    assert [json.loads(p) for p in printed] == [{"name": "tiny", "total": 3}, {"name": "tiny", "total": 6}]
    rows = [json.loads(r) for r in (results / "tiny.jsonl").read_text().splitlines()]
    assert [r["result"]["total"] for r in rows] == [3, 6]  # one line per run, newest last
    row = rows[-1]
    assert row["benchmark"] == "tiny" and row["script"] == "benchmarks/bench_tiny.py"
    assert row["what"] == "A tiny benchmark: sums." and row["against"] == "plain arithmetic"
    assert row["units"] == {"total": "the sum"} and row["headline"] == ["total"]
    python = os.path.relpath(sys.executable, ROOT) if Path(sys.executable).is_relative_to(ROOT) else sys.executable
    assert shlex.split(row["command"]) == [python, "benchmarks/bench_tiny.py", "--n", "3", "--record"]
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    assert row["commit"] == head and isinstance(row["dirty"], bool)
    when = dt.datetime.strptime(row["date_utc"], "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=dt.timezone.utc)
    assert before <= when <= after
    assert row["machine"]["cores"] == os.cpu_count() and row["machine"]["cpu"]
    assert row["machine"]["gpu"] == "none" or "nvidia-smi" not in row["machine"]["gpu"]
    # ... and the page was written from the store
    text = out.read_text()
    assert "| [tiny](#tiny) | plain arithmetic |" in text and "| `total` | 6 | the sum |" in text


def test_a_record_names_the_commit_it_started_from_and_calls_a_change_under_it_dirty(monkeypatch):
    """A run that started on one commit and ended on another was measured on neither alone: the record
    keeps the commit it started from, and says dirty."""
    bench = record.Benchmark("tiny", "A tiny benchmark.", against="plain arithmetic")
    monkeypatch.setattr(record, "_AT_START", (("0" * 40, False), "2026-01-01T00:00:00Z"))
    row = record.make_record({"name": "tiny"}, bench, argv=["benchmarks/bench_tiny.py"])
    assert row["commit"] == "0" * 40 and row["dirty"] is True and row["started_utc"] == "2026-01-01T00:00:00Z"


def test_without_record_the_line_is_only_printed(tmp_path, capsys):
    bench = record.Benchmark("tiny", "Tiny.", against="plain arithmetic")
    assert record.emit({"total": 1}, bench, False, results=tmp_path / "results", page=tmp_path / "p.md") is None
    assert capsys.readouterr().out == '{"total": 1}\n'
    assert not (tmp_path / "results").exists() and not (tmp_path / "p.md").exists()


def test_the_tree_is_dirty_when_code_differs_from_the_commit_not_when_the_store_grows(tmp_path):
    repo = tmp_path / "repo"

    def git(*args):
        subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True)

    (repo / "benchmarks" / "results").mkdir(parents=True)
    git("init", "-q")
    (repo / "code.py").write_text("x = 1\n")
    (repo / "benchmarks" / "results" / "tiny.jsonl").write_text("{}\n")
    git("add", ".")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "one")
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True, text=True).stdout.strip()
    assert record.git_state(repo) == (head, False)
    (repo / "benchmarks" / "results" / "tiny.jsonl").write_text("{}\n{}\n")  # a run recorded
    (repo / "new.py").write_text("")  # untracked: not what the commit names
    assert record.git_state(repo) == (head, False)
    (repo / "code.py").write_text("x = 2\n")
    assert record.git_state(repo) == (head, True)
    (tmp_path / "plain").mkdir()
    assert record.git_state(tmp_path / "plain") == (None, None)  # no repository: said, not raised


# -- the benchmarks and the committed page ----------------------------------------------------------

SCRIPTS = sorted(ROOT.glob("benchmarks/bench_*.py")) + [ROOT / "benchmarks" / f"{n}.py" for n in
                                                        ("search_belief_gain", "search_open_question", "search_sitl_belief_gain")]


@pytest.mark.parametrize("script", SCRIPTS, ids=[s.stem for s in SCRIPTS])
def test_every_benchmark_declares_itself_and_takes_record(script):
    tree = ast.parse(script.read_text())
    declared = [n.value for n in tree.body if isinstance(n, ast.Assign)
                and any(isinstance(t, ast.Name) and t.id == "BENCHMARK" for t in n.targets)]
    assert len(declared) == 1, f"{script.name}: no BENCHMARK = Benchmark(...)"
    call = declared[0]
    assert isinstance(call, ast.Call) and call.func.id == "Benchmark"
    assert ast.literal_eval(call.args[0]) == script.stem.removeprefix("bench_")  # its store's name
    against = next(k.value for k in call.keywords if k.arg == "against")
    assert ast.literal_eval(against).strip()
    names = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
    assert {"add_record_flag", "emit"} <= names
    dumps_printed = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)
                     and n.func.id == "print" and n.args and "json.dumps" in ast.unparse(n.args[0])
                     and not any(k.arg == "file" for k in n.keywords)]
    assert not dumps_printed, f"{script.name} prints a JSON line past emit()"


def test_the_store_is_readable_and_the_committed_page_is_the_stores():
    store = page.load(page.RESULTS)
    for name, records in store.items():
        for r in records:
            assert r.data["benchmark"] == name and r.data["command"].split()[1] == r.data["script"], r.source
    assert page.PAGE.read_text() == page.render(store), "docs/results.md is stale or edited: run `make results`"


def test_the_site_serves_the_page_as_the_store_makes_it():
    site = _load("docs_site", ROOT / "tools" / "docs_site.py")
    served = site.results_page()
    assert served.startswith("# Results\n")
    assert "](../benchmarks/" not in served  # links to the scripts made servable
