"""ArduCopter flight modes of the simulated autopilot, and the controllers they share.

Each mode turns pilot sticks, GCS targets or its own plan into goals for one
:class:`PositionController`, ArduPilot's AC_PosControl in miniature: a kinematic target
(position and velocity, shaped by ArduPilot's ``sqrt_controller`` and slew-limited by the
mode's speed and acceleration limits) tracked by a cascade position P -> velocity PI ->
acceleration -> lean angles and thrust. Gains follow ArduCopter's defaults where the structure
matches (PSC_POSXY_P 1, PSC_VELXY_P 2 / I 1, PSC_POSZ_P 1); the vertical velocity PI (4 / 2)
stands in for PSC_VELZ_P, followed by an acceleration PI standing in for PSC_ACCZ. A position step settles in a few
seconds without overshoot on the default airframe.

Modes and behaviour follow ArduCopter 4.5/4.6 (ardupilot.org/copter/docs/flight-modes.html):
STABILIZE 0, ALT_HOLD 2, GUIDED 4, LOITER 5, RTL 6, LAND 9, BRAKE 17. Angles are MAVLink's
(NED/FRD, yaw = heading); positions and velocities are ENU.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass
from typing import Protocol

from sitl.vehicle.airframe import GRAVITY, AirframeParams
from sitl.vehicle.physics import MulticopterPhysics

__all__ = [
    "sqrt_controller", "shape_vel_accel_xy", "rtl_return_alt", "stopping_point", "norm_input_dz", "pilot_climb_rate", "PositionController",
    "FlightMode", "Stabilize", "AltHold", "Guided", "Loiter", "Rtl", "Land", "Brake",
    "GuidedSubmode", "RtlState", "StraightSCurve", "make_modes", "ModeHost",
]

# tracking gains (ArduCopter defaults, see module docstring)
POS_XY_P = 1.0
VEL_XY_P = 2.0
VEL_XY_I = 1.0
VEL_XY_D = 0.25  # PSC_VELXY_D
VEL_XY_IMAX = 10.0  # m/s^2, PSC_VELXY_IMAX 1000: the integrator holds a lean-limited vehicle at its limit
VEL_XY_FILT_HZ = 5.0  # PSC_VELXY_FLTE and _FLTD: the velocity error and its derivative low-passed
POS_Z_P = 1.0
VEL_Z_P = 5.0  # PSC_VELZ_P and _I as ArduCopter's SITL reports them (PARAM_VALUE, V4.7.0-dev)
VEL_Z_I = 0.0
VEL_Z_IMAX = 4.0  # m/s^2
# PSC_ACCZ_P 0.5 and _I 1.0 act in throttle per cm/s^2 / 1000: at a hover throttle of 0.39 (ArduPilot's SITL
# quad) that is 1.26 and 2.5 /s of extra acceleration per m/s^2 of acceleration error
ACC_Z_P = 1.26
ACC_Z_I = 2.5
YAW_P = 3.0
AUTO_YAW_RATE_MAX = math.radians(90.0)
BRAKE_ACCEL = 7.5  # ArduCopter BRAKE_MODE_DECEL_RATE, m/s^2
LAND_DETECT_S = 1.0  # ArduCopter LAND_DETECTOR_TRIGGER_SEC
LAND_ACCEL_LPF_HZ = 1.0  # ArduCopter LAND_DETECTOR_ACCEL_LPF_CUTOFF
LAND_ACCEL_MAX = 1.0  # m/s^2, ArduCopter LAND_DETECTOR_ACCEL_MAX
LAND_VEL_Z_MAX = 1.0  # m/s, ArduCopter LAND_DETECTOR_VEL_Z_MAX
FACE_TARGET_MIN_DIST = 2.0  # closer targets keep the heading (WP_YAW_BEHAVIOR 2)
REACHED_TOL = 0.1  # m: the shaped target counts as arrived this close to its goal
ARMING_DELAY_S = 2.0  # s, ArduCopter's ARMING_DELAY_SEC: no rotor turns this long after arming
ATC_INPUT_TC = 0.15  # s, ArduCopter's attitude input time constant (the airframe's attitude lag here)


def sqrt_controller(error: float, p: float, accel_max: float, dt: float = 0.0) -> float:
    """ArduPilot's sqrt_controller: linear ``p * error`` near zero, ``sqrt(2 a e)`` beyond.

    The velocity it returns lets the target stop on ``error = 0`` decelerating at ``accel_max``.
    Given ``dt``, the correction is capped at ``|error| / dt`` so the last step cannot overshoot.
    """
    if accel_max <= 0.0:
        out = p * error
    else:
        linear = accel_max / (p * p)
        if error > linear:
            out = math.sqrt(2.0 * accel_max * (error - 0.5 * linear))
        elif error < -linear:
            out = -math.sqrt(2.0 * accel_max * (-error - 0.5 * linear))
        else:
            out = p * error
    if dt > 0.0:
        cap = abs(error) / dt
        out = min(max(out, -cap), cap)
    return out


def inv_sqrt_controller(output: float, p: float, accel_max: float) -> float:
    """The error at which :func:`sqrt_controller` returns ``output`` (ArduPilot inv_sqrt_controller)."""
    if accel_max <= 0.0:
        return output / p
    if p <= 0.0:
        return output * output / (2.0 * accel_max)
    linear = accel_max / p  # the output where the linear part ends
    if abs(output) <= linear:
        return output / p
    e = accel_max / (2.0 * p * p) + output * output / (2.0 * accel_max)
    return e if output > 0.0 else -e


def kinematic_limit(dx: float, dy: float, dz: float, max_xy: float, max_up: float, max_dn: float) -> float:
    """The largest speed along the direction (dx, dy, dz) that keeps its horizontal part within
    ``max_xy`` and its vertical part within ``max_up`` / ``max_dn`` (ArduPilot kinematic_limit)."""
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    if n <= 0.0 or max_xy <= 0.0 or max_up <= 0.0 or max_dn <= 0.0:
        return 0.0
    xy, z = math.hypot(dx, dy) / n, dz / n
    if xy <= 0.0:
        return max_up if z > 0.0 else max_dn
    vz_max = max_up if z > 0.0 else max_dn
    return max_xy / xy if abs(z) / xy < vz_max / max_xy else vz_max / abs(z)


def shape_vel_accel(v: float, tv: float, ta: float, accel_max: float, jerk_max: float, dt: float) -> float:
    """The target acceleration one step on, jerk-limited towards velocity ``v`` (ArduPilot shape_vel_accel,
    one axis, limits symmetric): a sqrt controller of gain jerk/accel on the velocity error, limited to
    ``accel_max``, approached by at most ``jerk_max * dt``."""
    at = min(max(sqrt_controller(v - tv, jerk_max / accel_max, jerk_max, dt), -accel_max), accel_max)
    step = jerk_max * dt
    return ta + min(max(at - ta, -step), step)


def shape_vel_accel_xy(vx: float, vy: float, tvx: float, tvy: float, tax: float, tay: float,
                       accel_max: float, jerk_max: float, dt: float) -> tuple[float, float]:
    """The target acceleration one step on, jerk-limited towards velocity (vx, vy) (ArduPilot shape_vel_accel_xy).

    The velocity error is closed by a sqrt controller of gain jerk/accel whose output is limited to
    ``accel_max``; while the demand is mostly along the commanded velocity, the part across it keeps at
    least 1/sqrt(2) of the limit (ArduPilot's CORNER_ACCELERATION_RATIO), so a turn is not starved by
    the speed change. The acceleration then moves towards that demand by at most ``jerk_max * dt``.
    """
    evx, evy = vx - tvx, vy - tvy
    e = math.hypot(evx, evy)
    if e > 0.0:
        a = sqrt_controller(e, jerk_max / accel_max, jerk_max, dt) / e
        atx, aty = evx * a, evy * a
    else:
        atx = aty = 0.0
    speed = math.hypot(vx, vy)
    along = (atx * vx + aty * vy) / speed if speed > 0.0 else 0.0
    cx, cy = (atx - along * vx / speed, aty - along * vy / speed) if speed > 0.0 else (atx, aty)
    if speed > 0.0 and along * along > cx * cx + cy * cy:
        c = math.hypot(cx, cy)
        corner = accel_max / math.sqrt(2.0)
        if c > corner:
            cx, cy, c = cx * corner / c, cy * corner / c, corner
        room = math.sqrt(max(accel_max * accel_max - c * c, 0.0))
        along = min(max(along, -room), room)
        atx, aty = cx + along * vx / speed, cy + along * vy / speed
    else:
        a = math.hypot(atx, aty)
        if a > accel_max:
            atx, aty = atx * accel_max / a, aty * accel_max / a
    dax, day = atx - tax, aty - tay
    da = math.hypot(dax, day)
    step = jerk_max * dt
    if da > step:
        dax, day = dax * step / da, day * step / da
    return tax + dax, tay + day


def norm_input_dz(pwm: float, dz: float) -> float:
    """A stick's PWM as -1..1 outside its deadzone (ArduPilot RC_Channel::norm_input_dz).

    Range 1000..2000, trim 1500: 1300 with a 20 us deadzone is (1300 - 1480) / 480 = -0.375.
    """
    lo = 1500.0 - dz
    hi = 1500.0 + dz
    if pwm < lo:
        return max(-1.0, (pwm - lo) / (lo - 1000.0))
    if pwm > hi:
        return min(1.0, (pwm - hi) / (2000.0 - hi))
    return 0.0


def pilot_climb_rate(pwm: float, thr_dz: float, up: float, dn: float) -> float:
    """Climb rate (m/s) from the throttle stick (ArduCopter get_pilot_desired_climb_rate).

    Mid-stick +- THR_DZ (in 0..1000 stick units) holds altitude; above it climbs up to ``up``,
    below it descends up to ``dn``.
    """
    thr = min(max(pwm - 1000.0, 0.0), 1000.0)
    top = 500.0 + thr_dz
    bottom = 500.0 - thr_dz
    if thr < bottom:
        return dn * (thr - bottom) / bottom
    if thr > top:
        return up * (thr - top) / (1000.0 - top)
    return 0.0


class PositionController:
    """Shaped position/velocity targets tracked by a P -> PI cascade (AC_PosControl-like).

    Horizontal and vertical axes are shaped independently. Goals: a position (``set_pos_xy``,
    ``set_alt``) approached at up to the given speed and acceleration and then held, or a
    velocity (``set_vel_xy``, ``set_climb``) reached at the given acceleration, whose target
    position keeps integrating so a zero velocity holds where it stopped. Yaw: a heading
    target, slewed by a rate feed-forward.

    The horizontal target is ArduPilot's jerk-limited kinematic path (AC_PosControl's
    input_pos_vel_accel_xy / shape_pos_vel_accel_xy): its acceleration changes by at most
    ``jerk_xy`` (PSC_JERK_XY) per second, and a position goal is approached by a sqrt controller
    of gain jerk/(2 accel) braking at half the acceleration limit, which is what keeps a GUIDED
    leg from overshooting its corner. The vertical target is shaped the same way in one dimension
    (``jerk_z``, PSC_JERK_Z; a height goal braked at half ``accel_z``).
    """

    def __init__(self, mass_kg: float, max_thrust_n: float) -> None:
        self.mass = mass_kg
        self.max_thrust = max_thrust_n
        self.tpx = self.tpy = self.tvx = self.tvy = 0.0
        self.tax = self.tay = 0.0
        self.jerk_xy = 5.0  # m/s^3, PSC_JERK_XY
        self.jerk_z = 5.0  # m/s^3, PSC_JERK_Z
        self._limit = (0.0, 0.0)  # the lean-limited acceleration, when the limit holds
        self._vel_err = (0.0, 0.0)
        self.gx = self.gy = 0.0
        self.xy_pos_goal = False
        self.line = False  # a 3D goal approached on a straight line (set_pos_xyz)
        self._line_xy = self._line_z = 0.0  # this step's speed limits along that line
        self.xy_external = self.z_external = False  # targets set by a trajectory this step, not shaped
        self.speed_xy = 1.0
        self.accel_xy = 1.0
        # the position error's correction (AC_PosControl set_correction_speed_accel_xy): a sqrt controller
        # of gain POS_XY_P braking at corr_accel_xy, the error held within what gives corr_speed_xy
        self.corr_speed_xy = 10.0
        self.corr_accel_xy = 2.5
        self.ix = self.iy = 0.0
        self._evf = self._dvf = (0.0, 0.0)  # the filtered velocity error and its filtered derivative
        self.tpz = self.tvz = 0.0
        self.taz = 0.0
        self.ia = 0.0
        self._last_vz = 0.0
        self.gz = 0.0
        self.z_pos_goal = False
        self.speed_up = self.speed_dn = 1.0
        self.accel_z = 1.0
        self.iz = 0.0
        self.yaw_target = 0.0
        self.yaw_rate_ff = 0.0

    # --- goals ---
    def reset(self, px: float, py: float, pz: float, vx: float, vy: float, vz: float,
              yaw: float) -> None:
        """Targets at the present state, integrators cleared, holding velocity then stopping."""
        self.tpx, self.tpy, self.tpz = px, py, pz
        self.tvx, self.tvy, self.tvz = vx, vy, vz
        self.tax = self.tay = self.taz = 0.0
        self._limit = (0.0, 0.0)
        self.ix = self.iy = self.iz = self.ia = 0.0
        self._evf = self._dvf = (0.0, 0.0)
        self._last_vz = vz
        self.xy_pos_goal = self.z_pos_goal = self.line = False
        self.xy_external = self.z_external = False
        self.gx = self.gy = self.gz = 0.0
        self.yaw_target = yaw
        self.yaw_rate_ff = 0.0

    def set_pos_xyz(self, x: float, y: float, z: float, speed: float, speed_up: float, speed_dn: float,
                    accel: float, accel_z: float) -> None:
        """Fly to (x, y, z) on a straight line and hold it (AC_PosControl input_pos_xyz, ArduCopter's
        GUIDED position target): each step the horizontal and vertical speed limits are those of the
        fastest speed along the line to the goal that keeps within ``speed`` across and ``speed_up`` /
        ``speed_dn`` vertically, so both axes arrive together."""
        self.set_pos_xy(x, y, speed, accel)
        self.set_alt(z, speed_up, speed_dn, accel_z)
        self.line = True

    def set_pos_xy(self, x: float, y: float, speed: float, accel: float) -> None:
        """Fly to (x, y) at up to ``speed`` m/s, ``accel`` m/s^2, and hold it."""
        self.line = False
        self.xy_external = False
        self.xy_pos_goal = True
        self.gx, self.gy = x, y
        self.speed_xy, self.accel_xy = speed, accel

    def set_correction_xy(self, speed: float, accel: float) -> None:
        """The position error's correction limits (AC_PosControl set_correction_speed_accel_xy; a mode
        sets them on entry, WPNAV_SPEED and WPNAV_ACCEL for most)."""
        self.corr_speed_xy, self.corr_accel_xy = speed, accel

    def set_vel_xy(self, vx: float, vy: float, accel: float) -> None:
        """Fly at (vx, vy), reached at ``accel`` m/s^2."""
        self.line = False
        self.xy_external = False
        self.xy_pos_goal = False
        self.gx, self.gy = vx, vy
        self.accel_xy = accel

    def set_alt(self, z: float, speed_up: float, speed_dn: float, accel: float) -> None:
        """Climb or descend to ENU height ``z`` and hold it."""
        self.line = False
        self.z_external = False
        self.z_pos_goal = True
        self.gz = z
        self.speed_up, self.speed_dn, self.accel_z = speed_up, speed_dn, accel

    def take_over_z(self, accel_est: float, thrust: float, roll: float, pitch: float) -> None:
        """Take the vertical axis over from a throttle set outside the controller (AC_PosControl
        D_init_controller): the target's acceleration is the measured one, within the vertical limit,
        and the acceleration loop's integrator holds the present thrust, so the hand-over from the
        take-off's throttle ramp neither drops the thrust to hover nor jumps it."""
        self.taz = min(max(accel_est, -self.accel_z), self.accel_z)
        tilt = max(math.cos(roll) * math.cos(pitch), 0.5)
        ia = thrust * tilt / self.mass - GRAVITY - ACC_Z_P * (self.taz - accel_est)
        self.ia = min(max(ia, -GRAVITY), GRAVITY)

    def set_climb(self, vz: float, accel: float) -> None:
        """Climb at ``vz`` m/s (negative descends), reached at ``accel`` m/s^2."""
        self.line = False
        self.z_external = False
        self.z_pos_goal = False
        self.gz = vz
        self.accel_z = accel

    def follow(self, pos: tuple[float, float, float], vel: tuple[float, float, float],
               accel: tuple[float, float, float]) -> None:
        """Take this step's target straight from a trajectory (AC_PosControl set_pos_vel_accel), unshaped;
        the target's position becomes the goal held once the trajectory stops calling."""
        self.tpx, self.tpy, self.tpz = pos
        self.tvx, self.tvy, self.tvz = vel
        self.tax, self.tay, self.taz = accel
        self.gx, self.gy, self.gz = pos
        self.xy_pos_goal = self.z_pos_goal = True
        self.line = False
        self.xy_external = self.z_external = True

    def xy_reached(self) -> bool:
        """The horizontal target has arrived at its position goal."""
        return self.xy_pos_goal and math.hypot(self.gx - self.tpx, self.gy - self.tpy) < REACHED_TOL

    def z_reached(self) -> bool:
        """The vertical target has arrived at its altitude goal."""
        return self.z_pos_goal and abs(self.gz - self.tpz) < REACHED_TOL

    # --- updates ---
    def _shape_xy(self, dt: float, px: float, py: float, vx: float, vy: float) -> tuple[float, float]:
        if self.xy_external:
            self.xy_external = False
            return self.tax, self.tay
        # move the target along with its acceleration, then reshape that acceleration (AC_PosControl order);
        # while the lean limit holds the vehicle back, the target does not run further ahead of it
        # (update_pos_vel_accel_xy with the limit vector)
        ax, ay = self.tax, self.tay
        dpx, dpy = (self.tvx + 0.5 * ax * dt) * dt, (self.tvy + 0.5 * ay * dt) * dt
        dvx, dvy = ax * dt, ay * dt
        lx, ly = self._limit
        if lx or ly:
            dpx, dpy = self._held_at_vehicle(dpx, dpy, px + vx * dt, py + vy * dt)
            vex, vey = self._vel_err
            if dvx * lx + dvy * ly > 0.0 and vex * lx + vey * ly > 0.0 and self.tvx * lx + self.tvy * ly >= 0.0:
                dvx = dvy = 0.0
        self.tpx += dpx
        self.tpy += dpy
        self.tvx += dvx
        self.tvy += dvy
        accel, jerk = self.accel_xy, self.jerk_xy
        if self.line:
            dx, dy, dz = self.gx - self.tpx, self.gy - self.tpy, self.gz - self.tpz
            n = math.sqrt(dx * dx + dy * dy + dz * dz)
            v = kinematic_limit(dx, dy, dz, self.speed_xy, self.speed_up, self.speed_dn)
            self._line_xy, self._line_z = (v * math.hypot(dx, dy) / n, abs(v * dz / n)) if n > 0.0 else (0.0, 0.0)
        if self.xy_pos_goal:
            ex, ey = self.gx - self.tpx, self.gy - self.tpy
            d = math.sqrt(ex * ex + ey * ey)
            if d < 1e-3 and self.tvx * self.tvx + self.tvy * self.tvy < 1e-4 and ax * ax + ay * ay < 1e-4:
                self.tpx, self.tpy, self.tvx, self.tvy, self.tax, self.tay = self.gx, self.gy, 0.0, 0.0, 0.0, 0.0
                return 0.0, 0.0
            # braking at half the acceleration limit leaves the other half for the turn onto the next leg
            v = min(sqrt_controller(d, 0.5 * jerk / accel, 0.5 * accel, dt), self._line_xy if self.line else self.speed_xy)
            s = v / d if d > 1e-9 else 0.0
            vgx, vgy = ex * s, ey * s
        else:
            vgx, vgy = self.gx, self.gy
        self.tax, self.tay = shape_vel_accel_xy(vgx, vgy, self.tvx, self.tvy, ax, ay, accel, jerk, dt)
        return self.tax, self.tay

    def _held_at_vehicle(self, dpx: float, dpy: float, nx: float, ny: float) -> tuple[float, float]:
        """The target's step along the lean limit cut so that it ends no further ahead than the vehicle will
        be at the next update (``nx``, ``ny``).

        ArduPilot stops the whole step while the position error points along the limit; at its 400 Hz that
        holds the target on the vehicle within 2.5 cm. At 50 Hz the same rule lets the target run a step
        ahead and then stands it still while the vehicle flies 0.2 m past, and each of those jumps in the
        error knocks the demand off the limit for a tenth of a second: into a strong wind the lean
        averaged 29.3 deg against ArduCopter's steady 30, and the leg took 0.15 s longer. Cut to where the
        vehicle will be, the step does at 50 Hz what ArduPilot's does at 400 Hz."""
        lx, ly = self._limit
        n = math.hypot(lx, ly)
        ux, uy = lx / n, ly / n
        along = dpx * ux + dpy * uy
        if along <= 0.0:
            return dpx, dpy
        ahead = (self.tpx - nx) * ux + (self.tpy - ny) * uy + along
        cut = min(max(ahead, 0.0), along)
        return dpx - cut * ux, dpy - cut * uy

    def update_xy(self, dt: float, px: float, py: float, vx: float, vy: float, yaw: float,
                  angle_max: float) -> tuple[float, float]:
        """Advance the horizontal target and return the (roll, pitch) that tracks it."""
        ffx, ffy = self._shape_xy(dt, px, py, vx, vy)
        cx, cy = self._position_correction(dt, px, py)
        # the velocity PID (AC_PID_2D): its error and the error's derivative each low-passed at VEL_XY_FILT_HZ
        k = lowpass_alpha(dt, VEL_XY_FILT_HZ)
        (fx, fy), (dx, dy) = self._evf, self._dvf
        evx = fx + k * (self.tvx + cx - vx - fx)
        evy = fy + k * (self.tvy + cy - vy - fy)
        dx += k * ((evx - fx) / dt - dx)
        dy += k * ((evy - fy) / dt - dy)
        self._evf, self._dvf = (evx, evy), (dx, dy)
        self._integrate(VEL_XY_I * evx * dt, VEL_XY_I * evy * dt)
        ax = ffx + VEL_XY_P * evx + VEL_XY_D * dx + self.ix
        ay = ffy + VEL_XY_P * evy + VEL_XY_D * dy + self.iy
        amax = GRAVITY * math.tan(angle_max)
        a = math.sqrt(ax * ax + ay * ay)
        self._vel_err = (evx, evy)
        if a > amax:
            ax, ay = ax * amax / a, ay * amax / a
            self._limit = (ax, ay)
        else:
            self._limit = (0.0, 0.0)
        return accel_to_lean(ax, ay, yaw)

    def _integrate(self, dix: float, diy: float) -> None:
        """The velocity integrator's step (AC_PID_2D::update_i), before the output as ArduPilot orders it: a
        step that pushes along the last step's lean limit may turn the integrator but not lengthen it."""
        n0 = math.hypot(self.ix, self.iy)
        ix, iy = self.ix + dix, self.iy + diy
        lx, ly = self._limit
        n = math.hypot(ix, iy)
        cap = min(n0, VEL_XY_IMAX) if dix * lx + diy * ly > 0.0 else VEL_XY_IMAX
        if n > cap:
            ix, iy = ix * cap / n, iy * cap / n
        self.ix, self.iy = ix, iy

    def _position_correction(self, dt: float, px: float, py: float) -> tuple[float, float]:
        """The velocity that corrects the horizontal position error (AC_P_2D update_all): a sqrt controller
        on the error's length, and a target further than its error limit dragged back to it."""
        ex, ey = self.tpx - px, self.tpy - py
        e = math.hypot(ex, ey)
        if e <= 0.0:
            return 0.0, 0.0
        e_max = inv_sqrt_controller(self.corr_speed_xy, POS_XY_P, self.corr_accel_xy)
        if e_max > 0.0 and e > e_max:
            ex, ey = ex * e_max / e, ey * e_max / e
            self.tpx, self.tpy = px + ex, py + ey
            e = e_max
        c = sqrt_controller(e, POS_XY_P, self.corr_accel_xy, dt) / e
        return ex * c, ey * c

    def _shape_z(self, dt: float) -> float:
        if self.z_external:
            self.z_external = False
            return self.taz
        # as the horizontal: move the target with its acceleration, then reshape that acceleration
        # (AC_PosControl input_vel_accel_z / input_pos_vel_accel_z with PSC_JERK_Z)
        a = self.taz
        self.tpz += (self.tvz + 0.5 * a * dt) * dt
        self.tvz += a * dt
        accel, jerk = self.accel_z, self.jerk_z
        if self.z_pos_goal:
            e = self.gz - self.tpz
            if abs(e) < 1e-3 and abs(self.tvz) < 1e-2 and abs(a) < 1e-2:
                self.tpz, self.tvz, self.taz = self.gz, 0.0, 0.0
                return 0.0
            down, up = (self._line_z, self._line_z) if self.line else (self.speed_dn, self.speed_up)
            vg = min(max(sqrt_controller(e, 0.5 * jerk / accel, 0.5 * accel, dt), -down), up)
        else:
            vg = self.gz
        self.taz = shape_vel_accel(vg, self.tvz, a, accel, jerk, dt)
        return self.taz

    def update_z(self, dt: float, pz: float, vz: float, roll: float, pitch: float) -> float:
        """Advance the vertical target and return the thrust (N) that tracks it.

        The velocity PI's acceleration demand goes through an acceleration PI on the measured climb
        acceleration (ArduPilot's PSC_ACCZ loop), so a demand the vehicle cannot follow, such as
        descending while standing on the ground, winds the thrust down within a fraction of a second.
        The demand itself is not fed forward into the thrust (PSC_ACCZ_FF 0): standing on the ground
        after a 0.5 m/s descent, the thrust reaches its floor 0.6 s after contact, as worked by hand from
        ArduCopter's gains; fed forward it took 0.4 s and the disarm came 0.2 s before ArduCopter's.
        """
        ff = self._shape_z(dt)
        ev = self.tvz + POS_Z_P * (self.tpz - pz) - vz
        az = ff + VEL_Z_P * ev + self.iz
        a_meas = (vz - self._last_vz) / dt
        self._last_vz = vz
        ea = az - a_meas
        thrust = self.mass * (GRAVITY + ACC_Z_P * ea + self.ia) / max(math.cos(roll) * math.cos(pitch), 0.5)
        if 0.0 < thrust < self.max_thrust:
            self.iz = min(max(self.iz + VEL_Z_I * ev * dt, -VEL_Z_IMAX), VEL_Z_IMAX)
            self.ia = min(max(self.ia + ACC_Z_I * ea * dt, -GRAVITY), GRAVITY)
        return min(max(thrust, 0.0), self.max_thrust)

    def update_yaw(self, dt: float, yaw: float, rate_max: float) -> float:
        """Advance the heading target by its rate feed-forward; return the yaw-rate command."""
        if self.yaw_rate_ff:
            self.yaw_target = wrap_pi(self.yaw_target + self.yaw_rate_ff * dt)
        r = self.yaw_rate_ff + YAW_P * wrap_pi(self.yaw_target - yaw)
        return min(max(r, -rate_max), rate_max)


