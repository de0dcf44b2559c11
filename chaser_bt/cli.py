"""`chaser-bt`: validate, show, run and rehearse mission trees; start the built-in simulator.

Exit codes: 0 success, 1 the mission failed or the vehicle could not be flown, 2 bad input
(an invalid tree or scenario, a bad argument), 130 interrupted (Ctrl-C or SIGTERM); ``run`` gives
each flight outcome its own (:data:`chaser_bt.mission.outcome.EXIT_CODES`). Arguments are
checked by :mod:`chaser_bt.cli_args` as the command line is read. The simulator and the rehearsal
harness are imported lazily: chaser_bt itself never depends on ``sitl`` (docs/design.md §2).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import errno
import importlib
import json
import logging
import signal
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

from chaser_bt import cli_args as arg
from chaser_bt.cli_args import ChaserParser
from chaser_bt.log.commands import add_recording_arguments
from chaser_bt.log.groot2.commands import add_groot2_arguments, start_hook

if TYPE_CHECKING:
    from chaser_bt.vehicle import LinkConfig

__all__ = ["main"]

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
DEFAULT_SEED = 1  # rehearse's and sitl's: the same seed flies the same flight in both
#: --camera-size's bounds, px a side: 8192 is a DCI 8K frame's width (a square frame of it is 200 MB).
MIN_CAMERA_SIDE_PX, MAX_CAMERA_SIDE_PX = 16, 8192

# Packages that bring their own sub-commands: each has ``add_command(subparsers)``.
_COMMAND_MODULES = (
    "chaser_bt.tree.commands",
    "chaser_bt.radar.commands",
    "chaser_bt.control.commands",
    "chaser_bt.vision.commands",
    "chaser_bt.log.commands",
    "chaser_bt.ground.commands",
)

# Commands that run the simulator live in sitl/ and are imported only when named (docs/design.md §2: chaser_bt
# reaches the simulator through lazily imported entry points); the others are listed but not loaded.
_SIM_COMMANDS = {
    "campaign": ("sitl.bench.campaign", "rehearse a tree over many seeds and scenarios in parallel; report and plots"),
    "search-trial": ("sitl.bench.search_trial", "fly the search-only trial (radar cut at 200 m, camera blind) and log belief gain"),
}

log = logging.getLogger("chaser_bt.cli")


class _BadInput(Exception):
    """Input the user must fix; the message says what and where."""


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _parser(argv)
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose > 1 else logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        with _sigterm_as_interrupt():
            return args.handler(args)
    except _BadInput as exc:
        print(f"chaser-bt: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"\nchaser-bt: {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return EXIT_OK


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """SIGTERM stops a command the way Ctrl-C does (the mission is halted and handed back hovering)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    parser = ChaserParser(prog="chaser-bt", description=__doc__.splitlines()[0], epilog=_EPILOG,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more logging (-vv for debug); "
                        "accepted before or after the subcommand")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}",
                        help="print the installed chaser-bt's version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                help="what to do: one of the commands below")

    def command(name: str, handler: Callable[[argparse.Namespace], int], help_: str) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=help_, description=help_)
        p.set_defaults(handler=handler)
        return p

    def tree_argument(p: argparse.ArgumentParser) -> None:
        p.add_argument("tree", type=arg.tree_file, metavar="TREE",
                       help="mission tree file: YAML (docs/trees.md) or BT.CPP v4 XML; or a shipped tree's name (`chaser-bt list`)")

    p = command("validate", _validate, "check a tree against the behaviour declarations; list every problem")
    tree_argument(p)

    p = command("show", _show, "print a tree as a unicode outline (or Graphviz dot) with its port values")
    tree_argument(p)
    p.add_argument("--format", choices=("unicode", "dot"), default="unicode",
                   help="unicode outline (default) or dot: pipe into `dot -Tpng`")

    command("nodes", _nodes, "list every node a tree can use, with its ports (from their declarations)")

    command("list", _list, "list the shipped trees and scenarios, by the names TREE and --scenario take, with their files")

    p = command("run", _run, "fly a tree against a vehicle (the simulator, ArduPilot SITL or a real ArduCopter)")
    tree_argument(p)
    p.add_argument("--connect", required=True, type=arg.connection_string, metavar="URL",
                   help="pymavlink connection string: tcp:HOST:PORT, udpout:HOST:PORT, udpin:HOST:PORT or a serial device (required)")
    p.add_argument("--rate-hz", type=arg.tick_rate, default=10.0, metavar="HZ",
                   help=f"tick rate, Hz, at most {arg.MAX_TICK_RATE_HZ:g} (the vehicle's clock counts milliseconds; default 10)")
    p.add_argument("--clock", choices=("vehicle", "wall"), default="vehicle",
                   help="tick on the vehicle's boot time (default; right at any sim speed-up) or on the wall clock")
    p.add_argument("--show-ticks", action="store_true", help="print the tree with statuses whenever a status changes")
    p.add_argument("--radar", type=arg.host_port, metavar="HOST:PORT", help="receive ground-radar datagrams here (docs/radar.md; default: no radar)")
    p.add_argument("--radar-pose", type=arg.input_file, metavar="FILE.json",
                   help="the radar's pose: `chaser-bt calibrate --json` output (required with --radar; default: none)")
    p.add_argument("--radar-time-offset", type=float, default=0.0, metavar="S", help="radar time + S = mission time, s (default 0)")
    p.add_argument("--radar-key", type=arg.input_file, metavar="FILE",
                   help="believe only radar datagrams signed with this key (the ground stream's HMAC; a MAVLink "
                        "signing key file; default: none, unsigned datagrams are believed)")
    p.add_argument("--radar-from", action="append", type=arg.ip_address, metavar="IP",
                   help="accept radar datagrams only from this address (repeat for several; default: any address); "
                        "without this or --radar-key anyone who reaches the port can cue the mission")
    p.add_argument("--uplink", type=arg.host_port, metavar="HOST:PORT",
                   help="listen here for the operator's signed designations (docs/ground.md; default: no uplink)")
    p.add_argument("--uplink-key", type=arg.input_file, metavar="FILE",
                   help="the uplink's key, MAVLink signing's format (required with --uplink: it is never unsigned; "
                        "default: none)")
    p.add_argument("--uplink-from", action="append", type=arg.ip_address, metavar="IP",
                   help="believe uplink commands only from this address (repeat for several; default: any that signs)")
    p.add_argument("--reload-from", type=Path, metavar="FILE",
                   help="retask in flight: each time FILE changes (and settles) its tree, checked first, replaces the "
                        "mission at a safe point (docs/trees.md, \"Retasking\"; default: no file)")
    p.add_argument("--reload-subtree", metavar="NAME",
                   help="with --reload-from: FILE's tree NAME (else its main tree) replaces only the subtree NAME of "
                        "the mission, whose other nodes keep their progress (default: the whole tree)")
    p.add_argument("--camera", metavar="SOURCE", help="video file, stream URL or device index for the on-board camera (default: none)")
    p.add_argument("--camera-size", type=_size, metavar="WxH",
                   help=f"resize camera frames to this size, px, {MIN_CAMERA_SIDE_PX} to {MAX_CAMERA_SIDE_PX} a side "
                        "(default: as captured)")
    p.add_argument("--camera-mount", choices=arg.CAMERA_MOUNTS, default="fixed",
                   help="how the camera is carried: fixed to the airframe, leaning with it, or on a two-axis "
                        "stabilising gimbal that holds its tilt below the horizon (docs/vision.md; default fixed)")
    p.add_argument("--camera-tilt", type=arg.camera_tilt, default=10.0, metavar="DEG",
                   help="the camera's optical axis, deg down from the airframe's forward axis (fixed) or from the "
                        "horizon (stabilised), between -90 and 90 (default 10)")
    p.add_argument("--perception", choices=("thread", "inline"), default="thread",
                   help="run the camera pipeline in its own thread beside the tick (default thread: the tick "
                        "reads its latest estimate) or inside the tick (inline)")
    p.add_argument("--no-telemetry", action="store_true", help="do not listen for the intruder's own MAVLink position")
    p.add_argument("--origin", type=arg.geodetic_point, metavar="LAT,LON[,ALT]",
                   help="the mission's ENU origin, deg, deg, m (default: the vehicle's home, from HOME_POSITION)")
    p.add_argument("--require-failsafes", action="store_true",
                   help="refuse to fly unless the vehicle's GCS and battery failsafes, fence and RTL_ALT are set "
                        "(they are read at connect and warned about either way)")
    _signing_arguments(p)
    p.add_argument("--designation-compid", type=arg.designation_compid, default=arg.DEFAULT_DESIGNATION_COMPID,
                   metavar="N", help="answer the operator's MAVLink target designations (docs/ground.md) as component "
                                     "N (2-255) of the vehicle's system; 0 or off: do not listen. They are listened "
                                     "for only with --signing-key or --designation-unsigned (default "
                                     f"{arg.DEFAULT_DESIGNATION_COMPID}, MAV_COMP_ID_ONBOARD_COMPUTER)")
    p.add_argument("--designation-unsigned", action="store_true",
                   help="bench only: believe UNSIGNED MAVLink designations too, so anyone on the link can change the "
                        "chase's target (warned at start; default: only those signed with --signing-key's key)")
    add_recording_arguments(p)
    add_groot2_arguments(p)

    p = command("rehearse", _rehearse, "fly a tree against the in-process simulator and report (Ctrl-C: a partial report)")
    tree_argument(p)
    p.add_argument("--scenario", required=True, type=arg.scenario_file, metavar="FILE",
                   help="scenario file (sitl/scenarios/README.md) or a shipped scenario's name (`chaser-bt list`; required)")
    p.add_argument("--seed", type=arg.seed, default=DEFAULT_SEED, metavar="N",
                   help=f"simulator seed: the same seed flies the same flight (default {DEFAULT_SEED})")
    p.add_argument("--rate-hz", type=arg.tick_rate, default=10.0, metavar="HZ",
                   help=f"tick rate, Hz, at most {arg.MAX_TICK_RATE_HZ:g} (the vehicle's clock counts milliseconds; default 10)")
    p.add_argument("--time-limit", type=arg.positive_float, metavar="S",
                   help="end the flight after S simulated seconds if the scenario's own limit is later (default: the scenario's)")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    p.add_argument("--show-ticks", action="store_true", help="print the tree with statuses whenever a status changes (to stderr with --json)")
    p.add_argument("--no-radar", action="store_true", help="no ground radar even if the scenario has one")
    p.add_argument("--radar-pose", choices=("calibrated", "surveyed"), default="calibrated",
                   help="how the mission learns the radar's pose: the appendix-A calibration flight (default) or a "
                        "survey (run takes the pose itself as a FILE)")
    p.add_argument("--no-camera", action="store_true", help="no rendered camera (trees without vision run faster)")
    p.add_argument("--camera-size", type=_size, default=(640, 480), metavar="WxH",
                   help=f"rendered camera size, px, {MIN_CAMERA_SIDE_PX} to {MAX_CAMERA_SIDE_PX} a side (default 640x480)")
    p.add_argument("--camera-in-process", action="store_true",
                   help="draw the camera's frames in this process, not in a render process beside it (the same frames, slower)")
    p.add_argument("--no-telemetry", action="store_true", help="do not give the mission the intruders' own MAVLink position")
    p.add_argument("--trace", type=arg.output_file, metavar="FILE.npz", help="write the flight's per-tick trace (FlightTrace) here (default: none)")
    p.add_argument("--report", type=arg.output_dir, metavar="DIR",
                   help="write the report there too: report.json, report.md, the trace and the paper's figures (default: none)")
    p.add_argument("--progress", choices=("auto", "always", "never"), default="auto",
                   help="a progress bar on stderr: simulated time, phase, real-time factor (default auto: on a terminal)")
    arg.add_autopilot_arguments(p)
    add_recording_arguments(p)
    add_groot2_arguments(p)

    for module in _COMMAND_MODULES:
        importlib.import_module(module).add_command(sub)
    named = next((a for a in argv if not a.startswith("-")), None)
    for name, (module, help_) in _SIM_COMMANDS.items():
        if name == named:
            importlib.import_module(module).add_command(sub)
        else:  # listed in --help; its real parser is built when the command is named
            sub.add_parser(name, help=help_, add_help=False)

    p = command("sitl", _sitl, "start the built-in ArduCopter-compatible simulator on loopback")
    p.add_argument("--scenario", required=True, type=arg.scenario_file, metavar="FILE",
                   help="scenario file (sitl/scenarios/README.md) or a shipped scenario's name (`chaser-bt list`; required)")
    p.add_argument("--speedup", type=arg.speedup, default=1.0, metavar="X",
                   help=f"simulated seconds per wall second, {arg.MIN_SPEEDUP:g} to {arg.MAX_SPEEDUP:g} (default 1)")
    p.add_argument("--seed", type=arg.seed, default=DEFAULT_SEED, metavar="N",
                   help=f"simulator seed, as rehearse's (default {DEFAULT_SEED})")
    p.add_argument("--tcp-port", type=arg.listen_port, default=5760, metavar="PORT",
                   help="TCP port to listen on, as ArduPilot SITL (default 5760; 0: any free one, printed)")
    p.add_argument("--udp-port", type=arg.listen_port, default=14550, metavar="PORT",
                   help="UDP port to listen on, reached with udpout: (default 14550; 0: any free one, printed)")
    p.add_argument("--radar-key", type=arg.input_file, metavar="FILE",
                   help="sign the scenario's radar datagrams (its radar.udp_port) with this key, as `run --radar-key` "
                        "verifies them (default: plain)")
    _signing_arguments(p)
    arg.add_verbose_everywhere(sub)
    return parser


