"""Clocks: the only things in chaser-bt that read time (DESIGN §3: time is passed in, never read).

A mission ticks on a :class:`Clock`. On a real aircraft that is the wall clock; against the
simulator at speed-up it is the vehicle's own boot time as it arrives in telemetry, so a
mission behaves the same at 1x and at 100x. Behaviours get the clock from ``setup(clock=...)``.
"""

from __future__ import annotations

import time
from typing import Callable, Protocol, runtime_checkable

__all__ = ["Clock", "WallClock", "ManualClock", "FunctionClock"]


@runtime_checkable
class Clock(Protocol):
    """Anything with ``now()``: seconds, monotonic, arbitrary epoch."""

    def now(self) -> float:
        """Current time in seconds."""
        ...


class WallClock:
    """Monotonic wall time, for flights on a real vehicle."""

    def now(self) -> float:
        return time.monotonic()


class ManualClock:
    """A clock that moves only when told to: for tests and lock-step simulation."""

    def __init__(self, t: float = 0.0) -> None:
        self._t = float(t)

    def now(self) -> float:
        return self._t

    def set(self, t: float) -> None:
        """Jump to ``t``; time never runs backwards."""
        if t < self._t:
            raise ValueError(f"clock cannot go back from {self._t} to {t}")
        self._t = float(t)

    def advance(self, dt: float) -> None:
        """Move forward by ``dt`` seconds."""
        self.set(self._t + dt)


class FunctionClock:
    """Adapts a zero-argument function returning seconds (e.g. a vehicle's boot time)."""

    def __init__(self, fn: Callable[[], float]) -> None:
        self._fn = fn

    def now(self) -> float:
        return self._fn()
