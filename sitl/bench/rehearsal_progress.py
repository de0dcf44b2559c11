"""A rehearsal's progress on the terminal: simulated time against the time limit, the mission's
phase and the real-time factor, as a tqdm bar that updates a few times a second.

``rehearse(..., progress=bar)`` calls the bar after every tick with the simulated time and the
phase (``/mission/phase``); the bar is drawn only on a terminal unless ``always`` (a log file
would fill with redraws).
"""

from __future__ import annotations

import sys
import time
from typing import IO

from tqdm import tqdm

__all__ = ["RehearsalProgress"]


class RehearsalProgress:
    """Callable ``(sim_time_s, phase)``: moves the bar to ``sim_time_s`` of ``total_s``."""

    def __init__(self, total_s: float, stream: IO[str] = sys.stderr, always: bool = False,
                 min_interval_s: float = 0.25) -> None:
        self.bar = tqdm(total=round(float(total_s), 1), unit="sim s", file=stream, dynamic_ncols=True,
                        disable=None if not always else False, mininterval=min_interval_s,
                        bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} sim s [{elapsed}<{remaining}{postfix}]")
        self.min_interval_s = min_interval_s
        self._wall0 = time.perf_counter()
        self._last_wall = -1.0
        self._phase: str | None = None

    def __call__(self, sim_time_s: float, phase: str | None) -> None:
        wall = time.perf_counter() - self._wall0
        if wall - self._last_wall < self.min_interval_s and phase == self._phase:
            return
        self._last_wall, self._phase = wall, phase
        factor = sim_time_s / wall if wall > 0 else 0.0
        self.bar.set_postfix_str(f"{phase or '-'}, {factor:.1f}x real time", refresh=False)
        self.bar.update(min(round(sim_time_s, 1), self.bar.total) - self.bar.n)

    def close(self) -> None:
        """End the bar (its last state stays on the terminal)."""
        self.bar.close()
