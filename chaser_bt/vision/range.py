"""Range to the target without its GPS (paper section 5: box-size ranging was too noisy to follow with).

Two estimators over the same measurement, the box's angular width and the target's known size:

- :func:`range_from_box` is what the paper tried: range = span / (2 tan(theta / 2)) per frame.
- :class:`RangeFilter` is a Kalman filter (filterpy) on [range, target radial speed]. Its prediction
  uses the ownship's own velocity along the line of sight, which is known exactly from telemetry:
  d(range)/dt = (v_target - v_own) . bearing, so ownship manoeuvres do not look like range noise.
  The box measurement has a relative error (``box_rel_std``), so its variance scales with range^2;
  gross outliers (a box that is suddenly much larger or smaller, e.g. a part-box after a tracker
  reseed) are gated out by their normalised innovation.

When the mission has the target's telemetry (the paper's flights), :meth:`RangeFilter.update_known`
takes the true distance instead, with its own small error. When a radar tracks the target, its
report adds two measurements: :meth:`RangeFilter.fuse_range`, the radar's position seen along the
camera's bearing (a few metres off at any range, where a box of a few pixels reads a distant target
far too close), and :meth:`RangeFilter.update_radial_speed`, its velocity along the bearing (box sizes
alone learn a target's dash at the chaser only over seconds, too late to back off before it passes
under the camera).
"""

from __future__ import annotations

import math

import numpy as np
from filterpy.kalman import KalmanFilter

__all__ = ["TARGET_SPAN_M", "range_from_box", "RangeFilter"]

_RANGE = np.array([[1.0, 0.0]])  # the measurement picks the state's range
_RADIAL_SPEED = np.array([[0.0, 1.0]])  # or the target's speed along the bearing

# Effective width (m) of each target kind as its box sees it: the widest horizontal extent seen
# side-on, averaged over yaw (rotor discs included): the median over 534 rendered training views (10-90 %: +-8 %).
# A person's box width varies far more (standing, lying, seen from any side: 10-90 % 0.42-1.81 m around
# the median 0.68 m over 284 rendered search views): ground-plane ranging (PipelineConfig.target_on_ground) is better.
TARGET_SPAN_M: dict[str, float] = {"s1000": 1.42, "phantom": 0.575, "person": 0.68}


def box_angular_width(x0: float, x1: float, cx: float, fx: float) -> float:
    """Angle (rad) between the rays through pixel columns x0 and x1 of a pinhole camera."""
    return abs(math.atan((x1 - cx) / fx) - math.atan((x0 - cx) / fx))


def range_from_box(box: tuple[float, float, float, float], span_m: float, cx: float, fx: float) -> float:
    """Range (m) of a target of width ``span_m`` whose box is ``box``: span / (2 tan(theta / 2))."""
    theta = box_angular_width(box[0], box[2], cx, fx)
    return span_m / (2.0 * math.tan(0.5 * max(theta, 1e-6)))


