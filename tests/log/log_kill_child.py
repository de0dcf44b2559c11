"""Child process of the SIGKILL test: flies the radar hop in real time, recording to argv[1], and
prints ``<mission time> <wall time>`` after every tick until it is killed."""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from log_flight import fly  # noqa: E402


def main() -> None:
    def report(runner) -> None:
        print(f"{runner.clock.now()!r} {time.time()!r}", flush=True)

    flush_period_s = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0  # the test's control: a longer period loses more
    fly(Path(sys.argv[1]), pace=1.0, on_tick=report, flush_period_s=flush_period_s)


if __name__ == "__main__":
    main()
