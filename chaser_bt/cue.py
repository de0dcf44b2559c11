"""A target cue: where a sensor last put the target, when, and how sure it was.

The cue is the currency between the mission's sensors and its planners: the ground radar writes
one (paper section 3.3), the search starts its belief from the last one (section 3.4), and later
the camera and the target's own telemetry write them too. Positions are ENU in the mission frame;
``t`` is mission time (the Clock's seconds), so a cue's age is ``now - t``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["TargetCue", "TargetEstimate", "sight_offset_sigma"]


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
        object.__setattr__(self, "position_enu", _finite_array(self.position_enu, (3,), "cue position"))
        object.__setattr__(self, "covariance_enu", _finite_array(self.covariance_enu, (3, 3), "cue covariance"))
        if self.velocity_enu is not None:
            object.__setattr__(self, "velocity_enu", _finite_array(self.velocity_enu, (3,), "cue velocity"))

    def age(self, now: float) -> float:
        """Seconds since the measurement."""
        return now - self.t

    def position_at(self, t: float) -> np.ndarray:
        """The position carried to time ``t`` on the cue's velocity (as measured when it has none)."""
        if self.velocity_enu is None:
            return self.position_enu
        return self.position_enu + self.velocity_enu * (t - self.t)

    def coasted(self, t: float, accel_mps2: float) -> TargetCue:
        """The cue carried to ``t`` on its velocity, its covariance grown by a target that may have
        accelerated at up to ``accel_mps2`` meanwhile (``(a dt^2 / 2)^2`` on each axis)."""
        dt = max(0.0, t - self.t)
        grow = (0.5 * accel_mps2 * dt * dt) ** 2
        return TargetCue(t, self.position_at(t), self.covariance_enu + grow * np.eye(3), self.velocity_enu, self.source,
                         self.track_id)


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
        bearing = _finite_array(self.bearing_enu, (3,), "bearing")
        if abs(float(np.linalg.norm(bearing)) - 1.0) > 1e-6:
            raise ValueError(f"bearing must be a unit 3-vector, got {self.bearing_enu!r}")
        if not 0.0 <= self.confidence <= 1.0:
            raise ValueError(f"confidence must be in [0, 1], got {self.confidence}")
        object.__setattr__(self, "bearing_enu", bearing)


def sight_offset_sigma(camera_enu: np.ndarray, bearing_enu: np.ndarray, point_enu: np.ndarray,
                       covariance_enu: np.ndarray) -> float:
    """How far a point (a radar report, a cue) lies from a camera's line of sight ``camera + s * bearing``
    (the range ``s`` left free: the camera measures it badly), in the point's own covariance: the
    smallest Mahalanobis distance of the line from it, ``sqrt(d'S d - (b'S d)^2 / (b'S b))`` with
    ``S`` the inverse covariance and ``d = point - camera``."""
    d = np.asarray(point_enu, float) - np.asarray(camera_enu, float)
    b = np.asarray(bearing_enu, float)
    s_inv = np.linalg.inv(np.asarray(covariance_enu, float))
    bsb = float(b @ s_inv @ b)
    bsd = float(b @ s_inv @ d)
    return math.sqrt(max(float(d @ s_inv @ d) - bsd * bsd / bsb, 0.0))


def _finite_array(value: object, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as a float array of ``shape`` with only finite entries, or a ValueError naming ``what``."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        array = None
    if array is None or array.shape != shape or not np.all(np.isfinite(array)):
        raise ValueError(f"{what} must be finite numbers of shape {shape}, got {value!r}")
    return array

