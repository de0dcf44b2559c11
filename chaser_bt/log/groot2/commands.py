"""``--groot2 [PORT]`` and ``--groot2-host`` for ``chaser-bt run`` and ``rehearse``: Groot2 attaches to the flight."""

from __future__ import annotations

import argparse
import logging
import sys
from typing import Any, Callable

from chaser_bt.cli_args import groot2_port
from chaser_bt.log.groot2.protocol import DEFAULT_PORT
from chaser_bt.log.groot2.publisher import LOOPBACK, Groot2Publisher

__all__ = ["add_groot2_arguments", "groot2_monitor", "start_hook"]

log = logging.getLogger(__name__)


def add_groot2_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--groot2", type=groot2_port, nargs="?", const=DEFAULT_PORT, metavar="PORT",
                        help=f"serve the tree and its live statuses to Groot2 on PORT and PORT+1, 1-65534 (PORT default "
                             f"{DEFAULT_PORT}, as BT.CPP's Groot2Publisher; default: off)")
    parser.add_argument("--groot2-host", default=LOOPBACK, metavar="ADDRESS",
                        help=f"address the Groot2 monitor listens on (default {LOOPBACK}; 0.0.0.0 for every interface)")


def groot2_monitor(args: argparse.Namespace, tree: Any) -> Groot2Publisher | None:
    """The monitor ``--groot2`` asks for, serving already (None without it).

    Raises:
        Groot2Error: the ports cannot be bound (bad input: nothing has flown yet).
    """
    port = getattr(args, "groot2", None)
    if port is None:
        return None
    monitor = Groot2Publisher(tree, port, host=getattr(args, "groot2_host", LOOPBACK))
    print(f"Groot2: connect to {monitor.host} port {port} (Monitor mode)", file=sys.stderr)
    return monitor


def start_hook(monitor: Groot2Publisher | None, hook: Callable[..., None] | None) -> Callable[..., None] | None:
    """A rehearsal ``on_start`` that attaches ``monitor`` to the runner, then calls ``hook`` (either may be None)."""
    if monitor is None:
        return hook

    def on_start(runner: Any, vehicle: Any, resources: Any = None) -> None:
        monitor.attach(runner)
        if hook is not None:
            hook(runner, vehicle, resources)

    return on_start