def lowpass_alpha(dt: float, cutoff_hz: float) -> float:
    """The step gain of a first-order low-pass at ``cutoff_hz`` (ArduPilot's LowPassFilter)."""
    return dt / (dt + 1.0 / (2.0 * math.pi * cutoff_hz))


def wrap_pi(a: float) -> float:
    """Angle wrapped to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def accel_to_lean(ax: float, ay: float, yaw: float) -> tuple[float, float]:
    """ENU horizontal acceleration -> (roll, pitch) at heading ``yaw`` (ArduPilot accel_to_lean_angles)."""
    cy, sy = math.cos(yaw), math.sin(yaw)
    forward = ay * cy + ax * sy  # north, east components onto the nose
    right = -ay * sy + ax * cy
    pitch = math.atan(-forward / GRAVITY)
    roll = math.atan(right * math.cos(pitch) / GRAVITY)
    return roll, pitch


def heading_to(dx: float, dy: float) -> float:
    """Compass heading (NED yaw) of the ENU direction (dx, dy)."""
    return math.atan2(dx, dy)


class ModeHost(Protocol):
    """What a flight mode reads and drives on its autopilot (:class:`sitl.vehicle.autopilot.Autopilot`).

    Written out here so the modes depend on this interface, not on the autopilot module that owns them.
    """

    airframe: AirframeParams
    phys: MulticopterPhysics
    pc: PositionController
    p: dict[str, float]
    time_s: float
    ex: float
    ey: float
    ez: float
    evz: float
    home_enu: tuple[float, float, float] | None
    ekf_ok: bool
    land_complete: bool
    armed: bool
    armed_at: float

    @property
    def angle_max(self) -> float: ...

    def alt_rel(self) -> float: ...

    def rc(self, ch: int) -> int: ...

    def idle(self) -> None: ...

    def reset_controller(self) -> None: ...

    def output(self, roll: float, pitch: float, yaw_rate: float, thrust: float) -> None: ...

    def output_tracking(self, dt: float, roll: float | None = None, pitch: float | None = None) -> None: ...


class FlightMode(abc.ABC):
    """One ArduCopter flight mode: entry checks, and a run() called every control step."""

    number = -1
    name = ""
    requires_position = False
    allows_arming = False
    manual_throttle = False
    is_autopilot = False  # Mode::is_autopilot(): the autopilot flies, not the pilot's sticks

    def enter(self, ap: ModeHost) -> str | None:
        """Initialise on entry; return a failure reason to refuse the change."""
        ap.reset_controller()
        ap.pc.set_correction_xy(ap.p["WPNAV_SPEED"] * 0.01, ap.p["WPNAV_ACCEL"] * 0.01)
        return None

    @abc.abstractmethod
    def run(self, ap: ModeHost, dt: float) -> None:
        """Compute this step's commands into ``ap.phys``."""

    def landing(self) -> bool:
        """The mode is descending to land (MAV_LANDED_STATE_LANDING)."""
        return False

    def taking_off(self) -> bool:
        """The mode is climbing out (MAV_LANDED_STATE_TAKEOFF)."""
        return False


