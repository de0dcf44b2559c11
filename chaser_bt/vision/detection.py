"""A detector's output for one object (kept free of torch so trackers and behaviours load light)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Detection"]


@dataclass(frozen=True)
class Detection:
    """One detected object: ``box`` (x0, y0, x1, y1) in frame pixels, score in [0, 1], class."""

    box: tuple[float, float, float, float]
    score: float
    class_id: int
    class_name: str

    @property
    def centre(self) -> tuple[float, float]:
        return (0.5 * (self.box[0] + self.box[2]), 0.5 * (self.box[1] + self.box[3]))
