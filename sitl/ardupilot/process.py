"""Finding and starting ArduPilot's ``arducopter`` SITL binary with our physics behind it.

The binary is looked for, in order, at the folder given (``--ardupilot DIR``), at
``$CHASER_BT_ARDUPILOT``, and at ``../shared/ardupilot`` beside the repository. The folder holds
``arducopter`` and ArduPilot's stock ``copter.parm`` (``../shared/ardupilot/README.md``).

Each start gets a fresh working folder (a wiped EEPROM: no stored parameters, missions or fences)
and a free *instance*: ArduPilot derives every port from it (MAVLink SERIAL0 on TCP ``5760 + 10 I``,
the JSON physics on UDP ``9002 + 10 I``, RC input on UDP ``5501 + 10 I``), so campaign workers
each claim their own by binding the physics port first. The parameters are ArduPilot's stock SITL
defaults, then the airframe's, then the scenario's (ArduCopter names; later files win).
"""

from __future__ import annotations

import ctypes
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

__all__ = ["ARDUPILOT_ENV", "ArduCopterProcess", "ArduPilotMissing", "RENAMED_PARAMS", "find_ardupilot", "mavlink_port", "rc_port",
           "with_renamed"]

log = logging.getLogger(__name__)

ARDUPILOT_ENV = "CHASER_BT_ARDUPILOT"
_PR_SET_PDEATHSIG = 1  # linux/prctl.h
_REPO_SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "ardupilot"


class ArduPilotMissing(FileNotFoundError):
    """No ``arducopter`` binary where it was looked for (the message says where)."""


def find_ardupilot(folder: str | Path | None = None) -> Path:
    """The folder holding ``arducopter`` and ``copter.parm``: ``folder``, else ``$CHASER_BT_ARDUPILOT``,
    else ``../shared/ardupilot`` beside the repository.

    Raises:
        ArduPilotMissing: the chosen folder lacks either file.
    """
    where = Path(folder or os.environ.get(ARDUPILOT_ENV) or _REPO_SHARED).expanduser()
    for name in ("arducopter", "copter.parm"):
        if not (where / name).is_file():
            raise ArduPilotMissing(f"no ArduCopter SITL at {where}: {name} is missing (give --ardupilot DIR or set "
                                   f"{ARDUPILOT_ENV})")
    return where


def mavlink_port(instance: int) -> int:
    """SERIAL0's TCP port for ``instance``."""
    return 5760 + 10 * instance


def rc_port(instance: int) -> int:
    """The UDP port SITL reads RC input from (16 little-endian uint16 PWMs per datagram)."""
    return 5501 + 10 * instance


def _port_free(kind: int, port: int) -> bool:
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def instance_free(instance: int) -> bool:
    """Whether ``instance``'s MAVLink and RC ports are free now (the physics port is claimed by binding it)."""
    return (_port_free(socket.SOCK_STREAM, mavlink_port(instance)) and _port_free(socket.SOCK_STREAM, mavlink_port(instance) + 2)
            and _port_free(socket.SOCK_DGRAM, rc_port(instance)))