def _stick_lean(ap: ModeHost, angle_max: float) -> tuple[float, float]:
    """Roll and pitch from sticks 1 and 2, limited to ``angle_max`` as a circle (ArduCopter)."""
    p = ap.p
    roll = norm_input_dz(ap.rc(1), p["RC1_DZ"]) * angle_max
    pitch = norm_input_dz(ap.rc(2), p["RC2_DZ"]) * angle_max
    total = math.sqrt(roll * roll + pitch * pitch)
    if total > angle_max:
        roll, pitch = roll * angle_max / total, pitch * angle_max / total
    return roll, pitch


def _stick_yaw_rate(ap: ModeHost) -> float:
    return norm_input_dz(ap.rc(4), ap.p["RC4_DZ"]) * math.radians(ap.p["PILOT_Y_RATE"])


def _stick_climb(ap: ModeHost) -> float:
    p = ap.p
    up = p["PILOT_SPEED_UP"] * 0.01
    dn = (p["PILOT_SPEED_DN"] or p["PILOT_SPEED_UP"]) * 0.01
    return pilot_climb_rate(ap.rc(3), p["THR_DZ"], up, dn)


class Stabilize(FlightMode):
    """Sticks -> lean angles and yaw rate; throttle stick -> thrust, mid-stick = hover."""

    number, name, allows_arming, manual_throttle = 0, "STABILIZE", True, True

    def run(self, ap: ModeHost, dt: float) -> None:
        p = ap.p
        dz = p["RC3_DZ"]
        stick = min(max((ap.rc(3) - 1000.0 - dz) / (1000.0 - dz), 0.0), 1.0)
        if stick <= 0.0 and ap.land_complete:
            ap.idle()
            return
        hover = ap.airframe.hover_throttle
        throttle = stick / 0.5 * hover if stick < 0.5 else hover + (stick - 0.5) / 0.5 * (1.0 - hover)
        roll, pitch = _stick_lean(ap, ap.angle_max)
        ph = ap.phys
        boost = max(math.cos(ph.roll) * math.cos(ph.pitch), 0.5)
        ap.output(roll, pitch, _stick_yaw_rate(ap), throttle * ap.airframe.max_thrust_n / boost)


