"""``chaser-bt replay LOG TREE``, ``plot LOG``, ``btlog LOG TREE``; the ``--record`` / ``--live`` / ``--btlog`` flags of run and rehearse.

``replay`` ticks a tree on a recorded flight (docs/logs.md) and prints its status changes, the
radar correlator's associations and the target cues and estimates the tree wrote, each compared with
the recording; ``--json`` prints one object. With ``--check`` it exits 1 unless all three are exactly
as recorded. ``plot`` draws the paper's figures
from a log into PNG files. ``btlog`` writes a log as a Groot2 log (``.btlog``, BT.CPP's FileLogger2) by
replaying it; it exits 1 if the replay's status changes are not the recorded ones. Bad input (no such
file, not a log, an invalid tree) exits 2.

The lead wires recording into ``run`` and ``rehearse`` with :func:`add_recording_arguments` and
:class:`RecordingHook`::

    hook = RecordingHook.from_args(args)          # None without --record / --live / --btlog; RecordingError: exit 2
    # run:      runner.setup(); hook(runner, link, runner.resources) ... finally: hook.close()
    # rehearse: rehearse(..., on_start=hook)      ... finally: hook.close()
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, Mapping

from chaser_bt.cli_args import listen_port, output_dir, output_file

__all__ = ["add_command", "add_recording_arguments", "RecordingError", "RecordingHook", "run_replay", "run_plot",
           "run_btlog"]

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2
DEFAULT_PORT = 8765  # chaser_bt.log.live.DEFAULT_PORT, kept here so that every CLI start need not load foxglove


def add_command(subparsers) -> None:
    """Add ``replay`` and ``plot`` to the ``chaser-bt`` sub-commands."""
    p = subparsers.add_parser("replay", help="tick a tree on a recorded flight (MCAP) and compare with the recording",
                              description="Feed a recorded flight's telemetry, radar datagrams and camera frames into a "
                                          "tree; print its status changes and the correlator's associations.")
    p.add_argument("log", type=Path, metavar="LOG", help="flight log (.mcap) written with --record")
    p.add_argument("tree", type=Path, metavar="TREE", help="tree to tick (the recorded one, or a changed one)")
    p.add_argument("--correlator", choices=("gated", "alg1"),
                   help="re-run the radar with this correlator: gated (ours) or alg1 (the paper's Algorithm 1; default: as recorded)")
    p.add_argument("--check", action="store_true",
                   help="exit 1 unless status changes, associations and target cues are exactly as recorded (a "
                        "detector re-run on JPEG frames may differ: record with --record-frames png for an exact replay)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=run_replay)

    p = subparsers.add_parser("plot", help="draw the paper's figures from a flight log",
                              description="Draw the overhead track, the relative geometry and the belief maps of a "
                                          "recorded flight as PNG files.")
    p.add_argument("log", type=Path, metavar="LOG", help="flight log (.mcap)")
    p.add_argument("--out", type=output_dir, metavar="DIR", help="folder for the PNGs (default: LOG without .mcap, plus _plots)")
    p.set_defaults(handler=run_plot)

    p = subparsers.add_parser("btlog", help="write a recorded flight (MCAP) as a Groot2 log (.btlog) by replaying it",
                              description="Replay a recorded flight through its tree and write every status transition "
                                          "as BT.CPP's FileLogger2 does (.btlog: Groot2's log player opens it).")
    p.add_argument("log", type=Path, metavar="LOG", help="flight log (.mcap) written with --record")
    p.add_argument("tree", type=Path, metavar="TREE", help="the tree that flew it")
    p.add_argument("-o", "--out", type=_btlog_file, metavar="FILE.btlog", help="the Groot2 log (default: LOG with .btlog)")
    p.set_defaults(handler=run_btlog)


def _btlog_file(text: str) -> Path:
    """A ``.btlog`` file to write (Groot2 and BT.CPP's FileLogger2 open no other suffix)."""
    path = output_file(text)
    if path.suffix != ".btlog":
        raise argparse.ArgumentTypeError(f"{path}: a Groot2 log must end in .btlog (Groot2 opens no other)")
    return path


def _bad_input(exc: Exception, tree: Any) -> int:
    """One line for a log, tree or file that cannot be read; the bad-input exit code."""
    if isinstance(exc, OSError):
        print(f"chaser-bt: {exc.filename or tree}: {exc.strerror or exc}", file=sys.stderr)
    else:
        print(f"chaser-bt: {exc}", file=sys.stderr)
    return EXIT_BAD_INPUT


def add_recording_arguments(parser: argparse.ArgumentParser) -> None:
    """``--record FILE.mcap``, ``--record-frames``, ``--live [PORT]``, ``--btlog FILE.btlog`` for ``run`` and ``rehearse``."""
    parser.add_argument("--record", type=output_file, metavar="FILE.mcap",
                        help="record the flight to an MCAP file (opens in Foxglove; `chaser-bt replay`, `chaser-bt plot`; "
                             "default: no recording)")
    parser.add_argument("--record-frames", choices=("jpeg", "png"), default="jpeg",
                        help="camera frames: jpeg, 5 per second (default), or png, every frame (lossless: replay "
                             "re-runs the detector exactly)")
    parser.add_argument("--live", type=listen_port, nargs="?", const=DEFAULT_PORT, metavar="PORT",
                        help=f"serve the flight live to Foxglove on ws://127.0.0.1:PORT (PORT default {DEFAULT_PORT}, 0: any free one; "
                             "default: no live view)")
    parser.add_argument("--btlog", type=_btlog_file, metavar="FILE.btlog",
                        help="write every status transition of the tree as BT.CPP's FileLogger2 does: the flight opens "
                             "in Groot2's log player (default: none)")


class RecordingError(ValueError):
    """``--record`` or ``--live`` cannot work (no such folder, port taken): bad input, before anything flies."""


class RecordingHook:
    """Attaches a recorder (file and/or live view) and a Groot2 log writer (``--btlog``) when called with
    ``(runner, link or vehicle, resources)``.

    The call signature is the rehearsal's ``on_start``; ``chaser-bt run`` calls it after
    ``runner.setup()``. :meth:`close` (always, in a ``finally``) finishes the file and stops the server.
    """

    def __init__(self, record: Path | None, live_port: int | None, frame_format: str = "jpeg",
                 btlog: Path | None = None) -> None:
        """Checks the file's folder and starts the live server at once, so a mistake stops the command
        before it connects to a vehicle.

        Raises:
            RecordingError: the folder of ``record`` does not exist, or the live server cannot start.
        """
        from chaser_bt.log.live import LiveSink, LiveViewError

        self.record, self.live_port, self.frame_format = record, live_port, frame_format
        self.recorder = None
        self.live = None
        self.btlog, self.btlog_writer = btlog, None
        for flag, path in (("--record", record), ("--btlog", btlog)):
            if path is not None and not Path(path).parent.is_dir():
                raise RecordingError(f"{flag} {path}: no such folder {Path(path).parent}")
        if live_port is not None:
            try:
                self.live = LiveSink(live_port)
            except LiveViewError as exc:
                raise RecordingError(f"--live {live_port}: {exc}") from None
            print(f"live view: open ws://127.0.0.1:{self.live.port} in Foxglove", file=sys.stderr)

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> RecordingHook | None:
        record, live, btlog = getattr(args, "record", None), getattr(args, "live", None), getattr(args, "btlog", None)
        if record is None and live is None and btlog is None:
            return None
        return cls(record, live, getattr(args, "record_frames", "jpeg"), btlog)

    def __call__(self, runner: Any, link_or_vehicle: Any, resources: Mapping[str, Any] | None = None) -> None:
        if self.btlog is not None:
            from chaser_bt.log.groot2.btlog import BtlogWriter

            self.btlog_writer = BtlogWriter(runner.tree, self.btlog).attach(runner)
        if self.record is None and self.live is None:
            return
        from chaser_bt.log.recorder import attach_recorder

        link = getattr(link_or_vehicle, "link", link_or_vehicle)
        self.recorder = attach_recorder(
            runner, link, runner.resources if resources is None else resources, self.record,
            sinks=[self.live] if self.live is not None else [],
            frame_format=self.frame_format, frame_period_s=0.0 if self.frame_format == "png" else 0.2,
        )

    def close(self) -> None:
        try:
            if self.btlog_writer is not None:
                self.btlog_writer.close()
        finally:
            if self.recorder is not None:
                self.recorder.close()
            elif self.live is not None:
                self.live.close()


def run_replay(args: argparse.Namespace) -> int:
    from chaser_bt.log import schemas as S
    from chaser_bt.log.recorder import TopicSink, attach_recorder
    from chaser_bt.log.replay import (LogError, read_log, recorded_associations, recorded_camera_factory,
                                      recorded_status_changes, replay)
    from chaser_bt.tree import TreeError, load_tree

    targets = TopicSink(S.TOPIC_TARGET)
    recorders: list = []

    def keep_targets(runner: Any, link: Any, resources: Any) -> None:  # no file, no frames: the cues only
        recorders.append(attach_recorder(runner, link, resources, None, sinks=[targets], frame_period_s=float("inf")))

    try:
        log = read_log(args.log)
        tree = load_tree(args.tree)
        try:
            result = replay(log, tree, correlator=args.correlator, camera_factory=recorded_camera_factory(log),
                            on_start=keep_targets)
        finally:
            for recorder in recorders:
                recorder.close()
    except (LogError, TreeError, OSError) as exc:
        return _bad_input(exc, args.tree)
    rec_changes, rec_assoc = recorded_status_changes(log), recorded_associations(log)
    same_changes = _first_difference(rec_changes, result.status_changes)
    same_assoc = _first_difference(rec_assoc, result.associations)
    rec_targets = [json.loads(m.data) for m in log.topic(S.TOPIC_TARGET)]
    new_targets = [json.loads(d) for d in targets.records]
    same_targets = _first_difference(rec_targets, new_targets)
    if args.json:
        out = result.to_dict()
        out.update(log=str(args.log), truncated=log.truncated, status_changes_as_recorded=same_changes is None,
                   associations_as_recorded=same_assoc is None, target_cues=len(new_targets),
                   target_cues_as_recorded=same_targets is None)
        print(json.dumps(out))
    else:
        if log.truncated:
            print(f"{args.log}: unfinished log (read up to {log.problem})")
        for c in result.status_changes:
            print(f"  {c.t:9.2f} s  {c.node}: {c.old} -> {c.new}")
        # A finished root is halted when replay stops, so its last status reads INVALID: say how it ended instead.
        ending = result.ended if result.ended.startswith("root ") else f"{result.ended} (root {result.root})"
        print(f"{result.ticks} ticks, ended: {ending}; {result.polls} MAVLink reads, "
              f"{result.datagrams} radar datagrams, {result.frames} camera frames")
        print(_compare_line("status changes", len(result.status_changes), same_changes, rec_changes, result.status_changes))
        if result.associations or rec_assoc:
            ids = sorted({a["associated_id"] for a in result.associations if a["associated_id"] is not None})
            print(f"radar: {len(result.associations)} pictures, ownship track(s) {ids}")
            print(_compare_line("associations", len(result.associations), same_assoc, rec_assoc, result.associations))
        if new_targets or rec_targets:
            print(_compare_line("target cues and estimates", len(new_targets), same_targets, rec_targets, new_targets))
    if args.check and (same_changes is not None or same_assoc is not None or same_targets is not None):
        return EXIT_FAILED
    return EXIT_OK


def _first_difference(recorded: list, replayed: list) -> int | None:
    """Index of the first entry where the lists differ (None: identical)."""
    for i, (a, b) in enumerate(zip(recorded, replayed)):
        if a != b:
            return i
    return None if len(recorded) == len(replayed) else min(len(recorded), len(replayed))


def _compare_line(what: str, n: int, diff: int | None, recorded: list | None = None, replayed: list | None = None) -> str:
    if diff is None:
        return f"{what}: {n}, exactly as recorded"
    line = f"{what}: {n}, differ from the recording from entry {diff}"
    if recorded is not None and replayed is not None:
        line += f" (recorded {_entry(recorded, diff)}; replayed {_entry(replayed, diff)})"
    return line


def _entry(entries: list, i: int) -> str:
    if i >= len(entries):
        return "nothing"
    e = entries[i]
    if hasattr(e, "node"):
        return f"{e.t:.2f} s {e.node}: {e.old} -> {e.new}"
    text = json.dumps(e, default=str)
    return text if len(text) <= 160 else text[:157] + "..."


def run_plot(args: argparse.Namespace) -> int:
    from chaser_bt.log.figures import plot_belief_snapshots, plot_overhead, plot_relative_geometry, save_figure
    from chaser_bt.log.replay import LogError, flight_trace, read_log

    try:
        trace = flight_trace(read_log(args.log))
    except LogError as exc:
        print(f"chaser-bt: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if len(trace) == 0:
        print(f"chaser-bt: {args.log}: no ticks recorded: nothing to plot", file=sys.stderr)
        return EXIT_FAILED
    out = args.out or args.log.with_name(args.log.stem + "_plots")
    out.mkdir(parents=True, exist_ok=True)
    title = f"{trace.meta.get('tree', '')} ({args.log.name})"
    written = [out / "overhead.png"]
    save_figure(plot_overhead([trace], title=title), written[-1])
    if trace.target_source != "none":
        written.append(out / "relative_geometry.png")
        save_figure(plot_relative_geometry([trace], title=title), written[-1])
    if trace.beliefs:
        written.append(out / "belief.png")
        save_figure(plot_belief_snapshots(trace, title=title), written[-1])
    for path in written:
        print(path)
    return EXIT_OK


def run_btlog(args: argparse.Namespace) -> int:
    from chaser_bt.log.groot2.btlog import convert_flight
    from chaser_bt.log.replay import LogError, read_log
    from chaser_bt.tree import TreeError, load_tree

    out = args.out or args.log.with_suffix(".btlog")
    try:
        conversion = convert_flight(read_log(args.log), load_tree(args.tree), out)
    except (LogError, TreeError, OSError) as exc:
        return _bad_input(exc, args.tree)
    print(f"{out}: {conversion.ticks} ticks, {conversion.transitions} transitions, ended: {conversion.ended} "
          "(open it in Groot2: Log Replay)")
    if not conversion.as_recorded:
        print(f"chaser-bt: btlog: the replayed tree's status changes differ from {args.log}'s (`chaser-bt replay` shows "
              "where): the file is the replay's, not the recorded flight's", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK
