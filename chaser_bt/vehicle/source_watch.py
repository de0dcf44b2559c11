"""One vehicle, one voice: MAVLink sequence numbers that interleave mean two senders share its ids.

Every MAVLink sender numbers its packets 0..255 in turn, one counter per link. A lossy radio skips
numbers forwards; nothing on one link makes them go backwards, except a second sender using the
vehicle's system and component id: a clone, a spoof, or a misconfigured companion computer. Two
interleaved counters step backwards about half the time. On an unsigned link the telemetry of
such a vehicle cannot be believed (the clone may say "landed, disarmed" while the real one
flies); MAVLink 2 signing is the cure, this watch is the alarm.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

__all__ = ["SequenceWatch"]


@dataclass
class SequenceWatch:
    """Feed it each message's sequence number from the vehicle's (system, component); :attr:`fault`
    says when at least ``max_backward`` of the last ``window`` steps went backwards."""

    window: int = 100
    max_backward: int = 10
    backward_steps: int = field(default=0, init=False)  # over the whole link, for the counters
    _last: int | None = field(default=None, init=False)
    _recent: deque[bool] = field(default_factory=deque, init=False, repr=False)
    _recent_backward: int = field(default=0, init=False)  # sum(_recent), kept as it changes

    def observe(self, seq: int) -> None:
        seq &= 0xFF
        if self._last is not None:
            step = (seq - self._last) & 0xFF
            backward = step >= 128  # 1..128 packets back; a lost packet only ever skips forward
            self.backward_steps += backward
            self._recent.append(backward)
            self._recent_backward += backward
            if len(self._recent) > self.window:
                self._recent_backward -= self._recent.popleft()
        self._last = seq

    @property
    def fault(self) -> str:
        """'' while the sequence is one sender's; else why not."""
        backward = self._recent_backward
        if backward < self.max_backward:
            return ""
        return (f"two senders use the vehicle's ids: {backward} of the last {len(self._recent)} MAVLink sequence "
                f"numbers went backwards (sign the link: --signing-key)")