class AltHold(FlightMode):
    """Sticks -> lean angles and yaw rate; throttle stick -> climb rate, mid-stick holds altitude."""

    number, name, allows_arming = 2, "ALT_HOLD", True

    def run(self, ap: ModeHost, dt: float) -> None:
        climb = _stick_climb(ap)
        if ap.land_complete and climb <= 0.0:
            ap.idle()
            return
        pc = ap.pc
        pc.set_climb(climb, ap.p["PILOT_ACCEL_Z"] * 0.01)
        roll, pitch = _stick_lean(ap, ap.angle_max)
        pc.yaw_rate_ff = _stick_yaw_rate(ap)
        ap.output_tracking(dt, roll=roll, pitch=pitch)


class Loiter(FlightMode):
    """Holds position; sticks fly it (velocity up to LOIT_SPEED), throttle as in ALT_HOLD."""

    number, name, requires_position, allows_arming = 5, "LOITER", True, True

    def enter(self, ap: ModeHost) -> str | None:
        super().enter(ap)
        # AC_Loiter::init_target: corrections up to LOITER_VEL_CORRECTION_MAX (2 m/s) at LOIT_ACC_MAX
        ap.pc.set_correction_xy(2.0, ap.p["LOIT_ACC_MAX"] * 0.01)
        return None

    def run(self, ap: ModeHost, dt: float) -> None:
        p = ap.p
        climb = _stick_climb(ap)
        if ap.land_complete and climb <= 0.0:
            ap.idle()
            return
        right = norm_input_dz(ap.rc(1), p["RC1_DZ"])
        forward = -norm_input_dz(ap.rc(2), p["RC2_DZ"])
        speed = p["LOIT_SPEED"] * 0.01
        yaw = ap.phys.yaw
        cy, sy = math.cos(yaw), math.sin(yaw)
        # body forward/right -> ENU east/north
        ve = (forward * sy + right * cy) * speed
        vn = (forward * cy - right * sy) * speed
        sticks = forward != 0.0 or right != 0.0
        accel = p["LOIT_ACC_MAX"] * 0.01 if sticks else p["LOIT_BRK_ACCEL"] * 0.01
        pc = ap.pc
        pc.set_vel_xy(ve, vn, accel)
        pc.set_climb(climb, p["PILOT_ACCEL_Z"] * 0.01)
        pc.yaw_rate_ff = _stick_yaw_rate(ap)
        ap.output_tracking(dt)