_EPILOG = """\
exit codes: 0 done, 1 the mission failed or the vehicle could not be flown, 2 bad input, 130 interrupted.
`chaser-bt COMMAND --help` describes each command's options."""


def _signing_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--signing-key", type=Path, metavar="FILE",
                   help="MAVLink 2 signing key file: a line of 64 hex digits, or a passphrase (key = SHA-256, as MAVProxy's "
                        "signing setup; default: none, unsigned)")
    p.add_argument("--signing-link-id", default=0, metavar="N", type=arg.non_negative_int, help="signing link id (default 0)")


def _signing(args: argparse.Namespace):
    """The SigningConfig named by ``--signing-key`` (None without one); a bad key file is bad input."""
    if args.signing_key is None:
        return None
    from chaser_bt.vehicle.signing import SigningConfig, SigningKeyError

    why = arg.file_problem(args.signing_key)
    if why is not None:
        raise _BadInput(f"--signing-key: {why}")
    try:
        return SigningConfig.from_file(args.signing_key, link_id=args.signing_link_id)
    except (SigningKeyError, OSError, ValueError) as exc:
        raise _BadInput(f"--signing-key: {exc}") from None


# -- trees --------------------------------------------------------------------------------------


def _load_tree(path: Path):
    from chaser_bt.tree import TreeError, load_tree

    try:
        return load_tree(path)
    except TreeError as exc:
        raise _BadInput(f"{path}: invalid tree\n{exc}") from None
    except OSError as exc:
        raise _BadInput(f"{path}: {exc.strerror or exc}") from None


