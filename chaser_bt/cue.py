"""A target cue: where a sensor last put the target, when, and how sure it was.

The cue is the currency between the mission's sensors and its planners: the ground radar writes
one (paper section 3.3), the search starts its belief from the last one (section 3.4), and later
the camera and the target's own telemetry write them too. Positions are ENU in the mission frame;
``t`` is mission time (the Clock's seconds), so a cue's age is ``now - t``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["TargetCue"]


@dataclass(frozen=True)
class TargetCue:
    """One target position estimate.

    Args:
        t: mission time of the measurement (s).
        position_enu: (3,) metres in the mission's ENU frame.
        covariance_enu: (3, 3) position covariance (m^2), e.g. a radar's range/azimuth/elevation
            noise carried into ENU through the measurement Jacobian.
        velocity_enu: (3,) m/s when the sensor estimates it, else None.
        source: which sensor made it ("radar", "vision", "telemetry", ...).
        track_id: the sensor's own id for the target, if it has one.
    """

    t: float
    position_enu: np.ndarray
    covariance_enu: np.ndarray = field(default_factory=lambda: np.eye(3))
    velocity_enu: np.ndarray | None = None
    source: str = ""
    track_id: int | None = None

    def __post_init__(self) -> None:
        pos = np.asarray(self.position_enu, dtype=float)
        cov = np.asarray(self.covariance_enu, dtype=float)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise ValueError(f"cue position must be 3 finite numbers, got {self.position_enu!r}")
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise ValueError(f"cue covariance must be a finite 3x3 matrix, got shape {cov.shape}")
        object.__setattr__(self, "position_enu", pos)
        object.__setattr__(self, "covariance_enu", cov)
        if self.velocity_enu is not None:
            vel = np.asarray(self.velocity_enu, dtype=float)
            if vel.shape != (3,) or not np.all(np.isfinite(vel)):
                raise ValueError(f"cue velocity must be 3 finite numbers, got {self.velocity_enu!r}")
            object.__setattr__(self, "velocity_enu", vel)

    def age(self, now: float) -> float:
        """Seconds since the measurement."""
        return now - self.t