class RangeFilter:
    """Kalman filter on x = [range (m), target radial speed (m/s)] (see module docstring).

    Args:
        box_rel_std: 1-sigma relative error of one box-size range.
        target_accel_std: random-walk acceleration of the target's radial speed (m/s^2).
        gate_sigma: measurements further than this many sigmas from the prediction are dropped.
        min_range_m: floor on the estimate.
    """

    def __init__(self, box_rel_std: float = 0.12, target_accel_std: float = 1.5, gate_sigma: float = 4.0, min_range_m: float = 1.0) -> None:
        self.box_rel_std = box_rel_std
        self.target_accel_std = target_accel_std
        self.gate_sigma = gate_sigma
        self.min_range_m = min_range_m
        self.kf: KalmanFilter | None = None
        self.t: float | None = None
        self.rejected = 0

    def reset(self) -> None:
        self.kf, self.t = None, None

    def _start(self, t: float, r: float, std: float) -> None:
        kf = KalmanFilter(dim_x=2, dim_z=1, dim_u=1)
        kf.x = np.array([[r], [0.0]])
        kf.P = np.diag([std**2, 4.0**2])
        kf.H = np.array([[1.0, 0.0]])
        self.kf, self.t = kf, t

    def predict(self, t: float, own_velocity_enu: np.ndarray, bearing_enu: np.ndarray) -> None:
        """Advance to ``t`` with the ownship's closing speed along the bearing as the control input."""
        if self.kf is None or self.t is None or t <= self.t:
            return
        dt = t - self.t
        kf = self.kf
        kf.F = np.array([[1.0, dt], [0.0, 1.0]])
        kf.B = np.array([[dt], [0.0]])
        q = self.target_accel_std**2
        kf.Q = q * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
        u = -float(np.dot(own_velocity_enu, bearing_enu))
        kf.predict(u=np.array([[u]]))
        kf.x[0, 0] = max(kf.x[0, 0], self.min_range_m)
        self.t = t

    def _update(self, t: float, z: float, std: float) -> bool:
        if self.kf is None:
            self._start(t, z, std)
            return True
        kf = self.kf
        s = float(kf.P[0, 0]) + std**2
        if abs(z - float(kf.x[0, 0])) > self.gate_sigma * math.sqrt(s):
            self.rejected += 1
            if self.rejected >= 5:  # the estimate, not the boxes, is wrong: restart on the data
                self._start(t, z, std)
                self.rejected = 0
                return True
            return False
        self.rejected = 0
        self._fold(z, std, _RANGE)
        return True

    def _fold(self, z: float, std: float, h: np.ndarray) -> None:
        """One Kalman update of the state's ``h`` component by ``z`` told with ``std``; the range floored."""
        self.kf.update(np.array([[float(z)]]), R=np.array([[std**2]]), H=h)
        self.kf.x[0, 0] = max(self.kf.x[0, 0], self.min_range_m)

    def update_radial_speed(self, speed_mps: float, std_mps: float) -> None:
        """Fold in the target's speed along the bearing at the filter's time (after :meth:`predict`; m/s,
        away from the camera positive), measured by another sensor (the radar track's velocity dotted
        with the camera's bearing). Nothing before a range has started the filter: a speed alone places
        nothing."""
        if self.kf is None or not (math.isfinite(speed_mps) and std_mps > 0.0):
            return
        self._fold(speed_mps, std_mps, _RADIAL_SPEED)

    def fuse_range(self, range_m: float, std_m: float, max_ratio: float = 4.0) -> bool:
        """Fold in a range measured by another sensor (the radar's target position, seen along the
        camera's bearing). It is dropped only when it is more than ``max_ratio`` times the estimate
        or less than its ``1 / max_ratio`` (another object on the bearing), never on the filter's own
        sigma: the boxes of a distant target read it far too close, with a confidence their own
        error model cannot know is misplaced, and this is the measurement that corrects them. At the
        filter's time (after :meth:`predict`); never restarts the filter. False when dropped."""
        if self.kf is None or not (math.isfinite(range_m) and range_m > 0.0 and std_m > 0.0):
            return False
        r = float(self.kf.x[0, 0])
        if not r / max_ratio <= range_m <= r * max_ratio:
            return False
        self._fold(range_m, std_m, _RANGE)
        return True

    def update_box(self, t: float, box: tuple[float, float, float, float], span_m: float, cx: float, fx: float) -> bool:
        """Fold in a box-size range; False when the gate dropped it."""
        z = range_from_box(box, span_m, cx, fx)
        r_ref = float(self.kf.x[0, 0]) if self.kf is not None else z
        return self._update(t, z, self.box_rel_std * max(r_ref, self.min_range_m))

    def update_known(self, t: float, range_m: float, std_m: float = 0.5) -> bool:
        """Fold in a range from the target's own telemetry (GPS)."""
        return self._update(t, float(range_m), std_m)

    @property
    def range_m(self) -> float:
        return float(self.kf.x[0, 0]) if self.kf is not None else float("nan")

    @property
    def range_std_m(self) -> float:
        return float(math.sqrt(self.kf.P[0, 0])) if self.kf is not None else float("nan")
