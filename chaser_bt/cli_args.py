"""The command line's argument checks: one parser class, value types and output-path checks.

Every input error ends the same way: the subcommand's usage, then one line
``chaser-bt: argument --OPTION: what was expected`` (with a "did you mean" for a near miss),
exit 2. Value types reject impossible numbers at parse time, and output paths are checked
there too, so a mistake stops the command before it connects to or flies anything.
"""

from __future__ import annotations

import argparse
import difflib
import math
import sys
import tempfile
from pathlib import Path
from typing import Callable, Iterable, NoReturn

from chaser_bt.shipped import NotShipped, resolve_scenario, resolve_scenarios, resolve_tree

__all__ = [
    "PROG", "ChaserParser", "did_you_mean", "seed", "positive_float", "non_negative_float", "positive_int",
    "non_negative_int", "port", "listen_port", "groot2_port", "tick_rate", "host_port", "connection_string",
    "DEFAULT_DESIGNATION_COMPID", "designation_compid",
    "geodetic_point", "file_problem", "input_file", "tree_file", "scenario_file", "scenario_set", "output_file", "output_dir",
    "add_verbose_everywhere", "AUTOPILOTS", "add_autopilot_arguments",
]

PROG = "chaser-bt"


def did_you_mean(word: str, known: Iterable[str]) -> str:
    """`` (did you mean X?)`` for the closest of ``known`` to ``word``, or ``""`` when none is close."""
    close = difflib.get_close_matches(word, list(known), n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


class ChaserParser(argparse.ArgumentParser):
    """argparse with the project's error line: the (sub)command's usage, then ``chaser-bt: message``, exit 2.

    Unknown options are reported by the subcommand that was given them (with its usage and a
    "did you mean"), and an invalid choice names the closest valid one.
    """

    def error(self, message: str) -> NoReturn:
        message = self._dash_value_message(message)
        self.print_usage(sys.stderr)
        self.exit(2, f"{PROG}: {message}\n")

    def _dash_value_message(self, message: str) -> str:
        """argparse's "expected one argument" when the value starts with '-' (``--seeds -3-2``): what is wrong with it.

        argparse takes such a value for an option unless it reads as a plain negative number; say
        what the option's type makes of it, or how to pass it (``--seeds=-3-2``).
        """
        if not message.endswith(": expected one argument"):
            return message
        words = list(getattr(self, "_given_args", None) or ())
        for option, value in zip(words, words[1:]):
            action = self._option_string_actions.get(option)
            if action is None or not message.startswith(f"argument {'/'.join(action.option_strings)}:"):
                continue
            if len(value) < 2 or value[0] != "-" or not (value[1].isdigit() or value[1] == "."):
                continue
            if callable(action.type):
                try:
                    action.type(value)
                except argparse.ArgumentTypeError as exc:
                    return f"argument {option}: {exc}"
                except (TypeError, ValueError):
                    pass
            return f"argument {option}: expected one argument; a value starting with '-' is written {option}={value}"
        return message

    def parse_known_args(self, args=None, namespace=None):
        self._given_args = list(sys.argv[1:] if args is None else args)
        if self._subparsers is None and args is not None:  # a subcommand: name a misspelt option before a missing one
            for text in args:
                if text == "--":
                    break
                name = text.split("=", 1)[0]
                if name.startswith("--") and not any(o.startswith(name) for o in self._option_string_actions):
                    self.error(f"unrecognized option {name}{did_you_mean(name, self._option_string_actions)}")
        namespace, extras = super().parse_known_args(args, namespace)
        if extras and self._subparsers is None:  # a subcommand: nothing after it belongs to the top level
            first = extras[0]
            if first.startswith("-"):
                name = first.split("=", 1)[0]
                self.error(f"unrecognized option {name}{did_you_mean(name, self._option_string_actions)}")
            self.error(f"unexpected argument {first!r}")
        return namespace, extras

    def _check_value(self, action: argparse.Action, value) -> None:
        if action.choices is not None and value not in action.choices:
            names = [str(c) for c in action.choices]
            raise argparse.ArgumentError(
                action, f"invalid choice {value!r}: expected one of {', '.join(names)}{did_you_mean(str(value), names)}")


def _number(cast: Callable[[str], float], ok: Callable[[float], bool], expected: str) -> Callable[[str], float]:
    what = "an integer" if cast is int else "a number"

    def parse(text: str):
        try:
            value = cast(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what} {expected}, got {text!r}") from None
        if not ok(value):
            raise argparse.ArgumentTypeError(f"expected {what} {expected}, got {text}")
        return value

    parse.__name__ = f"{what} {expected}"
    return parse


seed = _number(int, lambda v: 0 <= v < 2**32, "in [0, 2^32)")
positive_float = _number(float, lambda v: math.isfinite(v) and v > 0, "> 0")
non_negative_float = _number(float, lambda v: math.isfinite(v) and v >= 0, ">= 0")
positive_int = _number(int, lambda v: v > 0, ">= 1")
non_negative_int = _number(int, lambda v: v >= 0, ">= 0")
port = _number(int, lambda v: 1 <= v <= 65535, "in 1-65535 (a UDP/TCP port)")
listen_port = _number(int, lambda v: 0 <= v <= 65535, "in 0-65535 (a port; 0: any free one)")
#: Groot2 is served on PORT and PORT + 1 (BT.CPP's Groot2Publisher), so PORT + 1 must be a port too.
groot2_port = _number(int, lambda v: 1 <= v <= 65534, "in 1-65534 (Groot2 serves on PORT and PORT+1)")
#: Mission tick rate: at most 1000 Hz, because the vehicle's clock that ticks are timed on (MAVLink's
#: time_boot_ms) counts whole milliseconds: a shorter period cannot be told apart from no wait.
MAX_TICK_RATE_HZ = 1000.0
tick_rate = _number(float, lambda v: math.isfinite(v) and 0 < v <= MAX_TICK_RATE_HZ,
                    f"in (0, {MAX_TICK_RATE_HZ:g}] (Hz; the vehicle's clock counts milliseconds)")
#: chaser_bt.vision.camera.MOUNTS (the CLI does not import the camera model's scipy).
CAMERA_MOUNTS = ("fixed", "stabilised")
#: ``run --camera-tilt``: the optical axis below the airframe's forward axis or the horizon, deg (a scenario's
#: ``camera.tilt_deg`` takes the same range).
camera_tilt = _number(float, lambda v: math.isfinite(v) and -90 < v < 90, "in (-90, 90) (deg down)")
#: ``sitl --speedup``: the simulator alone runs a few hundred times real time on a laptop core, so past 1000 a
#: speed-up is only "as fast as it can"; below 0.01 a simulated second takes more than a wall minute and a half.
MIN_SPEEDUP, MAX_SPEEDUP = 0.01, 1000.0
speedup = _number(float, lambda v: math.isfinite(v) and MIN_SPEEDUP <= v <= MAX_SPEEDUP,
                  f"in [{MIN_SPEEDUP:g}, {MAX_SPEEDUP:g}] (simulated s per wall s)")


def host_port(text: str) -> str:
    """``HOST:PORT`` to listen on (``0.0.0.0:4950``; HOST may be empty: every interface), PORT in 1-65535."""
    host, sep, number = text.rpartition(":")
    if not sep or not (number.isascii() and number.isdigit()):
        raise argparse.ArgumentTypeError(f"expected HOST:PORT such as 0.0.0.0:4950, got {text!r}")
    if not (len(number) <= 5 and 1 <= int(number) <= 65535):
        raise argparse.ArgumentTypeError(f"{text}: port {number} out of range (expected 1-65535)")
    return text


#: pymavlink's network schemes, as chaser_bt.vehicle.connection accepts them (that module is not imported
#: here: it loads pymavlink, and the command line is read before anything is loaded).
_NETWORK_SCHEMES = ("udpin:", "udpout:", "udp:", "tcpin:", "tcp:")


def connection_string(text: str) -> str:
    """A ``--connect`` URL whose port, if it names one, is a port (1-65535); the rest is checked on connecting."""
    scheme = next((s for s in _NETWORK_SCHEMES if text.startswith(s)), None)
    if scheme is not None:
        _, sep, number = text[len(scheme):].rpartition(":")
        if sep and number.isascii() and number.isdigit() and not (len(number) <= 5 and 1 <= int(number) <= 65535):
            raise argparse.ArgumentTypeError(f"{text}: port {number} out of range (expected 1-65535)")
    return text


#: The component MAVLink designations are answered as: chaser_bt.vehicle.designation.DEFAULT_COMPID,
#: MAV_COMP_ID_ONBOARD_COMPUTER (not imported here: that module loads pymavlink).
DEFAULT_DESIGNATION_COMPID = 191


def designation_compid(text: str) -> int | None:
    """``--designation-compid``: a MAVLink component id 2-255, or ``0``/``off`` (None: not listened for).

    1 is refused: it is the autopilot's own component, whose commands the link would then answer.
    """
    if text.strip().lower() in ("off", "0"):
        return None
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a component id in 2-255, or 0 or off (not listened for), "
                                         f"got {text!r}") from None
    if value == 1:
        raise argparse.ArgumentTypeError("1 is the autopilot's component (MAV_COMP_ID_AUTOPILOT1): the link would "
                                         f"answer commands meant for it; expected 2-255 (default "
                                         f"{DEFAULT_DESIGNATION_COMPID}), or 0 or off")
    if not 2 <= value <= 255:
        raise argparse.ArgumentTypeError(f"expected a component id in 2-255, or 0 or off (not listened for), got {text}")
    return value


