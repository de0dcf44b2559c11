"""The relative-position follow controller: the paper's three PID loops (section 3.2, table 1).

The chaser keeps the target at a set slant range and elevation, from above, with a fixed camera
tilted down by that elevation. Slant range 40 m and elevation 40 deg become the set-points the
loops use: ground range ``R cos(el)`` = 30.6 m and relative height ``R sin(el)`` = 25.7 m.

Three loops at 5 Hz, each on a median-filtered (window 5) process variable:

- yaw rate from the target's azimuth off the nose (set-point 0): K_P 0.25, K_I 0.002,
  K_D = 0.0003 R (R the ground range: azimuth moves faster when close);
- pitch from ground range (set-point 30.6 m): 0.4 / 0.01 / 0.2;
- climb rate from relative height (set-point 25.7 m): 0.6 / 0.01 / 0.02.

Units (the paper gives none): azimuth in rad -> yaw rate in rad/s; ground range in m -> forward
acceleration in m/s^2 (the paper's loop "computes the required yaw rate, climb rate, and
acceleration"), flown as a pitch angle ``atan(a / g)``; relative height in m -> climb rate in m/s.
The forward error is the range error along the nose, ``(R_g - R_sp) cos(az)``, so a target off to
the side is first turned towards rather than chased sideways.

Options the paper left out:

- ``use_roll``: full horizontal control. A fourth loop on roll matches the target's sideways
  velocity across the nose, so the line of sight keeps its direction instead of the yaw loop
  having to chase it (the paper's "roll commands are needed to take full advantage of the
  agility of multicopters").
- ``feed_forward``: the target's velocity (from the cue, else differenced positions) feeds the
  loops: the line-of-sight rate to yaw, the target's climb rate to climb, and a velocity-matching
  term along the nose (and across it with roll) to the accelerations.

- ``min_range_m``: a floor on the slant range. Inside it the GUIDED velocity gains a back-off along
  the line of sight (``backoff_gain`` m/s per metre inside) and a climb, so a target that stops or
  turns back at the chaser is not overrun into the camera's blind zone; a target's velocity fed
  forward cannot carry the chaser closer than the floor.

- ``max_closing_mps``: a limit on the GUIDED range correction, the speed at which the chaser closes
  on the set-point beyond the target's own velocity. An engagement 100 m out otherwise closes at
  the speed limit: the airframe leans 30 degrees, which lifts a target near the horizon out of the
  top of a fixed camera's view for the whole approach, and arrives at a closing speed the autopilot
  cannot brake from in the set-point's distance (at 2.5 m/s^2, 13 m/s needs 34 m), so the target
  passes under the camera.

- ``range_smoothing_s``: lean on what the camera measures well. A camera estimate
  (:class:`~chaser_bt.cue.TargetEstimate`) has an accurate bearing and a poor range (box size;
  the paper's section 5: "too variable to use with the relative position controller, even with
  strong smoothing"). With this time constant > 0, the controller keeps the bearing as measured
  and replaces the range by a slow one (:class:`LineOfSightRange`: a first-order low-pass that
  moves with the chaser's own, well-known, velocity along the line of sight), so range noise no
  longer reaches the loops and the differenced target velocity: azimuth and elevation, hence the
  target's place in the image, are held on the accurate measurement, and a range error only
  changes the stand-off distance, slowly.

Safety (section 3.2): no target data for ``stale_after_s`` (2 s) -> a hover command at once, and the
loops reset; the behaviour sends hover on exit.

Outputs: :class:`FollowCommand` carries the loop outputs, the ALT_HOLD sticks
(:class:`~chaser_bt.control.sticks.RcSticks`, the paper's RC override) and a GUIDED velocity
alternative (``velocity_enu`` + ``yaw_rate``) built from the same loops.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from chaser_bt.control.pid import Pid, PidGains
from chaser_bt.control.sticks import GRAVITY, RcSticks, StickMap
from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.geo import wrap_pi

__all__ = ["FollowConfig", "FollowCommand", "FollowController", "ProcessVariables", "MedianWindow",
           "LineOfSightRange", "process_variables"]


@dataclass(frozen=True)
class FollowConfig:
    """Set-point geometry, gains, rates and options of the follow controller (SI units)."""

    slant_range_m: float = 40.0
    elevation_rad: float = math.radians(40.0)
    # Table 1 with I and D per 5 Hz control step (see the module docstring): I x 5 /s, D / 0.2 s.
    yaw: PidGains = PidGains(0.25, 0.002 * 5.0, 0.0, -1.0, 1.0, 0.05)  # yaw stick per rad of azimuth
    yaw_kd_per_m: float = 0.0003 * 5.0  # K_D = 0.0003 R per step
    pitch: PidGains = PidGains(0.4, 0.01 * 5.0, 0.2 * 5.0, -20.0, 20.0, 1.5)  # m/s^2 per m of ground range
    climb: PidGains = PidGains(0.6, 0.01 * 5.0, 0.02 * 5.0, -10.0, 10.0, 1.0)  # m/s per m of relative height
    roll: PidGains = PidGains(1.0, 0.1, 0.0, -20.0, 20.0, 1.5)  # m/s^2 per m/s of sideways relative velocity
    measured_rates: bool = True  # derivative terms from measured velocities when the target's is known
    use_roll: bool = False
    feed_forward: bool = False
    ff_velocity_gain: float = 0.6  # 1/s: m/s^2 of acceleration per m/s of relative velocity
    median_window: int = 5
    rate_hz: float = 5.0
    stale_after_s: float = 2.0
    guided_position_gain: float = 0.5  # 1/s: GUIDED velocity per metre of horizontal position error
    guided_speed_max: float = 20.0  # m/s
    range_smoothing_s: float = 0.0  # > 0: camera estimates keep their bearing, range low-passed (see module doc)
    max_lean_rad: float | None = None  # lean limit below the vehicle's ANGLE_MAX (keeps a fixed camera's view)
    min_range_m: float = 0.0  # > 0: closer than this (slant), GUIDED backs off along the line of sight
    backoff_gain: float = 1.0  # 1/s: m/s of back-off per metre inside min_range_m
    max_closing_mps: float = 0.0  # > 0: GUIDED closes on (or opens from) the set-point at most this fast

    def __post_init__(self) -> None:
        if not self.slant_range_m > 0.0:
            raise ValueError(f"slant_range_m must be > 0, got {self.slant_range_m}")
        if not 0.0 <= self.elevation_rad < math.pi / 2:
            raise ValueError(f"elevation must be in [0, 90) deg, got {math.degrees(self.elevation_rad):.1f}")
        if self.median_window < 1 or not self.rate_hz > 0.0 or not self.stale_after_s > 0.0:
            raise ValueError("median_window >= 1, rate_hz > 0 and stale_after_s > 0 are required")
        if self.max_lean_rad is not None and not 0.0 < self.max_lean_rad < math.pi / 2:
            raise ValueError(f"max_lean_rad must be in (0, 90) deg, got {self.max_lean_rad}")
        if not self.range_smoothing_s >= 0.0:
            raise ValueError(f"range_smoothing_s must be >= 0, got {self.range_smoothing_s}")
        if not self.max_closing_mps >= 0.0:
            raise ValueError(f"max_closing_mps must be >= 0, got {self.max_closing_mps}")
        if not (self.min_range_m >= 0.0 and self.backoff_gain >= 0.0) or self.min_range_m >= self.slant_range_m:
            raise ValueError(f"min_range_m must be in [0, slant_range_m) and backoff_gain >= 0, got "
                             f"{self.min_range_m}, {self.backoff_gain}")

    @property
    def ground_range_sp(self) -> float:
        """Ground-range set-point (m): 30.6 for 40 m at 40 deg."""
        return self.slant_range_m * math.cos(self.elevation_rad)

    @property
    def height_sp(self) -> float:
        """Relative-height set-point (m, chaser above target): 25.7 for 40 m at 40 deg."""
        return self.slant_range_m * math.sin(self.elevation_rad)

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz


@dataclass(frozen=True)
class ProcessVariables:
    """Where the target is relative to the chaser: azimuth off the nose (rad, left positive),
    ground range (m) and relative height (m, chaser above target positive)."""

    azimuth_rad: float
    ground_range_m: float
    rel_height_m: float

    @property
    def slant_range_m(self) -> float:
        return math.hypot(self.ground_range_m, self.rel_height_m)

    @property
    def elevation_rad(self) -> float:
        """Elevation of the chaser above the target as seen from the target (rad)."""
        return math.atan2(self.rel_height_m, self.ground_range_m)


def process_variables(own_pos_enu: np.ndarray, own_yaw_enu: float, target_pos_enu: np.ndarray) -> ProcessVariables:
    """The paper's three process variables for a target at ``target_pos_enu`` (ENU)."""
    d = np.asarray(target_pos_enu, float) - np.asarray(own_pos_enu, float)
    bearing = math.atan2(d[1], d[0])
    return ProcessVariables(wrap_pi(bearing - own_yaw_enu), float(math.hypot(d[0], d[1])), float(-d[2]))