class Brake(FlightMode):
    """Stops as hard as the lean limit allows and holds position (ArduCopter BRAKE)."""

    number, name, requires_position = 17, "BRAKE", True

    def enter(self, ap: ModeHost) -> str | None:
        super().enter(ap)
        accel = min(BRAKE_ACCEL, 0.8 * GRAVITY * math.tan(ap.angle_max))
        ap.pc.set_vel_xy(0.0, 0.0, accel)
        ap.pc.set_climb(0.0, ap.p["WPNAV_ACCEL_Z"] * 0.01)
        return None

    def run(self, ap: ModeHost, dt: float) -> None:
        if ap.land_complete:
            ap.idle()
            return
        ap.output_tracking(dt)


class GuidedSubmode:
    """What GUIDED is doing: waiting on the ground, taking off, or following one kind of target."""

    IDLE = "idle"
    TAKEOFF = "takeoff"
    POS = "pos"
    VEL = "vel"
    ATT = "att"


class Guided(FlightMode):
    """GCS-driven flight: takeoff, position, velocity and attitude targets (ArduCopter GUIDED).

    A position target holds until replaced; velocity and attitude targets time out after
    GUID_TIMEOUT (then stop and hold / level and hold altitude), as ArduCopter does.
    """

    number, name, requires_position, allows_arming = 4, "GUIDED", True, True
    is_autopilot = True

    def __init__(self) -> None:
        self.sub = GuidedSubmode.IDLE
        self.last_cmd_t = 0.0
        self.att = (0.0, 0.0, 0.0)  # roll, pitch, yaw target
        self.att_yaw_rate: float | None = None
        self.att_thrust = 0.5
        self.speed_override: float | None = None
        self.takeoff_z = 0.0
        self.takeoff_started = 0.0
        self.takeoff_throttle = 0.0
        self.lifted_off = False
        self._last_evz = 0.0

    def enter(self, ap: ModeHost) -> str | None:
        super().enter(ap)
        self.speed_override = None
        self.att_yaw_rate = None
        if ap.land_complete:
            self.sub = GuidedSubmode.IDLE
        else:
            self.sub = GuidedSubmode.VEL
            self._stop(ap)
        return None

    def _stop(self, ap: ModeHost) -> None:
        """Brake to a hold at WPNAV_ACCEL (the velocity-timeout and entry behaviour)."""
        pc = ap.pc
        pc.set_vel_xy(0.0, 0.0, ap.p["WPNAV_ACCEL"] * 0.01)
        pc.set_climb(0.0, ap.p["WPNAV_ACCEL_Z"] * 0.01)
        pc.yaw_rate_ff = 0.0

    def speed_xy(self, ap: ModeHost) -> float:
        return self.speed_override if self.speed_override is not None else ap.p["WPNAV_SPEED"] * 0.01

    def takeoff(self, ap: ModeHost, z: float) -> None:
        """Start ArduCopter's auto take-off to ENU height ``z``: spool up, ramp the throttle, then climb."""
        ap.reset_controller()
        self.sub = GuidedSubmode.TAKEOFF
        self.takeoff_z = z
        self.takeoff_started = ap.time_s
        self.takeoff_throttle = 0.0
        self.lifted_off = False
        self._last_evz = ap.evz

    def _run_takeoff(self, ap: ModeHost, dt: float) -> None:
        """ArduCopter's _AutoTakeoff::run: on the ground, the rotors first spool up (MOT_SPOOL_TIME, from the
        end of the 2 s arming delay at the earliest) with
        the controllers relaxed; then the throttle ramps from zero over TKOFF_SLEW_TIME until lift-off is
        detected (throttle at TKOFF_THR_MAX, at most 0.9; climbing at 10 % of WPNAV_SPEED_UP; or
        accelerating upwards at half WPNAV_ACCEL_Z); only then does the position controller fly the climb."""
        p = ap.p
        climb_accel = (ap.evz - self._last_evz) / dt
        self._last_evz = ap.evz
        if not self.lifted_off:
            ap.reset_controller()
            # the spool-up starts once the arming delay has let the rotors turn
            spool_from = max(self.takeoff_started, ap.armed_at + ARMING_DELAY_S)
            if ap.time_s - spool_from < p["MOT_SPOOL_TIME"]:
                ap.output(0.0, 0.0, 0.0, 0.0)
                return
            slew = max(p["TKOFF_SLEW_TIME"], 0.25)
            self.takeoff_throttle = min(self.takeoff_throttle + dt / slew, 1.0)
            ph = ap.phys
            boost = max(math.cos(ph.roll) * math.cos(ph.pitch), 0.5)
            thrust = self.takeoff_throttle * ap.airframe.max_thrust_n / boost
            ap.output(0.0, 0.0, 0.0, thrust)
            if (self.takeoff_throttle >= min(p["TKOFF_THR_MAX"], 0.9)
                    or ap.evz >= 0.1 * p["WPNAV_SPEED_UP"] * 0.01
                    or climb_accel >= 0.5 * p["WPNAV_ACCEL_Z"] * 0.01):
                self.lifted_off = True
                ap.pc.set_pos_xy(ap.ex, ap.ey, self.speed_xy(ap), p["WPNAV_ACCEL"] * 0.01)
                ap.pc.set_alt(self.takeoff_z, p["WPNAV_SPEED_UP"] * 0.01, p["WPNAV_SPEED_DN"] * 0.01,
                              p["WPNAV_ACCEL_Z"] * 0.01)
                ap.pc.take_over_z(climb_accel, thrust, ph.roll, ph.pitch)
            return
        if ap.pc.z_reached():
            self._enter_position_control()
        ap.output_tracking(dt)

    def _enter_position_control(self) -> None:
        """ArduCopter's ``pos_control_start`` (through ``pva_control_start``, mode_guided.cpp): a change into
        position control from another submode (take-off done, velocity, attitude) sets the horizontal
        speed back to WPNAV_SPEED, so a DO_CHANGE_SPEED sent before that change is lost; one sent after
        it holds for every later position target."""
        if self.sub != GuidedSubmode.POS:
            self.speed_override = None
        self.sub = GuidedSubmode.POS

    def set_position(self, ap: ModeHost, x: float, y: float, z: float, yaw: float | None) -> None:
        if self.sub == GuidedSubmode.IDLE:
            return  # on the ground GUIDED needs a takeoff command first, as ArduCopter
        if self.sub == GuidedSubmode.ATT:
            ap.reset_controller()
        self._enter_position_control()
        p = ap.p
        pc = ap.pc
        pc.set_pos_xyz(x, y, z, self.speed_xy(ap), p["WPNAV_SPEED_UP"] * 0.01, p["WPNAV_SPEED_DN"] * 0.01,
                       p["WPNAV_ACCEL"] * 0.01, p["WPNAV_ACCEL_Z"] * 0.01)
        pc.yaw_rate_ff = 0.0
        if yaw is not None:
            pc.yaw_target = yaw
        elif math.hypot(x - ap.ex, y - ap.ey) > FACE_TARGET_MIN_DIST:
            pc.yaw_target = heading_to(x - ap.ex, y - ap.ey)

    def set_velocity(self, ap: ModeHost, vx: float, vy: float, vz: float,
                     yaw: float | None, yaw_rate: float | None) -> None:
        if self.sub == GuidedSubmode.IDLE:
            return
        if self.sub == GuidedSubmode.ATT:
            ap.reset_controller()
        self.sub = GuidedSubmode.VEL
        self.last_cmd_t = ap.time_s
        pc = ap.pc
        pc.set_vel_xy(vx, vy, ap.p["WPNAV_ACCEL"] * 0.01)
        pc.set_climb(vz, ap.p["WPNAV_ACCEL_Z"] * 0.01)
        pc.yaw_rate_ff = 0.0
        if yaw is not None:
            pc.yaw_target = yaw
        elif yaw_rate is not None:
            pc.yaw_rate_ff = yaw_rate

    def set_attitude(self, ap: ModeHost, roll: float, pitch: float, yaw: float,
                     yaw_rate: float | None, thrust: float) -> None:
        if self.sub == GuidedSubmode.IDLE:
            return
        if self.sub != GuidedSubmode.ATT:
            ap.reset_controller()
        self.sub = GuidedSubmode.ATT
        self.last_cmd_t = ap.time_s
        self.att = (roll, pitch, yaw)
        self.att_yaw_rate = yaw_rate
        self.att_thrust = thrust

    def run(self, ap: ModeHost, dt: float) -> None:
        if self.sub == GuidedSubmode.IDLE or (ap.land_complete and self.sub != GuidedSubmode.TAKEOFF):
            ap.idle()
            return
        p = ap.p
        timed_out = ap.time_s - self.last_cmd_t > p["GUID_TIMEOUT"]
        if self.sub == GuidedSubmode.TAKEOFF:
            self._run_takeoff(ap, dt)
        elif self.sub == GuidedSubmode.VEL:
            if timed_out:
                self._stop(ap)
            ap.output_tracking(dt)
        elif self.sub == GuidedSubmode.ATT:
            self._run_attitude(ap, dt, timed_out)
        else:
            ap.output_tracking(dt)

    def _run_attitude(self, ap: ModeHost, dt: float, timed_out: bool) -> None:
        p = ap.p
        pc = ap.pc
        if timed_out:
            roll = pitch = 0.0
            pc.yaw_rate_ff = 0.0
            climb = 0.0
        else:
            amax = ap.angle_max
            roll = min(max(self.att[0], -amax), amax)
            pitch = min(max(self.att[1], -amax), amax)
            if self.att_yaw_rate is not None:
                pc.yaw_rate_ff = self.att_yaw_rate
            else:
                pc.yaw_rate_ff = 0.0
                pc.yaw_target = self.att[2]
            if int(p["GUID_OPTIONS"]) & 8:  # thrust is thrust: no altitude control
                thrust = min(max(self.att_thrust, 0.0), 1.0) * ap.airframe.max_thrust_n
                yaw_rate = pc.update_yaw(dt, ap.phys.yaw, AUTO_YAW_RATE_MAX + abs(pc.yaw_rate_ff))
                ap.output(roll, pitch, yaw_rate, thrust)
                pc.tpz, pc.tvz, pc.taz = ap.ez, ap.evz, 0.0  # bumpless hand-back to climb-rate control
                return
            t = min(max(self.att_thrust, 0.0), 1.0)
            scale = p["WPNAV_SPEED_UP"] if t >= 0.5 else p["WPNAV_SPEED_DN"]
            climb = (t - 0.5) * 2.0 * scale * 0.01
        pc.set_climb(climb, p["WPNAV_ACCEL_Z"] * 0.01)
        ap.output_tracking(dt, roll=roll, pitch=pitch)

    def taking_off(self) -> bool:
        return self.sub == GuidedSubmode.TAKEOFF


