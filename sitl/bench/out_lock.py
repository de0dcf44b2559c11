"""One command at a time writes into an output folder: ``campaign --out`` and ``rehearse --report``.

Two commands writing into one folder would overwrite each other's results and report, and both exit 0;
:func:`lock_out_dir` holds the folder for one of them and refuses the next, naming the holder.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterator

__all__ = ["LOCK_FILE", "OutDirError", "lock_out_dir"]

LOCK_FILE = ".chaser-bt.lock"


class OutDirError(ValueError):
    """The output folder is held by another command, or its lock file cannot be opened: bad input."""


@contextlib.contextmanager
def lock_out_dir(out: Path, option: str = "--out", command: str = "campaign") -> Iterator[None]:
    """Hold ``out`` for ``command``: an exclusive ``flock`` on ``out/.chaser-bt.lock``, which names our pid
    and ``command`` while it is held.

    Raises:
        OutDirError: another command holds the folder (naming it and its pid), or the lock file cannot be
            opened; the message starts with ``option`` and the folder.
    """
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    path = Path(out) / LOCK_FILE
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise OutDirError(f"{option} {out}: cannot open {path.name} ({exc.strerror or exc})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            pid, _, holder = os.pread(fd, 64, 0).decode("ascii", "replace").strip().partition(" ")
            raise OutDirError(f"{option} {out} is in use by another {holder or 'command'} (pid {pid or '?'}); "
                              f"wait for it to end, or give another {option}") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()} {command}\n".encode(), 0)
        try:
            yield
        finally:
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)