def _die_with_parent() -> None:
    """In the child, before exec: Linux kills it when the process that started it dies (a campaign
    worker ended at once leaves no ArduCopter behind; waiting for physics, it ignores SIGTERM)."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)


#: ArduCopter 4.7 moved these parameters to new names in SI units: (new name, factor from the old
#: unit), from its conversion tables (AC_WPNav, AC_Loiter, AC_AttitudeControl, mode_rtl, Parameters).
#: The defaults file carries both; a build ignores the name it does not know.
RENAMED_PARAMS: Mapping[str, tuple[str, float]] = {
    "WPNAV_SPEED": ("WP_SPD", 0.01), "WPNAV_RADIUS": ("WP_RADIUS_M", 0.01), "WPNAV_SPEED_UP": ("WP_SPD_UP", 0.01),
    "WPNAV_SPEED_DN": ("WP_SPD_DN", 0.01), "WPNAV_ACCEL": ("WP_ACC", 0.01), "WPNAV_ACCEL_Z": ("WP_ACC_Z", 0.01),
    "WPNAV_ACCEL_C": ("WP_ACC_CNR", 0.01), "RTL_ALT": ("RTL_ALT_M", 0.01), "RTL_SPEED": ("RTL_SPEED_MS", 0.01),
    "RTL_ALT_FINAL": ("RTL_ALT_FINAL_M", 0.01), "RTL_CLIMB_MIN": ("RTL_CLIMB_MIN_M", 0.01),
    "ANGLE_MAX": ("ATC_ANGLE_MAX", 0.01), "PILOT_SPEED_UP": ("PILOT_SPD_UP", 0.01),
    "PILOT_SPEED_DN": ("PILOT_SPD_DN", 0.01), "PILOT_ACCEL_Z": ("PILOT_ACC_Z", 0.01),
    "PILOT_TKOFF_ALT": ("PILOT_TKO_ALT_M", 0.01), "LOIT_SPEED": ("LOIT_SPEED_MS", 0.01),
    "LOIT_ACC_MAX": ("LOIT_ACC_MAX_M", 0.01), "LOIT_BRK_ACCEL": ("LOIT_BRK_ACC_M", 0.01),
    "LOIT_BRK_JERK": ("LOIT_BRK_JRK_M", 0.01), "ATC_ACCEL_Y_MAX": ("ATC_ACC_Y_MAX", 0.01),
    "ATC_ACCEL_R_MAX": ("ATC_ACC_R_MAX", 0.01), "ATC_ACCEL_P_MAX": ("ATC_ACC_P_MAX", 0.01),
    "ATC_SLEW_YAW": ("ATC_RATE_WPY_MAX", 0.01),
}


def with_renamed(params: Mapping[str, float]) -> dict[str, float]:
    """``params`` (ArduCopter 4.5/4.6 names) plus each renamed one under its 4.7+ name and unit."""
    out = dict(params)
    for name, value in params.items():
        if name in RENAMED_PARAMS:
            new, factor = RENAMED_PARAMS[name]
            out.setdefault(new, float(value) * factor)
    return out


@dataclass
class ArduCopterProcess:
    """One ``arducopter`` started with ``--model JSON``: it waits for our physics from its first step.

    Args:
        folder: from :func:`find_ardupilot`.
        instance: ArduPilot's ``-I``.
        home: (lat_deg, lon_deg, alt_m, heading_deg).
        params: ArduCopter parameters written to a defaults file after ``copter.parm``.
        speedup: ``--speedup``: lock-step physics sets the pace, so this only stops SITL sleeping.
    """

    folder: Path
    instance: int
    home: tuple[float, float, float, float]
    params: Mapping[str, float] = field(default_factory=dict)
    speedup: float = 100.0
    workdir: Path = field(init=False)
    proc: subprocess.Popen | None = field(init=False, default=None)

    def start(self) -> None:
        """Write the parameters and start the binary in a fresh working folder (its log is ``sitl.log`` there)."""
        self.workdir = Path(tempfile.mkdtemp(prefix=f"arducopter-I{self.instance}-"))
        defaults = [str(self.folder / "copter.parm")]
        if self.params:
            extra = self.workdir / "chaser_bt.parm"
            extra.write_text("".join(f"{k} {float(v):g}\n" for k, v in with_renamed(self.params).items()))
            defaults.append(str(extra))
        lat, lon, alt, hdg = self.home
        cmd = [str(self.folder / "arducopter"), "-w", "-I", str(self.instance), "--model", "JSON:127.0.0.1",
               "--speedup", f"{self.speedup:g}", "--serial0", "tcp:0", "--defaults", ",".join(defaults),
               "--home", f"{lat:.8f},{lon:.8f},{alt:.3f},{hdg:g}"]
        log.info("starting ArduCopter SITL: %s", " ".join(cmd))
        with open(self.workdir / "sitl.log", "wb") as out:
            try:
                self.proc = subprocess.Popen(cmd, cwd=self.workdir, stdout=out, stderr=subprocess.STDOUT,
                                             stdin=subprocess.DEVNULL, preexec_fn=_die_with_parent)
            except OSError as exc:  # not a program this machine runs (another platform's build, a text file)
                raise ArduPilotMissing(f"{self.folder / 'arducopter'} cannot be run: {exc.strerror or exc}") from None

    @property
    def url(self) -> str:
        """The mission's connection string (SERIAL0)."""
        return f"tcp:127.0.0.1:{mavlink_port(self.instance)}"

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def log_tail(self, lines: int = 8) -> str:
        """The end of SITL's own output (for error messages)."""
        try:
            text = (self.workdir / "sitl.log").read_text(errors="replace")
        except OSError:
            return ""
        return "\n".join(text.strip().splitlines()[-lines:])

    def stop(self) -> None:
        """Stop the binary (killed: it keeps nothing, and while it waits for physics it ignores SIGTERM)
        and remove its working folder."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        if getattr(self, "workdir", None) is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)