class MedianWindow:
    """Median of the last ``n`` samples (the paper's filter on each process variable)."""

    def __init__(self, n: int) -> None:
        self._values: deque[float] = deque(maxlen=n)

    def reset(self) -> None:
        self._values.clear()

    def __len__(self) -> int:
        return len(self._values)

    def push(self, value: float) -> float:
        self._values.append(float(value))
        return float(np.median(self._values))


class LineOfSightRange:
    """A slow range along an accurate bearing: first-order low-pass with time constant ``tau_s``.

    Between measurements the range moves with the chaser's own velocity along the line of sight
    (known from its telemetry): ``r -= (v_own . b) dt``; each measurement then pulls it by
    ``1 - exp(-dt / tau)``. What the target itself does along the line of sight shows up only
    through the measurements, i.e. with a lag of about ``tau_s``.
    """

    def __init__(self, tau_s: float) -> None:
        if not tau_s > 0.0:
            raise ValueError(f"tau_s must be > 0, got {tau_s}")
        self.tau_s = tau_s
        self.range_m: float | None = None
        self._t = 0.0

    def reset(self) -> None:
        self.range_m = None

    def update(self, t: float, range_m: float, bearing_enu: np.ndarray, own_vel_enu: np.ndarray) -> float:
        """Take a measured range at ``t``; the smoothed range."""
        if self.range_m is None or t <= self._t:
            if self.range_m is None:
                self.range_m, self._t = float(range_m), t
            return self.range_m
        dt = t - self._t
        closing = float(np.dot(own_vel_enu, bearing_enu)) if np.all(np.isfinite(own_vel_enu)) else 0.0
        predicted = max(self.range_m - closing * dt, 1.0)
        self.range_m = predicted + (1.0 - math.exp(-dt / self.tau_s)) * (float(range_m) - predicted)
        self._t = t
        return self.range_m


