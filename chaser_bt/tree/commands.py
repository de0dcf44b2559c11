"""``chaser-bt convert`` and ``chaser-bt export-model``: the tree-authoring commands.

:func:`add_command` adds both subcommands to the CLI's subparsers; each handler returns an exit
code: 0 done, 2 bad input (a message naming file, line and reason on stderr).

``convert`` validates its input first and reports its problems as ``validate`` does; it warns
on stderr before writing when the source's comments are left behind, and writes over the source
itself only with ``--force``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

__all__ = ["add_command", "add_convert_command", "add_export_model_command"]

EXIT_OK, EXIT_BAD_INPUT = 0, 2


def add_command(subparsers: argparse._SubParsersAction) -> None:
    """Add ``convert`` and ``export-model``."""
    add_convert_command(subparsers)
    add_export_model_command(subparsers)


def add_convert_command(subparsers: argparse._SubParsersAction) -> None:
    help_ = "convert a tree between YAML and BehaviorTree.CPP v4 XML (by extension), checking it round-trips"
    p = subparsers.add_parser("convert", help=help_, description=help_)
    p.add_argument("source", type=Path, metavar="TREE", help="tree file to read (.xml = BT.CPP XML, else YAML)")
    p.add_argument("target", type=Path, metavar="OUT", help="tree file to write (.xml = BT.CPP XML, else YAML); "
                   "relative include paths are rewritten for its folder")
    p.add_argument("--force", action="store_true",
                   help="allow OUT to be TREE itself (rewritten in place, its comments lost; default: refused)")
    p.set_defaults(handler=_convert)


def add_export_model_command(subparsers: argparse._SubParsersAction) -> None:
    help_ = "write Groot2's <TreeNodesModel> of every registered node (from their port declarations)"
    p = subparsers.add_parser("export-model", help=help_, description=help_)
    p.add_argument("--out", "-o", "--output", dest="out", type=Path, metavar="FILE.xml",
                   help="file to write (default: standard output)")
    p.add_argument("--include-builtin", action="store_true", help="also list BT.CPP's own nodes (Groot2 knows them)")
    p.set_defaults(handler=_export_model)


def _convert(args: argparse.Namespace) -> int:
    from chaser_bt.tree import validate_tree
    from chaser_bt.tree.conversion import comment_lines, converted_file
    from chaser_bt.tree.documents import format_of
    from chaser_bt.tree.errors import TreeError

    source, target = args.source, args.target
    if not source.is_file():
        print(f"chaser-bt: {source}: {'is a folder, not a tree file' if source.is_dir() else 'no such file'}", file=sys.stderr)
        return EXIT_BAD_INPUT
    problems = validate_tree(source)
    if problems:  # as `chaser-bt validate` reports them
        print("\n".join(str(p) for p in problems), file=sys.stderr)
        print(f"{source}: {len(problems)} problem(s)", file=sys.stderr)
        print(f"chaser-bt: {source}: not converted", file=sys.stderr)
        return EXIT_BAD_INPUT
    if target.exists() and os.path.samefile(source, target) and not args.force:
        print(f"chaser-bt: {target}: is the source; rewriting it in place drops its comments (--force to do so)",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        output = converted_file(source, target)
        lost = comment_lines(source.read_text(encoding="utf-8"), format_of(source))
        if lost:
            print(f"chaser-bt: warning: {source}: {lost} comment line(s) not carried over to {target}", file=sys.stderr)
        target.write_text(output, encoding="utf-8")
    except TreeError as e:
        print("\n".join(str(p) for p in e.problems), file=sys.stderr)
        print(f"chaser-bt: {source}: not converted", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as e:
        print(f"chaser-bt: {target}: {e.strerror or e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(f"{source} -> {target}")
    return EXIT_OK


def _export_model(args: argparse.Namespace) -> int:
    from chaser_bt.tree.node_model import node_model_xml
    from chaser_bt.tree.registry import default_registry

    text = node_model_xml(default_registry(), include_builtin=args.include_builtin)
    if args.out is None:
        sys.stdout.write(text)
        return EXIT_OK
    try:
        args.out.write_text(text, encoding="utf-8")
    except OSError as e:
        print(f"chaser-bt: {args.out}: {e.strerror or e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return EXIT_OK
