"""The simulated camera drawn in a process of its own, beside the rehearsal's tick.

Drawing a frame (a few milliseconds of warps, blends and JPEG, half of it Python) is the largest
part of a camera-on rehearsal's tick. A thread cannot take it off the tick: the drawing's Python
and the tick's take turns on the GIL (docs/vision.md, "Tenth session"). A :class:`RenderProcess`
is a child process holding its own :class:`~sitl.world.camera.frame_source.SimulatorFrameSource`
over the same camera world: the rehearsal takes a :class:`~sitl.world.camera.frame_source.Shot`
(poses and blur, cheap) and submits it; the child draws it while the tick goes on; the rehearsal
collects the frame later. The child builds its world itself (spawned, not forked: nothing of the
parent's threads or onnxruntime sessions comes along), so the parent never pays for it, and says
when it has (:meth:`RenderProcess.wait_ready`): a rehearsal waits for that while it sets its
sensors up, not at its first frame.

Shots are drawn in the order submitted, from the same sensor-noise stream as in-process drawing,
so a frame drawn here is the frame drawn in the parent, byte for byte. The pixels come back through
a file in shared memory (two frame slots, the shot's index choosing one) and only a small message
through the pipe: a 640 x 480 frame pickled through the pipe cost the parent 2.3 ms to receive,
a copy out of the slot a few hundredths of that.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import tempfile
import time
import traceback
from typing import Any, Iterator, Sequence

import numpy as np

from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.frame_source import Region
from sitl.world.camera.frame_source import Shot

__all__ = ["DrawnFrame", "RenderProcess"]

log = logging.getLogger(__name__)

#: The child's environment over the parent's, in place before its numpy and BLAS load:
#: - one BLAS/OpenMP thread: the child has one core, the tick the other;
#: - no huge pages for numpy's arrays of 4 MiB and more: where transparent huge pages are ``madvise``
#:   (the development machine), faulting them in (compaction included) made the child's world build
#:   1.18 s against 0.81 s without (cold builds of seed 1's farmland, four interleaved pairs); drawing
#:   frames gained nothing from them.
_CHILD_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
              "NUMPY_MADVISE_HUGEPAGE": "0"}

DrawnFrame = tuple[np.ndarray, "tuple[Region, ...] | None", tuple, float]  # image, regions drawn, labels, draw ms
_SLOTS = 2  # frame k is drawn into slot k % 2 while the parent copies frame k-1 out of the other


class RenderProcess:
    """A child process drawing shots of one camera world (``build_world(world, seed, width, height)``).

    Args:
        camera: the camera model (its size is the frame size).
        world: the scenario's :class:`~sitl.world.camera.world.WorldSpec`.
        seed: the rehearsal's seed: the world's layout and the sensor noise.
        timeout_s: :meth:`collect` gives up (raises) when the child has said nothing for this long.
    """

    def __init__(self, camera: CameraModel, world: Any, seed: int, timeout_s: float = 120.0) -> None:
        shape = (_SLOTS, camera.height_px, camera.width_px, 3)
        fd, self._path = tempfile.mkstemp(prefix="chaser-bt-frames-", dir="/dev/shm" if os.path.isdir("/dev/shm") else None)
        os.close(fd)
        self._slots = np.memmap(self._path, np.uint8, "w+", shape=shape)
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(target=_serve, args=(child, camera, world, seed, self._path, shape),
                                 name="chaser-bt-render", daemon=True)
        with _environment(_CHILD_ENV):
            self._proc.start()
        child.close()
        self.timeout_s = float(timeout_s)
        self.in_flight = 0
        #: Seconds the child took to build its world (None until :meth:`wait_ready` has heard it).
        self.world_s: float | None = None

    def wait_ready(self) -> float:
        """Wait until the child has built its world; the seconds that took. Raises RuntimeError as
        :meth:`collect` does."""
        if self.world_s is None:
            _, self.world_s = self._receive("ready")
        return self.world_s

    def submit(self, shot: Shot, regions: Sequence[Region] | None) -> None:
        """Have ``shot`` drawn (only ``regions`` when given); returns at once. At most two shots may
        be in flight: a third would be drawn into the slot of a frame not collected yet."""
        if self.in_flight >= _SLOTS:
            raise RuntimeError(f"{self.in_flight} shots already in flight: collect one first")
        self._conn.send((shot, None if regions is None else tuple(regions)))
        self.in_flight += 1

    def collect(self) -> DrawnFrame:
        """The oldest submitted shot, drawn: (image, views, labels, draw ms); waits for it.

        Raises RuntimeError when nothing is in flight, the child failed (its traceback in the
        message) or it was silent for ``timeout_s``.
        """
        if self.in_flight < 1:
            raise RuntimeError("no shot submitted to the render process")
        self.wait_ready()
        _, slot, regions, labels, draw_ms = self._receive("frame")
        self.in_flight -= 1
        return np.array(self._slots[slot]), regions, labels, draw_ms

    def _receive(self, kind: str) -> tuple:
        """The child's next message, which must be ``kind``; its error as RuntimeError."""
        if not self._conn.poll(self.timeout_s):
            raise RuntimeError(f"render process silent for {self.timeout_s:.0f} s (alive: {self._proc.is_alive()})")
        try:
            msg = self._conn.recv()
        except EOFError as e:
            raise RuntimeError(f"render process ended (exit code {self._proc.exitcode})") from e
        if msg[0] == "error":
            raise RuntimeError(f"render process failed:\n{msg[1]}")
        if msg[0] != kind:
            raise RuntimeError(f"render process answered {msg[0]!r}, expected {kind!r}")
        return msg

    def close(self, join_timeout_s: float = 5.0) -> None:
        """Stop the child: frames in flight are taken off the pipe (unread, the child would wait to
        send them); killed if it does not stop in time."""
        if self._proc.is_alive():
            with contextlib.suppress(EOFError, BrokenPipeError, OSError):  # the child already gone
                unread = self.in_flight + (self.world_s is None)  # the frames, and "ready" if not heard
                while unread > 0 and self._conn.poll(join_timeout_s):
                    self._conn.recv()
                    unread -= 1
                self.in_flight = 0
                self._conn.send(None)
            self._proc.join(join_timeout_s)
            if self._proc.is_alive():
                log.warning("render process did not stop in %.0f s: killed", join_timeout_s)
                self._proc.kill()
                self._proc.join(1.0)
        self._conn.close()
        del self._slots
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self._path)

    def __enter__(self) -> RenderProcess:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


