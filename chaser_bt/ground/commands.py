"""``chaser-bt designate`` and ``chaser-bt retask``: the operator's commands over the signed uplink.

``chaser-bt designate TRACK --to HOST:PORT --key FILE``: the operator designates the chase's target.

Sends one signed ``designate`` command (:mod:`chaser_bt.ground.uplink`) to the aircraft's
``GroundDesignation`` node; the radar behaviours then validate that track, or switch the chase to it.
UDP has no answer: the aircraft's log and its ground stream (``/target/custody``'s target id in the
status) say whether it was taken. ``--repeat N`` sends it N times, 0.2 s apart, against loss (each
copy has a fresh timestamp; the aircraft takes the first and designating the same track again
changes nothing). Exit 2 on a bad argument or key file, 1 when the datagram could not be sent.

``chaser-bt retask TREE --to HOST:PORT --key FILE --sysid N``: fly TREE instead of the running mission
(:mod:`chaser_bt.mission.retask`: checked on the aircraft first, taken at a safe point). The tree is
checked here too before it is sent; its includes are resolved on the aircraft, beside its running tree.
With ``--subtree NAME`` it sends a ``replace_subtree`` command instead: TREE's tree of that ID (else its
main tree) replaces that subtree of the running tree only (an aircraft that does not know the command
drops it, and flies on). Here the file must read and hold that tree; whether it fits the running tree
(its SubTree nodes' remappings, every key read written) is checked on the aircraft, which has that tree.
"""

from __future__ import annotations

import argparse
import socket
import sys
import time
from pathlib import Path

from chaser_bt.cli_args import host_port, positive_int

__all__ = ["add_command", "run_designate", "run_retask"]


def add_command(subparsers) -> None:
    """Add ``designate`` to the ``chaser-bt`` sub-commands."""
    p = subparsers.add_parser("designate", help="designate the chase's target by radar track id, over the signed uplink",
                              description="Designate the chase's target by its radar track id: one signed command to "
                                          "the aircraft's GroundDesignation node (docs/ground.md).")
    p.add_argument("track", metavar="TRACK_ID", type=int, help="the radar track id to designate (0 .. 2^31-1)")
    p.add_argument("--to", required=True, type=host_port, metavar="HOST:PORT",
                   help="the aircraft's uplink address (GroundDesignation's host and port; required)")
    p.add_argument("--key", required=True, metavar="FILE",
                   help="the uplink's key file, MAVLink signing's format (required: the uplink is never unsigned)")
    p.add_argument("--link-id", type=int, default=0, metavar="N", help="this ground station's link id, 0-255 (default 0)")
    p.add_argument("--repeat", type=positive_int, default=3, metavar="N",
                   help="send it N times, 0.2 s apart, against loss (default 3)")
    p.set_defaults(handler=run_designate)

    p = subparsers.add_parser("retask", help="send a new mission tree to a flying aircraft, over the signed uplink",
                              description="Send a new mission tree to a flying aircraft over the signed uplink; it is "
                                          "checked there and takes over at a safe point (docs/trees.md, \"Retasking\").")
    p.add_argument("tree", metavar="TREE", help="the tree file to fly instead (YAML, or BT.CPP XML)")
    p.add_argument("--to", required=True, type=host_port, metavar="HOST:PORT", help="the aircraft's uplink address (required)")
    p.add_argument("--key", required=True, metavar="FILE", help="the uplink's key file (required)")
    p.add_argument("--sysid", required=True, type=positive_int, metavar="N",
                   help="the vehicle's MAVLink system id: another vehicle refuses it (required)")
    p.add_argument("--subtree", metavar="NAME",
                   help="replace only this subtree (a tree ID) of the running tree, with TREE's tree NAME or else "
                        "its main tree; the rest of the mission keeps its progress (sent as a replace_subtree "
                        "command, which an aircraft without it drops; default: the whole tree)")
    p.add_argument("--link-id", type=int, default=0, metavar="N", help="this ground station's link id, 0-255 (default 0)")
    p.set_defaults(handler=run_retask)


def _send(to: str, datagrams: list[bytes]) -> str | None:
    """Send ``datagrams`` 0.2 s apart; the error, or None."""
    host, _, port = to.rpartition(":")
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for k, d in enumerate(datagrams):
                if k:
                    time.sleep(0.2)
                s.sendto(d, (host or "127.0.0.1", int(port)))
    except OSError as e:
        return f"cannot send to {to}: {e}"
    return None


def run_retask(args: argparse.Namespace) -> int:
    from chaser_bt.ground.auth import StreamSigner
    from chaser_bt.ground.uplink import replace_subtree_datagram, retask_datagram
    from chaser_bt.tree import TreeError, load_tree
    from chaser_bt.vehicle.signing import load_key

    path = Path(args.tree)
    subtree = getattr(args, "subtree", None)
    try:
        if subtree is None:
            load_tree(path)  # what the aircraft would refuse, refused here first
        else:
            _check_replacement(path, subtree)
        if args.sysid > 255:
            raise ValueError(f"--sysid {args.sysid}: expected 1-255")
        signer, text = StreamSigner(load_key(args.key), args.link_id), path.read_text(encoding="utf-8")
        if subtree is None:
            datagram = retask_datagram(signer, path.name, text, args.sysid)
        else:
            datagram = replace_subtree_datagram(signer, path.name, text, args.sysid, subtree)
    except TreeError as e:
        print(f"chaser-bt: retask: {str(e).strip().splitlines()[0]}", file=sys.stderr)
        return 2
    except (OSError, ValueError) as e:
        print(f"chaser-bt: retask: {e}", file=sys.stderr)
        return 2
    problem = _send(args.to, [datagram])
    if problem is not None:
        print(f"chaser-bt: retask: {problem}", file=sys.stderr)
        return 1
    what = f"retask {path.name}" + (f" as subtree {subtree}" if subtree is not None else "")
    print(f"{what}: sent to vehicle {args.sysid} at {args.to} ({len(datagram)} bytes, signed); "
          f"the aircraft's log says whether it was taken")
    return 0


def _check_replacement(path: Path, subtree: str) -> None:
    """A subtree's replacement, as far as it can be checked without the running tree: the file reads
    (its includes too) and holds a tree ``subtree``, or a main tree.

    Raises:
        TreeError: the file does not read.
        ValueError: it has no tree to put in the subtree's place (:func:`chaser_bt.tree.splice.replacement_tree`).
    """
    from chaser_bt.tree import TreeError
    from chaser_bt.tree.documents import read_document
    from chaser_bt.tree.splice import SpliceError, replacement_tree

    document, problems = read_document(path)
    if problems:
        raise TreeError(sorted(problems))
    try:
        replacement_tree(document, subtree)
    except SpliceError as e:
        raise ValueError(f"{path}: {e}") from None


def run_designate(args: argparse.Namespace) -> int:
    from chaser_bt.ground.auth import StreamSigner
    from chaser_bt.ground.uplink import designate_datagram
    from chaser_bt.vehicle.signing import load_key

    try:
        signer = StreamSigner(load_key(args.key), args.link_id)
        datagrams = [designate_datagram(signer, args.track, seq=k) for k in range(args.repeat)]
    except (OSError, ValueError) as e:
        print(f"chaser-bt: designate: {e}", file=sys.stderr)
        return 2
    problem = _send(args.to, datagrams)
    if problem is not None:
        print(f"chaser-bt: designate: {problem}", file=sys.stderr)
        return 1
    print(f"designate track {args.track}: sent {len(datagrams)} signed command(s) to {args.to}")
    return 0