def land_descent_rate(ap: ModeHost, dt: float = 0.0) -> float:
    """ArduCopter's landing descent rate (m/s, > 0; Mode::land_run_vertical_control): a sqrt controller
    towards LAND_ALT_LOW (PSC_POSZ_P, WPNAV_ACCEL_Z) held between LAND_SPEED and LAND_SPEED_HIGH (or
    WPNAV_SPEED_DN), so the descent eases down to LAND_SPEED over the metre or two above LAND_ALT_LOW
    and reaches it there, rather than starting to slow at it."""
    p = ap.p
    slow = p["LAND_SPEED"] * 0.01
    fast = max((p["LAND_SPEED_HIGH"] or p["WPNAV_SPEED_DN"]) * 0.01, slow)  # at least LAND_SPEED
    low = max(p["LAND_ALT_LOW"], 100.0) * 0.01
    rate = -sqrt_controller(low - ap.alt_rel(), POS_Z_P, p["WPNAV_ACCEL_Z"] * 0.01, dt)
    return min(max(rate, slow), fast)


def run_landing(ap: ModeHost, dt: float, hold_position: bool) -> None:
    """Descend at the landing rate, holding the horizontal target (or level without position)."""
    pc = ap.pc
    pc.set_climb(-land_descent_rate(ap, dt), ap.p["WPNAV_ACCEL_Z"] * 0.01)
    if hold_position and ap.ekf_ok:
        ap.output_tracking(dt)
    else:
        ap.output_tracking(dt, roll=0.0, pitch=0.0)