@contextlib.contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """``values`` in ``os.environ`` for the block (a child spawned in it inherits them); the parent's
    own values back after."""
    before = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _serve(conn: Any, camera: CameraModel, world_spec: Any, seed: int, path: str, shape: tuple[int, ...]) -> None:
    """The child: build the world, then draw each shot received into its slot until told to stop (None)."""
    try:
        import cv2

        cv2.setNumThreads(1)  # one core: the tick has the other
        from sitl.world.camera.frame_source import SimulatorFrameSource
        from sitl.world.camera.world import build_world

        slots = np.memmap(path, np.uint8, "r+", shape=shape)
        t0 = time.perf_counter()
        source = SimulatorFrameSource(None, camera, [], seed, world=build_world(world_spec, seed, camera.width_px, camera.height_px))
        conn.send(("ready", time.perf_counter() - t0))
        while (msg := conn.recv()) is not None:
            shot, regions = msg
            t0 = time.perf_counter()
            frame = source.develop(shot, regions)
            slot = shot.index % _SLOTS  # the parent copied this slot's last frame out before submitting this shot
            slots[slot] = frame.image
            conn.send(("frame", slot, frame.regions, source.last_labels, 1e3 * (time.perf_counter() - t0)))
    except (EOFError, KeyboardInterrupt):
        return  # the parent went away or is stopping: nothing to answer
    except Exception:  # the parent raises it, with this traceback, at its next collect()
        with contextlib.suppress(BrokenPipeError, OSError):  # unless it is gone
            conn.send(("error", traceback.format_exc()))
    finally:
        conn.close()
