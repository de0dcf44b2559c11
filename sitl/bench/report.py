"""One rehearsal's report on disk: ``report.json``, ``report.md``, the trace and the paper's figures.

``write_rehearsal_report(report, out_dir)`` is what ``make demo`` and ``chaser-bt rehearse --report
DIR`` call after a rehearsal: the DESIGN §7 keys beside the paper's values (section 4), and, when the
rehearsal kept a :class:`~chaser_bt.log.trace.FlightTrace`, ``trace.npz`` plus PNGs drawn by
:mod:`chaser_bt.log.figures` (overhead track, relative geometry as in figures 7 and 9, belief maps)
and, where the trace kept camera frames, ``rehearsal.gif`` (:mod:`chaser_bt.log.animation`: the
camera with the detector's box beside the overhead track, around the acquisition).
The campaign report (:mod:`sitl.bench.campaign`) shares the table helpers here.
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path
from typing import Any, Mapping, Sequence

from chaser_bt.log.figures import PAPER_VALUES
from chaser_bt.log.trace import FlightTrace

log = logging.getLogger(__name__)

__all__ = ["DESIGN_KEYS", "LOWER_IS_BETTER", "format_value", "markdown_table", "write_rehearsal_report", "write_json"]

#: The keys of DESIGN §7 a rehearsal reports (None where they do not apply).
DESIGN_KEYS: tuple[str, ...] = (
    "outcome", "sim_time_s", "wall_time_s", "t_airborne_s", "t_acquire_s", "target_in_fov_frac",
    "detection_frac", "radar_assoc_frac", "wrong_assoc_frac", "landed_dist_m",
)

#: Figures where smaller beats the paper (times, wrong associations); the other fractions are better larger.
LOWER_IS_BETTER: frozenset[str] = frozenset({"t_airborne_s", "t_acquire_s", "wrong_assoc_frac", "landed_dist_m"})


def format_value(value: Any) -> str:
    """A report value for a Markdown cell: None as a dash, floats to 4 significant digits."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return "–" if math.isnan(value) else f"{value:.4g}"
    return str(value)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A GitHub-flavoured Markdown table (cells through :func:`format_value`)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(format_value(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def beats_paper(key: str, value: float | None) -> bool | None:
    """Whether ``value`` of ``key`` is better than the paper's (None where the paper has no value or no value came)."""
    if value is None or key not in PAPER_VALUES or not math.isfinite(value):
        return None
    return value < PAPER_VALUES[key] if key in LOWER_IS_BETTER else value > PAPER_VALUES[key]


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as indented JSON atomically (a temporary file renamed over ``path``)."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=2, default=_json_default) + "\n")
    tmp.replace(path)


def _json_default(obj: Any) -> Any:
    if hasattr(obj, "item"):  # numpy scalars
        return obj.item()
    if hasattr(obj, "tolist"):
        return obj.tolist()
    return str(obj)


def _report_dict(report: Any) -> dict:
    data = report.to_dict() if hasattr(report, "to_dict") else dict(report)
    data.pop("trace", None)  # the trace goes to its own file
    return data


def write_rehearsal_report(report: Any, out_dir: str | Path, trace: FlightTrace | None = None) -> dict[str, Path]:
    """Write ``report.json``, ``report.md`` and, with a trace, ``trace.npz`` and the figures into ``out_dir``.

    Args:
        report: a :class:`sitl.bench.rehearsal.RehearsalReport` (or its ``to_dict()``).
        out_dir: created if missing; files in it of the same names are replaced.
        trace: the flight's trace; defaults to ``report.trace`` when the report carries one.

    Returns:
        The written files by kind (``json``, ``markdown``, ``trace``, ``overhead``, ``geometry``, ``belief``,
        ``animation``: ``rehearsal.gif``, where the trace kept camera frames).
    """
    from chaser_bt.log import figures

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    data = _report_dict(report)
    if trace is None:
        trace = getattr(report, "trace", None)
    written: dict[str, Path] = {"json": out / "report.json", "markdown": out / "report.md"}
    write_json(written["json"], data)

    images: list[tuple[str, str]] = []
    if trace is not None and len(trace):
        written["trace"] = trace.save(out / "trace.npz")
        label = f"{data.get('tree', '')} / {data.get('scenario', '')} / seed {data.get('seed', '')}"
        written["overhead"] = out / "overhead.png"
        figures.save_figure(figures.plot_overhead([trace], title=f"overhead track: {label}"), written["overhead"])
        images.append(("Overhead track (phases coloured, events marked)", "overhead.png"))
        written["geometry"] = out / "relative_geometry.png"
        figures.save_figure(figures.plot_relative_geometry([trace], title=f"target relative to the ownship: {label}"), written["geometry"])
        images.append(("Relative azimuth, elevation and range against the desired and the paper's follow geometry "
                       "(paper figures 7 and 9), with the phases, target-in-FOV and detection intervals", "relative_geometry.png"))
        if trace.beliefs:
            written["belief"] = out / "belief.png"
            figures.save_figure(figures.plot_belief_snapshots(trace, title=f"search belief: {label}"), written["belief"])
            images.append(("Search belief snapshots", "belief.png"))
        if trace.frames:
            from chaser_bt.log.animation import write_animation

            try:
                written["animation"] = write_animation(trace, out / "rehearsal.gif", title=label)
            except Exception:  # the numbers and the still figures stand without it
                log.exception("could not write the rehearsal's animation")
            else:
                t0, t1 = trace.frames[0].t, trace.frames[-1].t
                images.insert(0, (f"The camera with the detector's box beside the overhead track, mission time "
                                  f"{t0:.1f}-{t1:.1f} s (animated)", "rehearsal.gif"))
    written["markdown"].write_text(_rehearsal_markdown(data, trace, images))
    return written


def _rehearsal_markdown(data: Mapping[str, Any], trace: FlightTrace | None, images: list[tuple[str, str]]) -> str:
    title = f"# Rehearsal: {data.get('tree', '?')} on {data.get('scenario', '?')}, seed {data.get('seed', '?')}"
    rows = []
    for key in DESIGN_KEYS:
        if key in data:
            rows.append((key, data[key], PAPER_VALUES.get(key), beats_paper(key, data[key]) if key != "outcome" else None))
    parts = [title, "", f"Outcome **{data.get('outcome', '?')}**: {data.get('message', '')}".rstrip(": "), "",
             markdown_table(("key", "this run", "paper", "better than the paper"), rows)]
    others = [(k, v) for k, v in data.items() if k not in DESIGN_KEYS and not isinstance(v, (dict, list))]
    if others:
        parts += ["", "## Other figures", "", markdown_table(("key", "value"), others)]
    followed = data.get("followed_s_by_object")
    if followed:
        designated = data.get("designated_object")
        parts += ["", "## Who was followed", "",
                  f"The mission designated **{designated or 'no target'}**; seconds of the follow phase each object was "
                  f"followed (the camera's estimate matched it):", "",
                  markdown_table(("object", "followed (s)", "designated"), [(k, v, k == designated) for k, v in followed.items()])]
    if trace is not None and trace.events:
        parts += ["", "## Events", "",
                  "Times are mission time, from the start of the rehearsal (`t_airborne_s` counts from the radar validation).", "",
                  markdown_table(("mission time (s)", "event", "detail"), [(e.t, e.name, e.detail) for e in trace.events])]
    for caption, name in images:
        parts += ["", f"## {caption}", "", f"![{caption}]({name})"]
    return "\n".join(parts) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m sitl.bench.report TREE --scenario FILE [--seed N] --out DIR``: rehearse with every sensor and write the report.

    What ``make demo`` runs. Exit 0 when the mission ended well (landed, following, completed), 1
    otherwise, 2 on a bad tree or scenario.
    """
    import argparse
    import os
    import sys

    os.environ.setdefault("MAVLINK20", "1")
    parser = argparse.ArgumentParser(prog="python -m sitl.bench.report", description=main.__doc__.splitlines()[0])
    parser.add_argument("tree", type=Path)
    parser.add_argument("--scenario", required=True, type=Path)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", required=True, type=Path)
    args = parser.parse_args(argv)
    from chaser_bt.tree import TreeError, load_tree
    from sitl.bench.rehearsal import rehearse
    from sitl.world.scenario import ScenarioError, load_scenario

    try:
        tree, scenario = load_tree(args.tree), load_scenario(args.scenario)
    except (TreeError, ScenarioError, OSError) as exc:
        print(f"python -m sitl.bench.report: {exc}", file=sys.stderr)
        return 2
    report = rehearse(tree, scenario, args.seed, trace=True)
    files = write_rehearsal_report(report, args.out)
    print(f"{report.outcome}: {report.message}\nreport: {files['markdown']}")
    return 0 if report.outcome in ("landed", "following", "completed") else 1


if __name__ == "__main__":
    raise SystemExit(main())