class Land(FlightMode):
    """Descends (LAND_SPEED_HIGH / WPNAV_SPEED_DN, easing to LAND_SPEED by LAND_ALT_LOW) and disarms."""

    number, name = 9, "LAND"
    is_autopilot = True

    def __init__(self) -> None:
        self.hold_position = True

    def enter(self, ap: ModeHost) -> str | None:
        super().enter(ap)
        self.hold_position = ap.ekf_ok
        ap.pc.set_vel_xy(0.0, 0.0, ap.p["WPNAV_ACCEL"] * 0.01)
        return None

    def run(self, ap: ModeHost, dt: float) -> None:
        if ap.land_complete:
            ap.idle()
            return
        run_landing(ap, dt, self.hold_position)

    def landing(self) -> bool:
        return True


_CONST, _RISE, _FALL = 0, 1, 2  # jerk held, jerk rising to its peak (raised cosine), jerk falling from it


def _jerk_phase(kind: int, tau: float, tj: float, jm: float) -> tuple[float, float, float]:
    """(acceleration, speed, distance) gained over ``tau`` s of one jerk phase, from zero acceleration
    and speed: constant jerk ``jm``, or ``jm`` rising (falling) over ``tj`` as a raised cosine."""
    if kind == _CONST or tj <= 0.0:
        return jm * tau, 0.5 * jm * tau * tau, jm * tau ** 3 / 6.0
    k = tj / math.pi
    w = tau / k
    a = 0.5 * jm * (tau - k * math.sin(w))
    v = 0.5 * jm * (0.5 * tau * tau + k * k * (math.cos(w) - 1.0))
    x = 0.5 * jm * (tau ** 3 / 6.0 + k * k * (k * math.sin(w) - tau))
    if kind == _RISE:
        return a, v, x
    return jm * tau - a, 0.5 * jm * tau * tau - v, jm * tau ** 3 / 6.0 - x


@dataclass(frozen=True)
class StraightSCurve:
    """A rest-to-rest move along a straight leg with AC_WPNav's S-curve (SCurve.cpp) speed profile.

    Jerk rises to its peak ``jerk`` and falls back as a raised cosine over ``tj = pi jerk / (2 snap)``;
    speeding up is a jerk pulse (the acceleration climbs to at most ``accel``), a spell at that
    acceleration, and the opposite pulse; then a cruise, then the mirror image. The peak speed is the
    largest at or below ``speed`` for which both halves fit the leg; a leg too short for the full jerk
    pulses gets shorter ones of lower peak jerk, as ArduPilot does.
    Built with :meth:`plan`; :meth:`at` gives the distance along, speed and acceleration at a time.
    """

    length: float
    phases: tuple[tuple[float, int, float, float], ...]  # (duration s, kind, rise time tj s, jerk m/s^3)

    @staticmethod
    def _speed_up(v: float, accel: float, jerk: float, snap: float) -> tuple[float, float, float, float, float]:
        """(tj, peak jerk, constant-jerk time, constant-acceleration time, distance) to reach ``v`` from rest."""
        tj = jerk * math.pi / (2.0 * snap)
        # each pulse lasts 2 tj + t2 and takes the acceleration to jerk * (tj + t2); the speed gained is
        # that acceleration times (2 tj + t2 + t4)
        if v >= 2.0 * jerk * tj * tj:
            jm = jerk
            x = 0.5 * (-tj + math.sqrt(tj * tj + 4.0 * v / jm))  # tj + t2 with no constant-acceleration spell
            if jm * x > accel:
                x = max(accel / jm, tj)
            t2 = x - tj
            t4 = max(v / (jm * x) - (2.0 * tj + t2), 0.0)
        else:  # a short move: raised-cosine pulses only, peak jerk scaled down with them (jm = 2 snap tj / pi)
            tj = (math.pi * v / (4.0 * snap)) ** (1.0 / 3.0)
            jm = 2.0 * snap * tj / math.pi
            t2 = t4 = 0.0
        duration = 2.0 * (2.0 * tj + t2) + t4
        return tj, jm, t2, t4, 0.5 * v * duration

    @classmethod
    def plan(cls, length: float, speed: float, accel: float, jerk: float, snap: float) -> StraightSCurve:
        """The fastest such move over ``length`` m within ``speed`` m/s, ``accel`` m/s^2, ``jerk`` m/s^3
        and ``snap`` m/s^4."""
        if length <= 0.0 or speed <= 0.0 or accel <= 0.0 or jerk <= 0.0 or snap <= 0.0:
            return cls(max(length, 0.0), ())
        v = speed
        if 2.0 * cls._speed_up(v, accel, jerk, snap)[4] > length:
            lo, hi = 0.0, speed
            for _ in range(60):
                v = 0.5 * (lo + hi)
                lo, hi = (v, hi) if 2.0 * cls._speed_up(v, accel, jerk, snap)[4] <= length else (lo, v)
            v = lo
        tj, jm, t2, t4, d = cls._speed_up(v, accel, jerk, snap)
        tc = max((length - 2.0 * d) / v, 0.0) if v > 0.0 else 0.0

        def pulse(sign: float) -> list[tuple[float, int, float, float]]:
            return [(tj, _RISE, tj, sign * jm), (t2, _CONST, tj, sign * jm), (tj, _FALL, tj, sign * jm)]

        phases = (pulse(1.0) + [(t4, _CONST, tj, 0.0)] + pulse(-1.0) + [(tc, _CONST, tj, 0.0)]
                  + pulse(-1.0) + [(t4, _CONST, tj, 0.0)] + pulse(1.0))
        return cls(length, tuple(ph for ph in phases if ph[0] > 0.0))

    @property
    def duration(self) -> float:
        """Time the move takes, s."""
        return sum(ph[0] for ph in self.phases)

    def at(self, t: float) -> tuple[float, float, float]:
        """(distance along, speed, acceleration) at ``t`` s after the start; at rest at the end after it."""
        if t >= self.duration:
            return self.length, 0.0, 0.0
        s = v = a = 0.0
        for d, kind, tj, jm in self.phases:
            h = min(d, max(t, 0.0))
            da, dv, ds = _jerk_phase(kind, h, tj, jm)
            s += v * h + 0.5 * a * h * h + ds
            v += a * h + dv
            a += da
            t -= h
            if t <= 0.0:
                break
        return min(s, self.length), v, a


RTL_ALT_MIN_M = 0.3  # ArduCopter RTL_ALT_MIN (30 cm)
RTL_MIN_CONE_SLOPE = 0.5  # shallower cones are ignored


def rtl_return_alt(alt: float, dist: float, rtl_alt: float, climb_min: float, cone_slope: float) -> float:
    """Height above home RTL returns at (ArduCopter ModeRTL::compute_return_target), m.

    At least RTL_ALT and the present height plus RTL_CLIMB_MIN; a cone of slope RTL_CONE_SLOPE about
    home caps the climb near home (``dist`` from the stopping point: at most slope * dist, but never
    below the present height plus RTL_CLIMB_MIN); it never descends to return. RTL_ALT 0 returns at
    the present height.

    Args:
        alt: present height above home, m.
        dist: horizontal distance from the stopping point to home, m.
        rtl_alt: RTL_ALT, m.
        climb_min: RTL_CLIMB_MIN, m (negative counts as 0).
        cone_slope: RTL_CONE_SLOPE (below 0.5: no cone).
    """
    min_alt = max(RTL_ALT_MIN_M, alt + max(0.0, climb_min))
    target = max(rtl_alt, min_alt)
    if cone_slope >= RTL_MIN_CONE_SLOPE:
        target = min(target, max(dist * cone_slope, min_alt))
    return max(target, alt)


def stopping_point(px: float, py: float, vx: float, vy: float, accel: float) -> tuple[float, float]:
    """Where the horizontal controller would stop from (px, py) at (vx, vy): AC_PosControl's stopping
    point, the inverse of a sqrt controller of gain PSC_POSXY_P braking at ``accel``."""
    v = math.hypot(vx, vy)
    if v < 1e-6 or accel <= 0.0:
        return px, py
    linear_v = accel / POS_XY_P
    if v < linear_v:
        d = v / POS_XY_P
    else:
        d = 0.5 * accel / (POS_XY_P * POS_XY_P) + v * v / (2.0 * accel)
    return px + vx / v * d, py + vy / v * d