def geodetic_point(text: str) -> tuple[float, float, float]:
    """``LAT,LON[,ALT]`` (deg, deg, m; ALT default 0) -> (lat, lon, alt)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected LAT,LON or LAT,LON,ALT in deg, deg, m, got {text!r}")
    lat, lon, alt = (*values, 0.0)[:3]
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise argparse.ArgumentTypeError(f"expected a latitude in [-90, 90] and a longitude in [-180, 180], got {text}")
    return lat, lon, alt


def ip_address(text: str) -> str:
    """An IPv4 or IPv6 address, as the socket reports a sender's (``192.0.2.7``)."""
    import ipaddress

    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an IP address (such as 192.0.2.7)") from None


def file_problem(path: str | Path) -> str | None:
    """Why ``path`` cannot be read as a file (``no such file X``, ``X is a folder, not a file``), or None."""
    path = Path(path)
    if path.is_file():
        return None
    if path.is_dir():
        return f"{path} is a folder, not a file"
    return f"{path} is not a file" if path.exists() else f"no such file {path}"


def input_file(text: str) -> Path:
    """A file to read: it exists and is a file."""
    why = file_problem(text)
    if why is not None:
        raise argparse.ArgumentTypeError(why)
    return Path(text)


def tree_file(text: str) -> Path:
    """A tree: a file's path (checked when it is read), or a shipped tree's name (``chase``; ``chaser-bt list``)."""
    try:
        return resolve_tree(text)
    except NotShipped as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def scenario_file(text: str) -> Path:
    """A scenario: a file's path (checked when it is read), or a shipped scenario's name (``patrol``)."""
    try:
        return resolve_scenario(text)
    except NotShipped as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def scenario_set(text: str) -> Path:
    """A scenario file or a folder of them: a path, or a shipped scenario's or folder's name (``hard``)."""
    try:
        return resolve_scenarios(text)
    except NotShipped as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _writable_folder(folder: Path) -> str | None:
    """Why files cannot be written into ``folder`` (None: they can)."""
    if not folder.is_dir():
        return f"no such folder {folder}"
    try:  # try it: permission bits do not tell for root, /proc or a read-only mount
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return f"folder {folder} is not writable ({exc.strerror or exc})"
    return None


