"""A find: where a search-and-rescue mission puts the person its camera saw (DESIGN §1, the second mission).

The camera measures a bearing well and a range badly (paper section 5: range from the box size
was too noisy to follow with). A person is on the ground, so the bearing alone fixes them: the
line of sight meets the horizontal plane at the height of the box centre (:func:`ground_fix`, the
vision pipeline's ground ranging on that plane). Each confident camera estimate gives one fix;
the find is their component-wise median over the fixes within ``gate_m`` of the median of all of
them (one robust re-weighting step: a tracker box that slid onto a bush for a few frames does not
drag the find), reported once ``min_fixes`` fixes agree over at least ``min_span_s`` (the trackers
carry a box for a while after one detection, so a single false detection gives many agreeing
fixes, but over less time than the trackers keep an unconfirmed box) (:class:`FindEstimator`).

Such a find is a candidate. Over a real field the detector also fires, now and then and in the same
place, on a post, a bush or a dark rock, so a candidate is reported only after a second, closer look
(:class:`FindCheck`): the vehicle goes near it and new agreeing fixes from close by confirm it; a
candidate the camera has been near for a while without seeing again is rejected, and fixes in its
place are ignored from then on (:meth:`FindEstimator.reject`), so the search goes on.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from chaser_bt.cue import TargetEstimate
from chaser_bt.geo import GeoPoint, LocalFrame
from chaser_bt.vision.pipeline import ground_range

__all__ = ["Find", "FindCheck", "FindEstimator", "FindVerdict", "ground_fix"]


def ground_fix(estimate: TargetEstimate, plane_z_m: float, max_range_m: float) -> np.ndarray | None:
    """Where ``estimate``'s line of sight meets the plane z = ``plane_z_m`` (ENU), or None.

    None when the bearing does not point down (it meets the plane behind the camera or never),
    when the estimate has no finite range (the camera position is ``position - range * bearing``)
    or when the plane is farther than ``max_range_m`` along the ray.
    """
    if not math.isfinite(estimate.range_m):
        return None
    b = estimate.bearing_enu
    camera = estimate.position_enu - estimate.range_m * b
    s = ground_range(camera - [0.0, 0.0, plane_z_m], b, min_down=1e-6)  # the plane as the pipeline's ground
    if s is None or s > max_range_m:
        return None
    return camera + s * b


@dataclass(frozen=True)
class Find:
    """A person located: ENU position (m), its geodetic point, spread and support.

    Args:
        t: mission time of the latest fix used (s).
        position_enu: (3,) the median ground fix.
        geodetic: the same point as latitude/longitude/altitude (None when the mission frame is unknown).
        std_m: horizontal 1-sigma uncertainty of the median (RMS distance of the agreeing fixes / sqrt(n)).
        confidence: share of all fixes that agree, times their mean detector confidence, in [0, 1].
        fixes: how many fixes agree.
    """

    t: float
    position_enu: np.ndarray
    geodetic: GeoPoint | None
    std_m: float
    confidence: float
    fixes: int

    def to_dict(self) -> dict:
        """Plain numbers for logs and the ground stream."""
        g = self.geodetic
        return {"t": self.t, "position_enu": [round(float(v), 2) for v in self.position_enu],
                "lat_deg": None if g is None else g.lat_deg, "lon_deg": None if g is None else g.lon_deg,
                "alt_m": None if g is None else g.alt_m, "std_m": round(self.std_m, 2),
                "confidence": round(self.confidence, 3), "fixes": self.fixes}


class FindEstimator:
    """Collects ground fixes from camera estimates and reports a :class:`Find` once they agree.

    Args:
        plane_z_m: ENU height of the plane the box centre is on (about half a standing person's
            height above flat ground at the origin's altitude).
        max_range_m: fixes farther than this along the line of sight are not used (shallow rays
            turn small bearing errors into large ground errors).
        gate_m: a fix farther than this (horizontally) from the median of all fixes does not agree.
        min_fixes: agreeing fixes needed before a find is reported.
        min_span_s: the agreeing fixes must span at least this long (s).
        max_fixes: only the latest ``max_fixes`` fixes are kept.
    """

    def __init__(self, plane_z_m: float = 0.5, max_range_m: float = 60.0, gate_m: float = 10.0,
                 min_fixes: int = 5, min_span_s: float = 0.0, max_fixes: int = 100) -> None:
        if not (max_range_m > 0 and gate_m > 0 and 1 <= min_fixes <= max_fixes and min_span_s >= 0):
            raise ValueError(f"need max_range_m > 0, gate_m > 0, 1 <= min_fixes <= max_fixes and min_span_s >= 0, got "
                             f"{max_range_m}, {gate_m}, {min_fixes}, {max_fixes}, {min_span_s}")
        self.plane_z_m, self.max_range_m, self.gate_m = float(plane_z_m), float(max_range_m), float(gate_m)
        self.min_fixes, self.min_span_s, self.max_fixes = int(min_fixes), float(min_span_s), int(max_fixes)
        self._fixes: list[tuple[float, np.ndarray, float, float]] = []  # (t, point, confidence, camera to point m)
        self._rejected: list[np.ndarray] = []  # horizontal centres of rejected candidates
        self.ignored_fixes = 0  # fixes that fell where a candidate was rejected

    @property
    def fix_count(self) -> int:
        return len(self._fixes)

    def add(self, estimate: TargetEstimate) -> bool:
        """Add the ground fix of ``estimate``; False when it gives none (see :func:`ground_fix`) or when
        it falls within ``gate_m`` of a rejected candidate (counted in ``ignored_fixes``)."""
        p = ground_fix(estimate, self.plane_z_m, self.max_range_m)
        if p is None:
            return False
        if any(np.hypot(*(p[:2] - c)) <= self.gate_m for c in self._rejected):
            self.ignored_fixes += 1
            return False
        camera = estimate.position_enu - estimate.range_m * estimate.bearing_enu
        self._fixes.append((estimate.t, p, estimate.confidence, float(np.linalg.norm(p - camera))))
        del self._fixes[:-self.max_fixes]
        return True

    def reject(self, position_enu: np.ndarray) -> int:
        """Forget the fixes within ``gate_m`` of ``position_enu`` (horizontally) and ignore any that fall
        there later: a candidate the closer look did not confirm. Returns how many fixes were dropped."""
        centre = np.asarray(position_enu, float)[:2].copy()
        self._rejected.append(centre)
        kept = [f for f in self._fixes if np.hypot(*(f[1][:2] - centre)) > self.gate_m]
        dropped = len(self._fixes) - len(kept)
        self._fixes = kept
        return dropped

    def support(self, position_enu: np.ndarray, since_t: float, within_m: float) -> tuple[int, float]:
        """Fixes later than ``since_t`` within ``gate_m`` of ``position_enu`` (horizontally) and taken from
        no farther than ``within_m`` (camera to fix): how many, and the time they span (s)."""
        centre = np.asarray(position_enu, float)[:2]
        times = [t for t, p, _, slant in self._fixes
                 if t > since_t and slant <= within_m and np.hypot(*(p[:2] - centre)) <= self.gate_m]
        return len(times), (max(times) - min(times) if times else 0.0)

    def find(self, frame: LocalFrame | None = None) -> Find | None:
        """The find from the fixes so far, or None before ``min_fixes`` of them agree over ``min_span_s``."""
        if len(self._fixes) < self.min_fixes:
            return None
        pts = np.array([f[1] for f in self._fixes])
        centre = np.median(pts, axis=0)
        agree = np.hypot(*(pts[:, :2] - centre[:2]).T) <= self.gate_m
        n = int(agree.sum())
        times = np.array([f[0] for f in self._fixes])[agree]
        if n < self.min_fixes or (n and times.max() - times.min() < self.min_span_s):
            return None
        inliers = pts[agree]
        position = np.median(inliers, axis=0)
        spread = float(np.sqrt(np.mean(np.sum((inliers[:, :2] - position[:2]) ** 2, axis=1))))
        conf = np.array([f[2] for f in self._fixes])[agree]
        return Find(t=float(times.max()), position_enu=position, geodetic=None if frame is None else frame.to_geodetic(position),
                    std_m=spread / math.sqrt(n), confidence=float(np.clip(n / len(pts) * conf.mean(), 0.0, 1.0)), fixes=n)


class FindVerdict(enum.Enum):
    """What the closer look made of a candidate."""

    PENDING = "pending"  # not seen again from close by yet
    CONFIRMED = "confirmed"  # seen again from close by: report it
    REJECTED = "rejected"  # the camera was near it for ``timeout_s`` and did not see it again


class FindCheck:
    """The second look: confirms a candidate find with new fixes from close by, or rejects it.

    A candidate is confirmed once ``confirm_fixes`` agreeing fixes taken after it was first put
    forward, each from no farther than ``close_m`` (camera to fix), span ``min_span_s`` (one false
    detection carried by the trackers does not). It is rejected once the vehicle has been within
    ``close_m`` of it (horizontally) for ``timeout_s`` without that. A candidate that moves more than
    ``gate_m`` is a new one. Once confirmed, a find stays confirmed.

    Args:
        close_m: how near the camera must be for a fix to count as a closer look (m).
        confirm_fixes: new close fixes needed.
        min_span_s: the time they must span (s).
        timeout_s: time near the candidate after which it is rejected (s).
        gate_m: a candidate that moved this far is a new one (m); the estimator's gate.
    """

    def __init__(self, close_m: float = 30.0, confirm_fixes: int = 3, min_span_s: float = 1.0, timeout_s: float = 15.0,
                 gate_m: float = 10.0) -> None:
        if not (close_m > 0 and confirm_fixes >= 1 and min_span_s >= 0 and timeout_s > 0 and gate_m > 0):
            raise ValueError(f"need close_m > 0, confirm_fixes >= 1, min_span_s >= 0, timeout_s > 0 and gate_m > 0, got "
                             f"{close_m}, {confirm_fixes}, {min_span_s}, {timeout_s}, {gate_m}")
        self.close_m, self.confirm_fixes, self.min_span_s = float(close_m), int(confirm_fixes), float(min_span_s)
        self.timeout_s, self.gate_m = float(timeout_s), float(gate_m)
        self.confirmed = False
        self._anchor: np.ndarray | None = None  # the candidate under check (horizontal)
        self._since_t = -math.inf  # when it was put forward
        self._near_since: float | None = None  # when the vehicle first came near it

    def update(self, t: float, vehicle_enu: np.ndarray, candidate: Find, estimator: FindEstimator) -> FindVerdict:
        """The verdict on ``candidate`` at time ``t`` with the vehicle at ``vehicle_enu``."""
        if self.confirmed:
            return FindVerdict.CONFIRMED
        here = np.asarray(candidate.position_enu, float)[:2]
        if self._anchor is None or np.hypot(*(here - self._anchor)) > self.gate_m:
            self._anchor, self._since_t, self._near_since = here.copy(), t, None
        n, span = estimator.support(candidate.position_enu, self._since_t, self.close_m)
        if n >= self.confirm_fixes and span >= self.min_span_s:
            self.confirmed = True
            return FindVerdict.CONFIRMED
        if np.hypot(*(np.asarray(vehicle_enu, float)[:2] - here)) <= self.close_m:
            if self._near_since is None:
                self._near_since = t
            elif t - self._near_since >= self.timeout_s:
                self._anchor = self._near_since = None
                return FindVerdict.REJECTED
        return FindVerdict.PENDING

    def close_fixes(self, candidate: Find, estimator: FindEstimator) -> int:
        """New close fixes of ``candidate`` so far (for feedback)."""
        return estimator.support(candidate.position_enu, self._since_t, self.close_m)[0]