class RtlState:
    """Stages of ArduCopter's RTL."""

    CLIMB = "climb"
    RETURN = "return"
    LOITER = "loiter_at_home"
    FINAL_DESCENT = "final_descent"
    LAND = "land"


class Rtl(FlightMode):
    """Return to launch (ArduCopter ModeRTL): climb to the return altitude (:func:`rtl_return_alt`:
    RTL_ALT, capped by RTL_CONE_SLOPE near home) above the stopping point, fly home at RTL_SPEED,
    hover RTL_LOIT_TIME, then land and disarm (or descend to RTL_ALT_FINAL and hover).

    The climb and the return are waypoint legs, each a :class:`StraightSCurve` (WPNAV_JERK, WPNAV_ACCEL
    or WPNAV_ACCEL_Z, the leg's speed) that the position controller follows. The climb leg, with the
    return leg queued behind it, ends when its curve does (a fast waypoint); the return leg ends when its
    curve has stopped over home and the vehicle is within WPNAV_RADIUS of it.
    """

    number, name, requires_position = 6, "RTL", True
    is_autopilot = True

    def __init__(self) -> None:
        self.state = RtlState.CLIMB
        self.return_z = 0.0
        self.loiter_start = 0.0
        self.leg_start = 0.0
        self.leg_origin = (0.0, 0.0, 0.0)
        self.leg_dir = (0.0, 0.0, 0.0)
        self.leg = StraightSCurve(0.0, ())
        self.leg_t = 0.0
        self.track_scale = 1.0
        self.track_tc = 1.0

    def enter(self, ap: ModeHost) -> str | None:
        if ap.home_enu is None:
            if ap.armed:
                return "requires position"
            super().enter(ap)  # ModeRTL::init(ignore_checks): accepted disarmed; RTL cannot arm
            self.state = RtlState.LAND
            return None
        super().enter(ap)
        p = ap.p
        sx, sy = stopping_point(ap.ex, ap.ey, ap.evx, ap.evy, p["WPNAV_ACCEL"] * 0.01)
        dist = math.hypot(sx - ap.home_enu[0], sy - ap.home_enu[1])
        self.return_z = ap.home_enu[2] + rtl_return_alt(ap.alt_rel(), dist, p["RTL_ALT"] * 0.01,
                                                        p["RTL_CLIMB_MIN"] * 0.01, p["RTL_CONE_SLOPE"])
        if ap.land_complete:
            self.state = RtlState.LAND
            return None
        self.state = RtlState.CLIMB
        # the waypoint controller starts at the stopping point (wp_and_spline_init)
        pc = ap.pc
        pc.tpx, pc.tpy, pc.tvx, pc.tvy, pc.tax, pc.tay = sx, sy, 0.0, 0.0, 0.0, 0.0
        self._start_leg(ap, (sx, sy, ap.ez), (sx, sy, self.return_z))
        return None

    def speed_xy(self, ap: ModeHost) -> float:
        return (ap.p["RTL_SPEED"] or ap.p["WPNAV_SPEED"]) * 0.01

    def _start_leg(self, ap: ModeHost, origin: tuple[float, float, float],
                   destination: tuple[float, float, float]) -> None:
        """Plan a straight S-curve leg; speed and acceleration are the horizontal or vertical limits,
        whichever the leg's direction meets first (AC_WPNav's kinematic_limit)."""
        p = ap.p
        d = [b - a for a, b in zip(origin, destination)]
        length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        self.leg_origin = origin
        self.leg_dir = tuple(c / length for c in d) if length > 1e-9 else (0.0, 0.0, 0.0)
        h = math.hypot(self.leg_dir[0], self.leg_dir[1])
        up = self.leg_dir[2]
        v_z = p["WPNAV_SPEED_UP"] * 0.01 if up > 0.0 else p["WPNAV_SPEED_DN"] * 0.01
        speed = _kinematic_limit(h, up, self.speed_xy(ap), v_z)
        accel = _kinematic_limit(h, up, p["WPNAV_ACCEL"] * 0.01, p["WPNAV_ACCEL_Z"] * 0.01)
        jerk = p["WPNAV_JERK"]
        # AC_WPNav::calc_scurve_jerk_and_snap: snap from the attitude loop's time constant, halved
        self.leg = StraightSCurve.plan(length, speed, accel, jerk, 0.5 * jerk * math.pi / (2.0 * ATC_INPUT_TC))
        self.leg_t = 0.0
        self.track_scale = 1.0
        self.track_tc = p["WPNAV_ACCEL"] * 0.01 / jerk if jerk > 0.0 else 1.0

    def _follow_leg(self, ap: ModeHost, dt: float) -> bool:
        """Put this step's point of the leg into the position controller; True once the curve has ended.

        The curve's clock runs slower while the vehicle lags its target (AC_WPNav's track time scale:
        the vehicle's speed along the track, less the position error's share, over the target's speed,
        filtered with a time constant of WPNAV_ACCEL / WPNAV_JERK), so a vehicle still carrying speed
        the other way first stops, then follows.
        """
        o, u = self.leg_origin, self.leg_dir
        s, v, _ = self.leg.at(self.leg_t)
        scale = 1.0
        if v > 1e-6:
            err = sum((o[i] + u[i] * s - e) * u[i] for i, e in enumerate((ap.ex, ap.ey, ap.ez)))
            along = ap.evx * u[0] + ap.evy * u[1] + ap.evz * u[2]
            scale = min(max(0.05 + (along - POS_XY_P * err) / v, 0.0), 1.0)
        self.track_scale += (scale - self.track_scale) * min(dt / self.track_tc, 1.0)
        self.leg_t += dt * self.track_scale
        s, v, a = self.leg.at(self.leg_t)
        ap.pc.follow(tuple(o[i] + u[i] * s for i in range(3)), tuple(u[i] * v for i in range(3)),
                     tuple(u[i] * a for i in range(3)))
        return self.leg_t >= self.leg.duration

    def run(self, ap: ModeHost, dt: float) -> None:
        if ap.land_complete:
            ap.idle()
            return
        p = ap.p
        pc = ap.pc
        hx, hy, hz = ap.home_enu
        if self.state == RtlState.CLIMB:
            if self._follow_leg(ap, dt):
                self.state = RtlState.RETURN
                self._start_leg(ap, (pc.tpx, pc.tpy, self.return_z), (hx, hy, self.return_z))
        if self.state == RtlState.RETURN:
            ended = self._follow_leg(ap, dt)
            if ended and math.hypot(ap.ex - hx, ap.ey - hy) <= p["WPNAV_RADIUS"] * 0.01:
                self.state = RtlState.LOITER
                self.loiter_start = ap.time_s
        elif self.state == RtlState.LOITER and ap.time_s - self.loiter_start >= p["RTL_LOIT_TIME"] * 0.001:
            final = p["RTL_ALT_FINAL"] * 0.01
            if final > 0.0:
                self.state = RtlState.FINAL_DESCENT
                pc.set_alt(hz + final, p["WPNAV_SPEED_UP"] * 0.01, p["WPNAV_SPEED_DN"] * 0.01,
                           p["WPNAV_ACCEL_Z"] * 0.01)
            else:
                self.state = RtlState.LAND
        if self.state == RtlState.LAND:
            run_landing(ap, dt, hold_position=True)
        else:
            ap.output_tracking(dt)

    def landing(self) -> bool:
        return self.state == RtlState.LAND


def _kinematic_limit(h: float, up: float, max_xy: float, max_z: float) -> float:
    """The largest speed (or acceleration) along a unit direction with horizontal part ``h`` and
    vertical part ``up`` that keeps within ``max_xy`` across and ``max_z`` up or down."""
    if h < 1e-9:
        return max_z
    if abs(up) < 1e-9:
        return max_xy
    return min(max_xy / h, max_z / abs(up))


def make_modes() -> dict[int, FlightMode]:
    """One instance of each supported mode, by ArduCopter mode number."""
    modes: list[FlightMode] = [Stabilize(), AltHold(), Guided(), Loiter(), Rtl(), Land(), Brake()]
    return {m.number: m for m in modes}