def _validate(args: argparse.Namespace) -> int:
    from chaser_bt.tree import validate_tree

    if args.tree.is_dir():
        raise _BadInput(f"{args.tree}: is a folder, not a tree file")
    if not args.tree.is_file():
        raise _BadInput(f"{args.tree}: no such file")
    problems = validate_tree(args.tree)
    if problems:
        print("\n".join(str(p) for p in problems), file=sys.stderr)
        print(f"{args.tree}: {len(problems)} problem(s)", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(f"{args.tree}: ok")
    return EXIT_OK


def _show(args: argparse.Namespace) -> int:
    from chaser_bt.tree import render_tree
    from chaser_bt.tree.display import render_dot

    tree = _load_tree(args.tree)
    print(render_dot(tree) if args.format == "dot" else render_tree(tree))
    return EXIT_OK


def _list(args: argparse.Namespace) -> int:
    from chaser_bt.shipped import shipped_scenarios, shipped_trees

    for title, shipped in (("trees (TREE)", shipped_trees()), ("scenarios (--scenario)", shipped_scenarios())):
        print(f"shipped {title}:")
        width = max((len(name) for name in shipped), default=0)
        for name, files in shipped.items():
            others = ", ".join(f.name for f in files[1:])
            print(f"  {name:<{width}}  {files[0]}" + (f" (also {others})" if others else ""))
        if not shipped:
            print("  none found")
    return EXIT_OK


def _nodes(args: argparse.Namespace) -> int:
    from chaser_bt.tree import default_registry, render_node_reference

    print(render_node_reference(default_registry()))
    return EXIT_OK


# -- flying ---------------------------------------------------------------------------------------


def _run(args: argparse.Namespace) -> int:
    tree = _load_tree(args.tree)
    _check_reload(args, tree)
    _check_designation(args)
    monitor = _groot2_monitor(args, tree)
    try:
        return _fly(args, tree, monitor)
    finally:
        if monitor is not None:
            monitor.close()


def _fly(args: argparse.Namespace, tree, monitor) -> int:
    from chaser_bt.clock import FunctionClock, WallClock
    from chaser_bt.mission.flight_sensors import FlightSensorError, check_sensors, close_flight_sensors
    from chaser_bt.mission.runner import MissionRunner, RunStatus
    from chaser_bt.vehicle import VehicleError, VehicleLink

    try:  # before connecting: a tree that needs a sensor it was not given never reaches the vehicle
        check_sensors(tree, _sensor_options(args))
    except FlightSensorError as exc:
        raise _BadInput(f"{args.tree}: {exc}") from None
    hook = _recording_hook(args)
    config = _link_config(args)
    try:
        link = VehicleLink.connect(args.connect, config)
    except ValueError as exc:  # a malformed connection string
        raise _BadInput(str(exc)) from None
    except VehicleError as exc:
        print(f"chaser-bt: {exc}", file=sys.stderr)
        return EXIT_FAILED
    from chaser_bt.mission.preflight import read_fence, read_safety_settings, safety_warnings

    unsafe = safety_warnings(read_safety_settings(link))
    env = read_fence(link)
    print(f"chaser-bt: run: set-points kept within {env.max_distance_m:g} m of home, {env.min_alt_m:g} to "
          f"{env.max_alt_m:g} m above it (the vehicle's fence, where enabled, less its margin)", file=sys.stderr)
    for line in unsafe:
        print(f"chaser-bt: run: warning: {line}", file=sys.stderr)
    if unsafe and args.require_failsafes:
        link.close()
        raise _BadInput(f"run: --require-failsafes: {len(unsafe)} safety setting(s) off on the vehicle (above); "
                        "not flying (docs/ardupilot.md says what to set)")
    clock = WallClock() if args.clock == "wall" else FunctionClock(lambda: link.state.t_boot_s)
    try:
        resources = _flight_sensors(args, link, clock)
    except (FlightSensorError, VehicleError) as exc:
        link.close()
        raise _BadInput(str(exc)) from None
    runner = MissionRunner(tree, link, clock, rate_hz=args.rate_hz, resources=resources)
    _retask_sources(runner, args, resources)
    if monitor is not None:
        monitor.attach(runner)
    if args.show_ticks:
        runner.on_tick(_tick_printer(tree, sys.stdout))
    print(f"flying {tree.name} on {args.connect} (Ctrl-C hands the aircraft back holding)")
    try:
        if hook is not None:
            runner.setup()
            hook(runner, link, runner.resources)
        result = runner.run()
    finally:
        if hook is not None:
            hook.close()
        close_flight_sensors(resources)  # the camera's threads end with the flight (Ctrl-C and SIGTERM too)
        link.close()
    state = link.state
    verdict = result.verdict
    print(f"{verdict.line()} after {result.ticks} ticks; vehicle {state.mode or '?'}, "
          f"{'armed' if state.armed else 'disarmed'}, {state.alt_rel_m:.1f} m above home"
          + (f"; {result.hand_back}" if result.hand_back else ""))
    if "no ENU frame yet" in (result.message or ""):
        print("chaser-bt: run: the vehicle has not sent its home yet (a vehicle already flying, or just "
              "reconnected): wait for it, or give the mission's origin with --origin LAT,LON,ALT", file=sys.stderr)
    if result.status is not RunStatus.SUCCESS and args.signing_key is None and "no answer" in (result.message or ""):
        print("chaser-bt: run: the vehicle did not answer our commands; if it requires MAVLink 2 signing "
              "(`chaser-bt sitl --signing-key FILE` does), pass the same --signing-key", file=sys.stderr)
    return verdict.exit_code  # 0 only for "completed" (docs/run.md lists the others)


def _link_config(args: argparse.Namespace) -> LinkConfig:
    """The vehicle link's settings from ``run``'s options (a bad key file is bad input)."""
    from chaser_bt.geo import GeoPoint
    from chaser_bt.vehicle import LinkConfig

    return LinkConfig(signing=_signing(args), origin=None if args.origin is None else GeoPoint(*args.origin),
                      timers_on_vehicle_time=args.clock == "vehicle", designation_compid=args.designation_compid,
                      designation_unsigned=args.designation_unsigned)


def _check_designation(args: argparse.Namespace) -> None:
    """``--designation-unsigned`` needs MAVLink designation on; said loudly at start, before anything connects."""
    if not args.designation_unsigned:
        return
    if args.designation_compid is None:
        raise _BadInput("run: --designation-unsigned: MAVLink designation is off (--designation-compid off); "
                        "give one or the other")
    print("chaser-bt: run: WARNING: --designation-unsigned: UNSIGNED MAVLink designations are believed: anyone "
          "on the link can change the chase's target (bench use only; never fly with it)", file=sys.stderr)


def _rehearse(args: argparse.Namespace) -> int:
    tree = _load_tree(args.tree)
    scenario = _load_scenario(args.scenario)
    if args.time_limit is not None:
        scenario = dataclasses.replace(scenario, time_limit_s=min(scenario.time_limit_s, args.time_limit))
    with contextlib.ExitStack() as held:
        if args.report is not None:  # one rehearsal (or campaign) at a time writes into the report's folder
            from sitl.bench.out_lock import OutDirError, lock_out_dir

            try:
                args.report.mkdir(parents=True, exist_ok=True)
                held.enter_context(lock_out_dir(args.report, "--report", "rehearsal"))
            except OSError as exc:
                raise _BadInput(f"--report {args.report}: {exc.strerror or exc}") from None
            except OutDirError as exc:
                raise _BadInput(str(exc)) from None
        return _rehearse_flight(args, tree, scenario)


def _rehearse_flight(args: argparse.Namespace, tree, scenario) -> int:
    """``rehearse`` once its inputs are read and its report folder is held."""
    from sitl.ardupilot.process import ArduPilotMissing
    from sitl.ardupilot.simulator import ArduPilotStopped
    from sitl.bench.rehearsal import AutopilotChoice, RehearsalInterrupted, SensorSetupError, rehearse
    from sitl.bench.sensors import SensorOptions

    on_tick = _tick_printer(tree, sys.stderr if args.json else sys.stdout) if args.show_ticks else None
    sensors = SensorOptions(radar=not args.no_radar, radar_pose=args.radar_pose, camera=not args.no_camera,
                            camera_size=args.camera_size, telemetry=not args.no_telemetry,
                            render_process=not args.camera_in_process)
    hook = _recording_hook(args)
    monitor = _groot2_monitor(args, tree)
    bar = None
    if args.progress != "never" and not args.show_ticks:
        from sitl.bench.rehearsal_progress import RehearsalProgress

        bar = RehearsalProgress(scenario.time_limit_s, sys.stderr, always=args.progress == "always")
    interrupted = False
    try:
        report = rehearse(tree, scenario, args.seed, rate_hz=args.rate_hz, on_tick=on_tick, sensors=sensors,
                          on_start=start_hook(monitor, hook), trace=args.trace is not None or args.report is not None,
                          progress=bar, autopilot=AutopilotChoice(args.autopilot, args.airframe, args.ardupilot))
    except RehearsalInterrupted as stop:  # Ctrl-C or SIGTERM: the partial report, then exit 130
        report, interrupted = stop.report, True
    except (ArduPilotMissing, ArduPilotStopped) as exc:  # no autopilot to fly: nothing was flown
        print(f"chaser-bt: rehearse: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except SensorSetupError as exc:  # nothing was flown; -vv logs the cause's traceback
        log.debug("sensor set-up failed", exc_info=exc.__cause__)
        print(f"chaser-bt: rehearse: {exc}", file=sys.stderr)
        return EXIT_FAILED
    finally:
        if bar is not None:
            bar.close()
        if hook is not None:
            hook.close()
        if monitor is not None:
            monitor.close()
    if args.trace is not None:
        report.trace.save(args.trace)
    if args.report is not None:
        from sitl.bench.report import write_rehearsal_report

        written = write_rehearsal_report(report, args.report)
        print(f"report written to {written['markdown']}", file=sys.stderr)
    if args.json:
        print(json.dumps(report.to_dict()))
    else:
        _print_report(report.to_dict())
    if interrupted:
        print(f"chaser-bt: rehearse: {report.message}; the report covers the flight so far", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK if report.outcome in ("landed", "completed", "following") else EXIT_FAILED


def _sensor_options(args: argparse.Namespace):
    """The sensors the operator named on ``run``."""
    from chaser_bt.mission.flight_sensors import FlightSensorOptions

    return FlightSensorOptions(radar_listen=args.radar, radar_pose_file=args.radar_pose,
                               radar_time_offset_s=args.radar_time_offset, radar_key_file=args.radar_key,
                               radar_hosts=frozenset(args.radar_from) if args.radar_from else None,
                               uplink_listen=args.uplink, uplink_key_file=args.uplink_key,
                               uplink_hosts=frozenset(args.uplink_from or ()), camera=args.camera,
                               camera_size=args.camera_size, camera_mount=args.camera_mount,
                               camera_tilt_deg=args.camera_tilt, telemetry=not args.no_telemetry,
                               perception=args.perception)


def _flight_sensors(args: argparse.Namespace, link, clock) -> dict:
    """The resources ``run`` hands the tree: radar, camera and target telemetry as the operator named them."""
    import time

    from chaser_bt.mission.flight_sensors import build_flight_sensors
    from chaser_bt.vehicle import VehicleError

    options = _sensor_options(args)
    if options.radar_listen is not None:  # the radar's pose is placed in the vehicle's home frame
        deadline = time.monotonic() + 15.0
        while link.frame is None and time.monotonic() < deadline:
            link.poll()
            time.sleep(0.05)
        if link.frame is None:
            raise VehicleError("no HOME_POSITION from the vehicle within 15 s: cannot place the radar")
    return build_flight_sensors(link, clock, options)


def _recording_hook(args: argparse.Namespace):
    """The ``--record``/``--live`` hook, checked before anything flies (None when neither is asked for)."""
    from chaser_bt.log.commands import RecordingError, RecordingHook

    try:
        return RecordingHook.from_args(args)
    except RecordingError as exc:
        raise _BadInput(str(exc)) from None


def _groot2_monitor(args: argparse.Namespace, tree):
    """The ``--groot2`` monitor, serving before anything flies (None without it); a taken port is bad input."""
    from chaser_bt.log.groot2 import Groot2Error
    from chaser_bt.log.groot2.commands import groot2_monitor

    try:
        return groot2_monitor(args, tree)
    except Groot2Error as exc:
        raise _BadInput(f"--groot2: {exc}") from None


def _size(text: str) -> tuple[int, int]:
    """``WxH`` -> (W, H), for argparse: each side in [MIN_CAMERA_SIDE_PX, MAX_CAMERA_SIDE_PX]."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 640x480, got {text!r}") from None
    if w < MIN_CAMERA_SIDE_PX or h < MIN_CAMERA_SIDE_PX:
        raise argparse.ArgumentTypeError(
            f"camera size {text} is too small (at least {MIN_CAMERA_SIDE_PX}x{MIN_CAMERA_SIDE_PX})")
    if w > MAX_CAMERA_SIDE_PX or h > MAX_CAMERA_SIDE_PX:
        raise argparse.ArgumentTypeError(
            f"camera size {text} is too large (at most {MAX_CAMERA_SIDE_PX}x{MAX_CAMERA_SIDE_PX})")
    return w, h


def _tick_printer(tree, stream):
    """A tick listener that prints the tree with statuses whenever one changed."""
    from chaser_bt.tree import render_tree

    def show(changes) -> None:
        if changes:
            print(f"--- t = {changes[0].t:.1f} s: " + ", ".join(f"{c.node} {c.old}->{c.new}" for c in changes), file=stream)
            print(render_tree(tree, show_status=True), file=stream)

    return show


def _print_report(report: dict) -> None:
    width = max(len(k) for k in report)
    for key, value in report.items():
        print(f"  {key:<{width}}  {_plain(value)}")


def _plain(value) -> str:
    """A report value as people read it: ``-`` for none, lists comma-separated (not Python's reprs)."""
    if value is None:
        return "-"
    if isinstance(value, (list, tuple)):
        return ", ".join(_plain(v) for v in value) if value else "-"
    if isinstance(value, dict):
        return ", ".join(f"{k} {_plain(v)}" for k, v in value.items()) if value else "-"
    return str(value)


def _load_scenario(path: Path):
    from sitl.world.scenario import ScenarioError, load_scenario

    try:
        return load_scenario(path)
    except ScenarioError as exc:
        raise _BadInput(str(exc)) from None
    except OSError as exc:
        raise _BadInput(f"{path}: {exc.strerror or exc}") from None


def _check_reload(args: argparse.Namespace, tree) -> None:
    """``--reload-subtree`` names a subtree the mission has, and comes with ``--reload-from``."""
    from chaser_bt.tree.splice import subtree_ids

    name = args.reload_subtree
    if name is None:
        return
    if args.reload_from is None:
        raise _BadInput(f"run: --reload-subtree {name}: give the file it is reloaded from with --reload-from FILE")
    known = subtree_ids(tree)
    if name not in known:
        raise _BadInput(f"run: --reload-subtree {name}: {args.tree} has no subtree {name}"
                        f"{arg.did_you_mean(name, known)}; its subtrees: {', '.join(known) or 'none'}")


def _retask_sources(runner, args: argparse.Namespace, resources: dict) -> None:
    """Where retasks come from on ``run``: the watched file and the uplink's ``retask`` and
    ``replace_subtree`` commands."""
    from chaser_bt.ground.uplink import RETASK_COMMANDS
    from chaser_bt.mission.retask import FileWatcher, RetaskRequest

    if args.reload_from is not None:
        runner.retask_sources.append(FileWatcher(args.reload_from, subtree=args.reload_subtree).poll)
    uplink = resources.get("uplink")
    if uplink is not None:
        base = Path(args.tree).parent

        def from_uplink() -> RetaskRequest | None:
            taken = uplink.take(*RETASK_COMMANDS)
            if not taken:
                return None
            cmd = taken[-1]  # the latest of either kind wins; earlier ones in the same poll are superseded
            return RetaskRequest(cmd.tree.encode("utf-8"), cmd.name, base, "uplink", cmd.sysid, cmd.subtree)

        runner.retask_sources.append(from_uplink)


def _sitl(args: argparse.Namespace) -> int:
    scenario = _load_scenario(args.scenario)
    signing = _signing(args)
    radar_sign = None
    if args.radar_key is not None:
        from chaser_bt.ground.auth import StreamSigner
        from chaser_bt.vehicle.signing import SigningKeyError, load_key

        if scenario.radar is None or scenario.radar.udp_port is None:
            raise _BadInput(f"--radar-key: scenario {scenario.name} sends no radar datagrams (no radar.udp_port)")
        try:
            radar_sign = StreamSigner(load_key(args.radar_key)).sign
        except SigningKeyError as exc:
            raise _BadInput(f"--radar-key: {exc}") from None
    from sitl.server import serve

    def ready(connection_strings: list[str]) -> None:
        print(f"simulating {scenario.name} at {args.speedup:g}x (seed {args.seed}); connect with:")
        for url in connection_strings:
            print(f"  {url}")
        if signing is not None:
            print(f"MAVLink 2 signing is on: unsigned messages are refused; fly with "
                  f"`chaser-bt run TREE --connect URL --signing-key {args.signing_key}`")
        sys.stdout.flush()

    try:
        interrupted = serve(scenario, seed=args.seed, speedup=args.speedup, udp_port=args.udp_port,
                            tcp_port=args.tcp_port, ready=ready, signing=signing, radar_sign=radar_sign)
    except OSError as exc:
        if exc.errno not in (errno.EADDRINUSE, errno.EACCES, errno.EADDRNOTAVAIL):
            raise
        raise _BadInput(f"--tcp-port {args.tcp_port} / --udp-port {args.udp_port}: cannot listen on loopback "
                        f"({exc.strerror}); is another `chaser-bt sitl` running? pick other ports") from None
    if interrupted:  # Ctrl-C or SIGTERM stopped the server: exit 130 like every interrupted command
        raise KeyboardInterrupt
    return EXIT_OK


def _version() -> str:
    """The installed package's version (the source's, ``chaser_bt.__version__``, from a checkout never installed)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("chaser-bt")
    except PackageNotFoundError:
        import chaser_bt

        return chaser_bt.__version__


if __name__ == "__main__":
    sys.exit(main())
