"""A target cue: where a sensor last put the target, when, and how sure it was.

The cue is the currency between the mission's sensors and its planners: the ground radar writes
one (paper section 3.3), the search starts its belief from the last one (section 3.4), and later
the camera and the target's own telemetry write them too. Positions are ENU in the mission frame;
``t`` is mission time (the Clock's seconds), so a cue's age is ``now - t``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["TargetCue", "TargetEstimate"]


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


@dataclass(frozen=True)
class TargetEstimate(TargetCue):
    """A cue from an on-board sensor that sees the target along a line of sight (the camera).

    The bearing is what the camera measures well; the range is what it measures badly (paper
    section 5: range from box size was too noisy to follow with), so both travel with their own
    uncertainty and ``position_enu`` is the camera position plus ``range_m`` along the bearing.

    Args:
        bearing_enu: (3,) unit vector from the camera to the target, ENU.
        range_m: estimated distance along the bearing (m); ``range_std_m`` its 1-sigma.
        confidence: detector/tracker confidence in [0, 1].
    """

    bearing_enu: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    range_m: float = float("nan")
    range_std_m: float = float("nan")
    confidence: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        bearing = np.asarray(self.bearing_enu, dtype=float)
        norm = float(np.linalg.norm(bearing)) if bearing.shape == (3,) else 0.0
        if not np.isfinite(norm) or abs(norm - 1.0) > 1e-6:
            raise ValueError(f"bearing must be a unit 3-vector, got {self.bearing_enu!r}")
        if not 0.0 <= self.confidence <= 1.0:
            raise ValueError(f"confidence must be in [0, 1], got {self.confidence}")
        object.__setattr__(self, "bearing_enu", bearing)