@dataclass(frozen=True)
class FollowCommand:
    """One control step's demand.

    ``hover`` True: stop (stale or missing target data; ``reason`` says which). Otherwise the loop
    outputs: ``yaw_rate`` (rad/s ENU, counter-clockwise), ``forward_accel`` / ``right_accel``
    (m/s^2, body), ``climb`` (m/s); ``sticks`` for ALT_HOLD and ``velocity_enu`` for GUIDED, with
    either ``yaw_rate`` or ``heading_enu`` (the filtered bearing to the target, ENU yaw: for an
    autopilot whose own yaw controller should turn the nose).
    """

    t: float
    hover: bool
    reason: str = ""
    yaw_rate: float = 0.0
    forward_accel: float = 0.0
    right_accel: float = 0.0
    climb: float = 0.0
    sticks: RcSticks = RcSticks(1500, 1500, 1500, 1500)
    velocity_enu: np.ndarray = field(default_factory=lambda: np.zeros(3))
    pv: ProcessVariables | None = None
    heading_enu: float = 0.0


class FollowController:
    """The paper's follow loops; call :meth:`update` every tick, it computes at ``rate_hz``.

    Args:
        config: set-points, gains and options.
        sticks: the vehicle's stick mapping (its ArduCopter parameters) for the RC override.
    """

    def __init__(self, config: FollowConfig = FollowConfig(), sticks: StickMap = StickMap()) -> None:
        self.config = config
        self.stick_map = sticks
        self.yaw_pid = Pid(config.yaw)
        self.pitch_pid = Pid(config.pitch)
        self.roll_pid = Pid(config.roll)
        self.climb_pid = Pid(config.climb)
        n = config.median_window
        self._az, self._gr, self._rh = MedianWindow(n), MedianWindow(n), MedianWindow(n)
        self._last: FollowCommand | None = None
        self._last_cue: TargetCue | None = None
        self._target_vel: np.ndarray | None = None
        self._los_range = LineOfSightRange(config.range_smoothing_s) if config.range_smoothing_s > 0 else None
        self._los_cue: tuple[TargetEstimate, TargetCue] | None = None  # (estimate, its smoothed cue)

    def reset(self) -> None:
        """Forget filters, integrals and the last command (after hover or a new engagement)."""
        for pid in (self.yaw_pid, self.pitch_pid, self.roll_pid, self.climb_pid):
            pid.reset()
        for w in (self._az, self._gr, self._rh):
            w.reset()
        self._last = None
        self._last_cue = None
        self._target_vel = None
        if self._los_range is not None:
            self._los_range.reset()
        self._los_cue = None

    def is_stale(self, t: float, cue: TargetCue | None) -> bool:
        """No cue, or the newest one is older than ``stale_after_s``."""
        return cue is None or t - cue.t > self.config.stale_after_s

    def update(self, t: float, own_pos_enu: np.ndarray, own_vel_enu: np.ndarray, own_yaw_enu: float,
               cue: TargetCue | None) -> FollowCommand:
        """The command for mission time ``t``; a new one every ``1 / rate_hz`` s, hover at once when stale."""
        if self.is_stale(t, cue):
            self.reset()
            why = "no target data" if cue is None else f"target data {t - cue.t:.1f} s old"
            self._last = FollowCommand(t, hover=True, reason=why)
            return self._last
        if not (np.all(np.isfinite(own_pos_enu)) and math.isfinite(own_yaw_enu)):
            self.reset()
            self._last = FollowCommand(t, hover=True, reason="own position or heading unknown")
            return self._last
        cue = self._smoothed(cue, np.asarray(own_vel_enu, float))
        last = self._last
        if last is not None and not last.hover and t - last.t < self.config.period_s - 1e-6:
            return last
        dt = self.config.period_s if last is None or last.hover else t - last.t
        self._observe_target(cue)
        self._last = self._step(t, dt, np.asarray(own_pos_enu, float), np.asarray(own_vel_enu, float), own_yaw_enu, cue)
        return self._last

    # -- internals -----------------------------------------------------------------------------
    def _smoothed(self, cue: TargetCue, own_vel: np.ndarray) -> TargetCue:
        """A camera estimate with its range replaced by the line-of-sight low-pass (when enabled)."""
        if self._los_range is None or not isinstance(cue, TargetEstimate) or not math.isfinite(cue.range_m):
            return cue
        if self._los_cue is not None and self._los_cue[0] is cue:
            return self._los_cue[1]
        if self._los_cue is not None and self._los_cue[0].track_id != cue.track_id:
            self._los_range.reset()  # another target: its range starts afresh
        camera = cue.position_enu - cue.range_m * cue.bearing_enu
        r = self._los_range.update(cue.t, cue.range_m, cue.bearing_enu, own_vel)
        smoothed = TargetCue(cue.t, camera + r * cue.bearing_enu, cue.covariance_enu, cue.velocity_enu, cue.source,
                             cue.track_id)
        self._los_cue = (cue, smoothed)
        return smoothed

    def _observe_target(self, cue: TargetCue) -> None:
        """Target velocity: the cue's own, else differenced positions of successive cues."""
        if cue.velocity_enu is not None:
            self._target_vel = np.asarray(cue.velocity_enu, float)
        elif self._last_cue is not None and cue.t - self._last_cue.t > 1e-3:
            v = (cue.position_enu - self._last_cue.position_enu) / (cue.t - self._last_cue.t)
            self._target_vel = v if self._target_vel is None else 0.5 * self._target_vel + 0.5 * v
        if self._last_cue is None or cue.t != self._last_cue.t:
            self._last_cue = cue

    def _step(self, t: float, dt: float, pos: np.ndarray, vel: np.ndarray, yaw: float, cue: TargetCue) -> FollowCommand:
        c = self.config
        raw = process_variables(pos, yaw, cue.position_enu)
        az = self._az.push(raw.azimuth_rad)
        gr = self._gr.push(raw.ground_range_m)
        rh = self._rh.push(raw.rel_height_m)
        pv = ProcessVariables(az, gr, rh)
        fwd = np.array([math.cos(yaw), math.sin(yaw)])
        right = np.array([math.sin(yaw), -math.cos(yaw)])
        vt = self._target_vel if self._target_vel is not None else np.zeros(3)
        rel_v = vt - vel  # target velocity relative to the chaser
        ff = c.feed_forward and self._target_vel is not None

        sm = self.stick_map
        lean = sm.angle_max_rad if c.max_lean_rad is None else min(sm.angle_max_rad, c.max_lean_rad)
        amax = GRAVITY * math.tan(lean)
        yaw_ff = 0.0
        if ff and gr > 1.0:
            d = cue.position_enu[:2] - pos[:2]
            yaw_ff = float(d[0] * rel_v[1] - d[1] * rel_v[0]) / (gr * gr)  # line-of-sight rate, rad/s
        # The yaw loop's output is the yaw stick's deflection (-1..1): a share of PILOT_Y_RATE.
        yaw_rate = sm.yaw_rate_max * self.yaw_pid.update(az, dt, kd=c.yaw_kd_per_m * gr,
                                                         feed_forward=yaw_ff / sm.yaw_rate_max)

        fwd_ff = c.ff_velocity_gain * float(rel_v[:2] @ fwd) if ff else 0.0
        gr_rate = None
        if c.measured_rates and self._target_vel is not None and raw.ground_range_m > 1.0:
            d = cue.position_enu[:2] - pos[:2]
            gr_rate = float(d @ rel_v[:2]) / raw.ground_range_m * math.cos(az)
        forward = self.pitch_pid.update((gr - c.ground_range_sp) * math.cos(az), dt, feed_forward=fwd_ff,
                                        error_rate=gr_rate)
        right_acc = 0.0
        if c.use_roll:
            right_ff = c.ff_velocity_gain * float(rel_v[:2] @ right) if ff else 0.0
            right_acc = self.roll_pid.update(float(rel_v[:2] @ right), dt, feed_forward=right_ff)
        total = math.hypot(forward, right_acc)
        if total > amax:  # ANGLE_MAX limits the lean as a circle
            forward, right_acc = forward * amax / total, right_acc * amax / total

        climb_ff = float(vt[2]) if ff else 0.0
        climb_rate = float(rel_v[2]) if c.measured_rates and self._target_vel is not None else None
        climb = self.climb_pid.update(c.height_sp - rh, dt, feed_forward=climb_ff, error_rate=climb_rate)
        climb = min(max(climb, -sm.climb_down_max), sm.climb_up_max)

        sticks = sm.sticks(forward_accel=forward, right_accel=right_acc, climb_mps=climb, yaw_rate_enu=yaw_rate)
        return FollowCommand(t, False, "", yaw_rate, forward, right_acc, climb, sticks,
                             self._guided_velocity(pos, cue, vt if ff else np.zeros(3), az, gr, yaw, climb), pv,
                             wrap_pi(yaw + az))

    def _guided_velocity(self, pos: np.ndarray, cue: TargetCue, vt: np.ndarray, az: float, gr: float, yaw: float,
                         climb: float) -> np.ndarray:
        """GUIDED alternative: fly to the set-point on the line of sight (+ the target's velocity)."""
        c = self.config
        d = cue.position_enu[:2] - pos[:2]
        los = d / gr if gr > 1e-6 else np.array([math.cos(yaw), math.sin(yaw)])
        correction = c.guided_position_gain * (gr - c.ground_range_sp) * los
        size = float(np.linalg.norm(correction))
        if c.max_closing_mps > 0.0 and size > c.max_closing_mps:
            correction *= c.max_closing_mps / size
        v = vt[:2] + correction
        slant = float(np.linalg.norm(cue.position_enu - pos))
        if c.min_range_m > 0.0 and slant < c.min_range_m:  # too close: back off along the line of sight, and up
            v = v - c.backoff_gain * (c.min_range_m - slant) * los
            climb = max(climb, c.backoff_gain * (c.min_range_m - slant) * math.sin(c.elevation_rad))
        speed = float(np.linalg.norm(v))
        if speed > c.guided_speed_max:
            v *= c.guided_speed_max / speed
        return np.array([v[0], v[1], climb])