def output_file(text: str) -> Path:
    """A file to write: its folder exists and is writable, and it is not a folder itself."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{path} is a folder; expected a file name")
    why = _writable_folder(path.parent if str(path.parent) else Path("."))
    if why is not None:
        raise argparse.ArgumentTypeError(f"cannot write {path}: {why}")
    return path


def output_dir(text: str) -> Path:
    """A folder to write into: it is a writable folder, or the nearest existing folder above it is."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{path} is a file; expected a folder")
    above = path
    while not above.exists():
        if above.parent == above:
            break
        above = above.parent
    if not above.is_dir():
        raise argparse.ArgumentTypeError(f"cannot create {path}: {above} is a file")
    why = _writable_folder(above)
    if why is not None:
        raise argparse.ArgumentTypeError(f"cannot write into {path}: {why}")
    return path


def add_verbose_everywhere(subparsers: argparse._SubParsersAction) -> None:
    """Let ``-v`` follow the subcommand as well as precede it."""
    for parser in subparsers.choices.values():
        if "-v" not in parser._option_string_actions:
            parser.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS,
                                help="more logging (-vv for debug); also accepted before the subcommand")


AUTOPILOTS = ("builtin", "ardupilot")
AIRFRAMES = ("s1000", "quad")  # sitl.vehicle.rotor_body.AIRFRAMES (the CLI does not import the simulator)


def add_autopilot_arguments(p: argparse.ArgumentParser) -> None:
    """``--autopilot``, ``--airframe`` and ``--ardupilot``: who flies a rehearsal (rehearse and campaign)."""
    p.add_argument("--autopilot", choices=AUTOPILOTS, default="builtin",
                   help="who flies: the built-in simulator (default, fast) or ArduPilot's ArduCopter SITL inside the same "
                        "world (docs/ardupilot.md)")
    p.add_argument("--airframe", choices=AIRFRAMES, default="s1000",
                   help="the rotor body ArduCopter flies with --autopilot ardupilot (default s1000, the paper's octocopter)")
    p.add_argument("--ardupilot", type=Path, metavar="DIR",
                   help="folder holding ArduPilot's arducopter and copter.parm (default $CHASER_BT_ARDUPILOT, then "
                        "../shared/ardupilot beside the repository)")
