"""The simulated ArduCopter: arming, modes, failsafes, sensors and estimates around the physics.

:class:`Autopilot` is what a MAVLink endpoint talks to. It keeps the vehicle's side of the
ArduCopter 4.5/4.6 behaviour the mission relies on (DESIGN §5): the slow boot (GPS fix, EKF
position, pre-arm health), pre-arm and arming refusals with ArduPilot's texts, auto-disarm on
the ground after DISARM_DELAY, the GCS-heartbeat, battery and EKF failsafes, RC overrides with
their timeout, and the flight modes of :mod:`sitl.vehicle.modes`. Time only advances through
:meth:`Autopilot.step`; nothing here reads a clock.

Without a transmitter the pilot's RC sits as in ArduPilot's SITL with no joystick: roll, pitch
and yaw centred (1500) and the throttle stick down (1000), so ALT_HOLD descends until the GCS
overrides throttle to 1500 (DESIGN §5). Channels 5-16 read 1500 (no mode switch is simulated).
As ArduCopter, the rotors stay still for 2 s after arming (ARMING_DELAY_SEC); the land detector
reports landed once the rotors touch the ground with the thrust command at its lower limit (ground
idle), the climb rate under 1 m/s and the 1 Hz low-passed acceleration under 1 m/s^2, for
LAND_DETECTOR_TRIGGER_SEC (1 s), as ArduCopter's, and a landing mode disarms after the rotors spool down (MOT_SPOOL_TIME).

Mode changes follow Copter::set_mode: while disarmed any existing mode is accepted (the checks a
mode needs, such as a position estimate, come at arming), while armed a mode that needs a position
is refused without one. The geofence (:mod:`sitl.vehicle.fence`) is checked at 10 Hz; a new breach
while armed is announced ("Fence Breached") and acted on as FENCE_ACTION says. The vehicle's
mission, fence and rally storage (:mod:`sitl.vehicle.mission`) is kept here, as ArduCopter keeps it
in its own storage; this autopilot does not fly AUTO.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.spatial.transform import Rotation

from chaser_bt.geo import (
    GeoPoint,
    LocalFrame,
    NearbyGeodetic,
    body_to_enu_rotation,
    euler_ned_from_rotation,
)
from sitl.vehicle.airframe import AirframeParams
from sitl.vehicle.fence import FENCE_GIVE_UP_DISTANCE_M, breach_distance, destination_within_fence, fence_breaches
from sitl.vehicle.mission import MissionStore
from sitl.vehicle.modes import (
    ARMING_DELAY_S,
    AUTO_YAW_RATE_MAX,
    LAND_ACCEL_LPF_HZ,
    LAND_ACCEL_MAX,
    LAND_DETECT_S,
    LAND_VEL_Z_MAX,
    FlightMode,
    Guided,
    PositionController,
    lowpass_alpha,
    make_modes,
    wrap_pi,
)
from sitl.vehicle.params import ParamStore
from sitl.vehicle.physics import PHYSICS_DT, MulticopterPhysics, NormalStream, Wind
from sitl.vehicle.setup import GCS_MODES, VehicleSetup

__all__ = [
    "CommandResult", "Estimate", "GpsReading", "BatteryReading", "TruthState", "Autopilot",
    "MAV_LANDED_STATE_ON_GROUND", "MAV_LANDED_STATE_IN_AIR", "MAV_LANDED_STATE_TAKEOFF",
    "MAV_LANDED_STATE_LANDING", "FORCE_ARM_MAGIC",
]

MAV_LANDED_STATE_ON_GROUND = 1
MAV_LANDED_STATE_IN_AIR = 2
MAV_LANDED_STATE_TAKEOFF = 3
MAV_LANDED_STATE_LANDING = 4
FORCE_ARM_MAGIC = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2 that skips the checks

_SEV_CRITICAL, _SEV_WARNING, _SEV_NOTICE, _SEV_INFO = 2, 4, 5, 6
#: Mode::name() of ArduCopter's mode.h, where a STATUSTEXT quotes it ("EKF Failsafe: changed to Land Mode").
_MODE_TITLES = {0: "Stabilize", 2: "Altitude Hold", 4: "Guided", 5: "Loiter", 6: "RTL", 9: "Land", 17: "Brake"}
_RC_NEUTRAL = (1500, 1500, 1000, 1500) + (1500,) * 12  # ch1-16 with no transmitter
_UINT16_MAX = 65535

# estimate and GPS error processes (first-order Gauss-Markov): std (m) and time constant (s)
_EST_STD_H, _EST_STD_V, _EST_TAU = 0.05, 0.1, 30.0
_GPS_STD_H, _GPS_STD_V, _GPS_TAU = 0.3, 0.5, 20.0
# the EKF's error is a slow, smooth drift, not a rough walk: its Gauss-Markov process seen through a
# first-order low-pass of this time constant, so it moves at ~0.01 m/s RMS. A 5 s unsmoothed walk had the
# altitude hold chase it at 0.05 m/s RMS (0.1-0.2 m/s at times) in a still hover, where ArduCopter's SITL
# holds 0.00 m/s, and a LAND then began 0.1 s late.
_EST_SMOOTH_S = 3.0
_EKF_LOSS_GRACE_S = 1.0  # the EKF dead-reckons this long after losing GPS before giving up
_BATT_CHECK_PERIOD_S = 0.1


@dataclass(frozen=True)
class CommandResult:
    """Outcome of a command; ``text`` is the STATUSTEXT a real ArduCopter sends (may be "")."""

    accepted: bool
    text: str = ""


@dataclass(frozen=True)
class Estimate:
    """The EKF's navigation solution: ENU position/velocity and geodetic position.

    The geodetic position is converted from ``pos_enu`` on first use only: the conversion costs more
    than a physics step, and many readers (LOCAL_POSITION_NED, set-points) need only ENU.
    """

    pos_enu: np.ndarray
    vel_enu: np.ndarray
    alt_rel_m: float
    geodesy: NearbyGeodetic = field(repr=False)

    @cached_property
    def geodetic(self) -> GeoPoint:
        """``pos_enu`` on WGS84 (altitude in the frame origin's datum: AMSL)."""
        return self.geodesy(self.pos_enu)

    @property
    def lat_deg(self) -> float:
        return self.geodetic.lat_deg

    @property
    def lon_deg(self) -> float:
        return self.geodetic.lon_deg

    @property
    def alt_amsl_m(self) -> float:
        return self.geodetic.alt_m


@dataclass(frozen=True)
class GpsReading:
    """What the GPS receiver reports (GPS_RAW_INT)."""

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    vel_ned: np.ndarray
    fix_type: int
    satellites: int
    eph_m: float
    epv_m: float
    cog_rad: float


@dataclass(frozen=True)
class BatteryReading:
    """Battery monitor output (SYS_STATUS / BATTERY_STATUS)."""

    voltage_v: float
    current_a: float
    remaining_pct: float
    consumed_mah: float


@dataclass(frozen=True)
class TruthState:
    """Ground truth for scoring only; never sent on MAVLink."""

    pos_enu: np.ndarray
    vel_enu: np.ndarray
    euler_ned: tuple[float, float, float]  # roll, pitch, yaw of FRD body in NED, radians
    on_ground: bool
    crashed: bool

    @property
    def attitude(self) -> Rotation:
        """FLU body -> ENU; built on demand, since the scorer reads truth every physics step."""
        return body_to_enu_rotation(*self.euler_ned)


class Autopilot:
    """A simulated ArduCopter flying a :class:`MulticopterPhysics` (see module docstring)."""

    def __init__(self, scenario: VehicleSetup, rng: np.random.Generator) -> None:
        self.setup = scenario
        self.frame = LocalFrame(scenario.home)
        self.geodesy = NearbyGeodetic(self.frame)  # the GPS's and the EKF's positions, near each other
        self.airframe: AirframeParams = scenario.airframe
        self.params = ParamStore({"BATT_CAPACITY": self.airframe.battery_capacity_mah,
                                  **scenario.params})
        self.p = self.params.values
        self._normals = NormalStream(rng)
        self.phys = MulticopterPhysics(self.airframe, Wind(scenario.wind, self._normals),
                                       yaw=math.radians(scenario.home_heading_deg))
        self.pc = PositionController(self.airframe.mass_kg, self.airframe.max_thrust_n)
        self.time_s = 0.0
        self._modes = make_modes()
        self._mode: FlightMode = self._modes[0]
        self.mode_changes = 0  # counts entered modes: ArduCopter sends a HEARTBEAT on each (Copter::set_mode)
        self.armed = False
        self.armed_at = -math.inf
        self.land_complete = True
        self.home: GeoPoint | None = None
        self.home_enu: tuple[float, float, float] | None = None
        self.gps_ok = self.ekf_ok = self.prearm_ok = False
        self._texts: list[tuple[int, str]] = []
        # navigation estimate (ENU floats) and error processes
        self.ex = self.ey = self.ez = 0.0
        self.evx = self.evy = self.evz = 0.0
        self._est_walk = [0.0, 0.0, 0.0]  # the Gauss-Markov process that _est_err smooths
        self._est_err = [0.0, 0.0, 0.0]
        self._gps_err = [0.0, 0.0, 0.0]
        self._err_dt = -1.0
        self._err_coef = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self._gps_lost_at: float | None = None
        # faults as (start, end) intervals per kind
        self._fault_windows = {
            kind: tuple((f.at_s, math.inf if f.duration_s is None else f.at_s + f.duration_s)
                        for f in scenario.faults if f.kind == kind)
            for kind in ("gps_loss", "battery_drop", "rc_loss")
        }
        # forced disarms still to come (a ground station's MAV_CMD_COMPONENT_ARM_DISARM 0 / 21196)
        self._disarms_due = sorted(f.at_s for f in scenario.faults if f.kind == "disarm")
        # RC: overrides per channel (0 = none) and when each was last set
        self._ovr = [0] * 18
        self._ovr_t = [0.0] * 18
        # failsafes, detectors, timers
        self._gcs_last: float | None = None
        # scripted people: the safety pilot's switch, the operator's ground-station mode changes
        self._pilot = scenario.pilot
        self._gcs_events = list(scenario.ground_station)
        self.fs_gcs = False
        self.fs_radio = False
        self._rc_last = 0.0  # when the RC receiver last heard the transmitter
        self.fs_battery = False
        self.fs_ekf = False
        self._batt_low_since: float | None = None
        self._batt_next_check = 0.0
        self.fence_breaches = 0  # FENCE_TYPE bits breached now (SYS_STATUS GEOFENCE health)
        self.missions = MissionStore()
        self._ground_time = 0.0
        self._land_last_vel = (0.0, 0.0, 0.0)
        self._land_accel = [0.0, 0.0, 0.0]  # earth-frame acceleration, low-passed at LAND_ACCEL_LPF_HZ
        self._spool_down_s = 0.0
        self._idle = False
        self._idle_time = 0.0
        self._update_sensors(0.0)

    # ------------------------------------------------------------------ time
    def step(self, dt: float) -> None:
        """Advance controller, physics, battery, failsafes and scripted faults by ``dt`` seconds.

        Steps longer than the physics step (:data:`PHYSICS_DT`) are split evenly.
        """
        if dt <= 0.0:
            return
        n = max(1, math.ceil(dt / PHYSICS_DT - 1e-9))
        h = dt / n
        for _ in range(n):
            self._tick(h)

    def _tick(self, h: float) -> None:
        self.time_s += h
        self._update_sensors(h)
        self._ground_station()
        if self._disarms_due and self.time_s >= self._disarms_due[0]:
            self._disarms_due.pop(0)
            self.request_arm(False, force=True)
        self._failsafes()
        ph = self.phys
        self._idle = False
        if self.armed:
            # ArduCopter holds the motor interlock off for ARMING_DELAY_SEC after arming: rotors still
            ph.motors_on = self.time_s - self.armed_at >= ARMING_DELAY_S
            self._mode.run(self, h)
        else:
            ph.motors_on = False
            ph.thrust_cmd = ph.roll_cmd = ph.pitch_cmd = ph.yaw_rate_cmd = 0.0
        ph.step(h)
        self._land_detector(h)
        self._auto_disarm(h)

    # ------------------------------------------------------------------ sensors, estimate
    def _in_fault(self, kind: str) -> bool:
        windows = self._fault_windows[kind]
        if not windows:  # checked twice a physics step; most scenarios script no faults
            return False
        t = self.time_s
        return any(a <= t < b for a, b in windows)

    def _update_sensors(self, h: float) -> None:
        t = self.time_s
        boot = self.setup.boot
        ph = self.phys
        gps_lost = self._in_fault("gps_loss")
        if gps_lost and self._gps_lost_at is None:
            self._gps_lost_at = t
        elif not gps_lost:
            self._gps_lost_at = None
        self.gps_ok = t >= boot.gps_fix_s and not gps_lost
        ekf_lost = self._gps_lost_at is not None and t - self._gps_lost_at >= _EKF_LOSS_GRACE_S
        self.ekf_ok = t >= boot.ekf_ready_s and not ekf_lost
        self.prearm_ok = t >= boot.prearm_ok_s and self.ekf_ok
        ph.battery.voltage_drop_v = failed_cell_drop_v(ph) if self._in_fault("battery_drop") else 0.0
        if h > 0.0:
            self._advance_errors(h)
        e = self._est_err
        if self._gps_lost_at is None:
            self.ex, self.ey = ph.px + e[0], ph.py + e[1]
            self.evx, self.evy = ph.vx, ph.vy
        else:
            self.evx = self.evy = 0.0
        self.ez, self.evz = ph.pz + e[2], ph.vz
        if self.home is None and self.gps_ok:
            self._set_home()

    def _advance_errors(self, h: float) -> None:
        if h != self._err_dt:
            self._err_dt = h
            a1, a2 = math.exp(-h / _EST_TAU), math.exp(-h / _GPS_TAU)
            s1, s2 = math.sqrt(1.0 - a1 * a1), math.sqrt(1.0 - a2 * a2)
            self._err_coef = (a1, _EST_STD_H * s1, _EST_STD_V * s1, a2, _GPS_STD_H * s2, _GPS_STD_V * s2,
                              1.0 - math.exp(-h / _EST_SMOOTH_S))
        a1, bh1, bv1, a2, bh2, bv2, k = self._err_coef
        take = self._normals.take
        w, e, g = self._est_walk, self._est_err, self._gps_err
        w[0] = a1 * w[0] + bh1 * take()
        w[1] = a1 * w[1] + bh1 * take()
        w[2] = a1 * w[2] + bv1 * take()
        e[0] += (w[0] - e[0]) * k
        e[1] += (w[1] - e[1]) * k
        e[2] += (w[2] - e[2]) * k
        g[0] = a2 * g[0] + bh2 * take()
        g[1] = a2 * g[1] + bh2 * take()
        g[2] = a2 * g[2] + bv2 * take()

    def _set_home(self) -> None:
        self.home_enu = (self.ex, self.ey, self.ez)
        self.home = self.frame.to_geodetic(self.home_enu)

    def alt_rel(self) -> float:
        """Estimated height above home (above the frame origin before home is set), m."""
        return self.ez - (self.home_enu[2] if self.home_enu is not None else 0.0)

    # ------------------------------------------------------------------ controller plumbing for modes
    @property
    def angle_max(self) -> float:
        """ANGLE_MAX in radians."""
        return math.radians(self.p["ANGLE_MAX"] * 0.01)

    def reset_controller(self) -> None:
        """Position controller targets at the present estimate, heading held."""
        self.pc.reset(self.ex, self.ey, self.ez, self.evx, self.evy, self.evz, self.phys.yaw)

    def idle(self) -> None:
        """Rotors at ground idle, controller following the vehicle (no wind-up on the ground)."""
        ph = self.phys
        ph.thrust_cmd = ph.roll_cmd = ph.pitch_cmd = ph.yaw_rate_cmd = 0.0
        self.reset_controller()
        self._idle = True

    def output(self, roll: float, pitch: float, yaw_rate: float, thrust: float) -> None:
        """Send attitude, yaw-rate and thrust commands to the airframe."""
        ph = self.phys
        ph.roll_cmd, ph.pitch_cmd, ph.yaw_rate_cmd, ph.thrust_cmd = roll, pitch, yaw_rate, thrust

    def output_tracking(self, dt: float, roll: float | None = None, pitch: float | None = None) -> None:
        """Run the position controller; ``roll``/``pitch`` given = pilot-set lean (no xy control)."""
        ph = self.phys
        pc = self.pc
        pc.jerk_z = self.p["PSC_JERK_Z"]
        if roll is None or pitch is None:
            pc.jerk_xy = self.p["PSC_JERK_XY"]
            roll, pitch = pc.update_xy(dt, self.ex, self.ey, self.evx, self.evy, ph.yaw, self.angle_max)
        else:
            pc.tpx, pc.tpy, pc.tvx, pc.tvy = self.ex, self.ey, self.evx, self.evy
            pc.tax = pc.tay = 0.0
        thrust = pc.update_z(dt, self.ez, self.evz, ph.roll, ph.pitch)
        yaw_rate = pc.update_yaw(dt, ph.yaw, AUTO_YAW_RATE_MAX + abs(pc.yaw_rate_ff))
        self.output(roll, pitch, yaw_rate, thrust)

    def rc(self, ch: int) -> int:
        """PWM of RC channel ``ch`` (1-based) as the flight controller sees it."""
        i = ch - 1
        v = self._ovr[i]
        if v:
            timeout = self.p["RC_OVERRIDE_TIME"]
            if timeout < 0.0 or self.time_s - self._ovr_t[i] < timeout:
                return v
        if self._pilot is not None:
            if ch == self._pilot.gate_channel:
                return self._pilot.gate_pwm(self.time_s)
            if ch == 3:
                return 1500  # a pilot standing by holds the throttle stick centred (hold altitude)
        return _RC_NEUTRAL[i]

    def _ground_station(self) -> None:
        """The operator's scripted mode changes, as a second ground station's SET_MODE would arrive."""
        while self._gcs_events and self._gcs_events[0].at_s <= self.time_s:
            ev = self._gcs_events.pop(0)
            result = self.request_mode(GCS_MODES[ev.mode])
            if not result.accepted:
                self._text(_SEV_WARNING, f"ground station: {ev.mode} refused ({result.text})")

    # ------------------------------------------------------------------ detectors, failsafes
    def _land_detector(self, h: float) -> None:
        """ArduCopter's land detector (Copter::update_land_detector): landed once, for
        LAND_DETECTOR_TRIGGER_SEC, the throttle has sat at its lower limit (here: a thrust command at or
        below ground idle) with the rotors on the ground, the estimated climb rate within
        LAND_DETECTOR_VEL_Z_MAX of zero and the earth-frame acceleration, low-passed at 1 Hz
        (land_accel_ef_filter), within LAND_DETECTOR_ACCEL_MAX: the touchdown's jolt has to settle."""
        v = (self.evx, self.evy, self.evz)
        a = [(now - last) / h for now, last in zip(v, self._land_last_vel)]
        self._land_last_vel = v
        alpha = lowpass_alpha(h, LAND_ACCEL_LPF_HZ)
        self._land_accel = [f + alpha * (x - f) for f, x in zip(self._land_accel, a)]
        ph = self.phys
        if not ph.on_ground:
            self._ground_time = 0.0
            self.land_complete = False
            return
        still = math.sqrt(sum(x * x for x in self._land_accel)) <= LAND_ACCEL_MAX and abs(self.evz) < LAND_VEL_Z_MAX
        if ph.thrust_cmd <= self.airframe.idle_thrust_n and still:
            self._ground_time += h
        else:
            self._ground_time = 0.0
        if not self.armed or self._ground_time >= LAND_DETECT_S:
            self.land_complete = True

    def _auto_disarm(self, h: float) -> None:
        if not self.armed:
            return
        if self.land_complete and self._mode.landing():
            # a landing mode disarms once the rotors have spooled down to ground idle (MOT_SPOOL_TIME)
            self._spool_down_s += h
            if self._spool_down_s >= self.p["MOT_SPOOL_TIME"]:
                self._disarm()
            return
        self._spool_down_s = 0.0
        delay = self.p["DISARM_DELAY"]
        if self._idle and self.land_complete and delay > 0:
            self._idle_time += h
            if self._idle_time >= delay:
                self._disarm()
        else:
            self._idle_time = 0.0

    def _failsafes(self) -> None:
        t = self.time_s
        p = self.p
        # GCS heartbeat failsafe: only once a GCS has been heard, only while armed
        if self._gcs_last is not None and p["FS_GCS_ENABLE"] and self.armed and not self.fs_gcs:
            if t - self._gcs_last > p["FS_GCS_TIMEOUT"]:
                self.fs_gcs = True
                if int(p["FS_OPTIONS"]) & 16 and not self._mode.is_autopilot and not self.land_complete:
                    self._text(_SEV_WARNING, "GCS Failsafe - Continuing Pilot Control")  # FS_OPTIONS bit 4
                else:
                    self._text(_SEV_WARNING, "GCS Failsafe")
                    self._failsafe_action(int(p["FS_GCS_ENABLE"]), {1: 6, 2: 6, 3: 6, 6: 6, 4: 9, 5: 9, 7: 17})
        self._radio_failsafe()
        # EKF failsafe: position lost while flying in a mode that needs it
        if not self.ekf_ok and self._gps_lost_at is not None and not self.fs_ekf and self.armed:
            # Copter::ekf_check, then failsafe_ekf_event: its words, then its action's
            self.fs_ekf = True
            self._text(_SEV_CRITICAL, "EKF variance: position lost")
            action = int(p["FS_EKF_ACTION"])
            if action and not self.land_complete and (self._mode.requires_position or action == 3):
                self._change_mode(2 if action == 2 else 9)
                self._text(_SEV_CRITICAL, f"EKF Failsafe: changed to {_MODE_TITLES.get(self._mode.number, self.mode)} Mode")
            else:
                self._text(_SEV_CRITICAL, "EKF Failsafe")
        elif self.fs_ekf and self.ekf_ok:
            self.fs_ekf = False
            self._text(_SEV_CRITICAL, "EKF Failsafe Cleared")
        # battery failsafe, checked at 10 Hz like AP_BattMonitor
        if t >= self._batt_next_check:
            self._batt_next_check = t + _BATT_CHECK_PERIOD_S
            self._battery_failsafe()
            self._fence_check()

    def _radio_failsafe(self) -> None:
        """Copter::failsafe_radio_on_event: RC silent for RC_FS_TIMEOUT while armed. FS_THR_ENABLE's
        action unless FS_OPTIONS bit 2 keeps GUIDED flying; "Radio Failsafe Cleared" when it returns."""
        p, t = self.p, self.time_s
        if not self._in_fault("rc_loss"):
            self._rc_last = t
            if self.fs_radio:
                self.fs_radio = False
                self._text(_SEV_WARNING, "Radio Failsafe Cleared")
            return
        if self.fs_radio or t - self._rc_last <= p["RC_FS_TIMEOUT"] or not p["FS_THR_ENABLE"]:
            return
        self.fs_radio = True
        if not self.armed:
            return
        if self.land_complete:
            self._text(_SEV_WARNING, "Radio Failsafe - Disarming")
            self._disarm()
        elif self._mode.number == 4 and int(p["FS_OPTIONS"]) & 4:
            self._text(_SEV_WARNING, "Radio Failsafe - Continuing Guided Mode")
        else:
            self._text(_SEV_WARNING, "Radio Failsafe")
            self._failsafe_action(int(p["FS_THR_ENABLE"]), {1: 6, 2: 6, 3: 9, 4: 6, 5: 9, 6: 6, 7: 17})

    def _battery_failsafe(self) -> None:
        p = self.p
        b = self.phys.battery
        volt = b.voltage_v
        low_v = p["BATT_LOW_VOLT"] > 0.0 and volt < p["BATT_LOW_VOLT"]
        low_mah = p["BATT_LOW_MAH"] > 0.0 and p["BATT_CAPACITY"] - b.consumed_mah < p["BATT_LOW_MAH"]
        if not (low_v or low_mah):
            self._batt_low_since = None
            return
        if self._batt_low_since is None:
            self._batt_low_since = self.time_s
        if self.fs_battery or (low_v and not low_mah and self.time_s - self._batt_low_since < p["BATT_LOW_TIMER"]):
            return
        # AP_BattMonitor::check_failsafes (armed only: a disarmed low battery is a pre-arm failure), then
        # Copter::handle_battery_failsafe's announcement and action
        if not self.armed:
            return
        self.fs_battery = True
        self._text(_SEV_WARNING, f"Battery 1 is low {volt:.2f}V used {b.consumed_mah:.0f} mAh")
        self._text(_SEV_WARNING, "Battery Failsafe - Disarming" if self.land_complete else "Battery Failsafe")
        self._failsafe_action(int(p["BATT_FS_LOW_ACT"]), {1: 9, 2: 6, 3: 6, 4: 9, 6: 6})

    def _fence_check(self) -> None:
        """Copter::fence_check: breaches are recorded armed or not, acted on only while armed."""
        p = self.p
        if self.home_enu is None:
            self.fence_breaches = 0
            return
        hx, hy, _ = self.home_enu
        dist, alt = math.hypot(self.ex - hx, self.ey - hy), self.alt_rel()
        before = self.fence_breaches
        self.fence_breaches = fence_breaches(p, dist, alt)
        new = self.fence_breaches & ~before
        if not new or not self.armed:
            return
        if not self.land_complete:
            self._text(_SEV_NOTICE, "Fence Breached")
        action = int(p["FENCE_ACTION"])
        if action == 0:
            return
        if action in (1, 3, 5) and breach_distance(p, new, dist, alt) > FENCE_GIVE_UP_DISTANCE_M:
            action = 2  # too far outside to fly back: land where it is
        self._failsafe_action(action, {1: 6, 2: 9, 3: 6, 4: 17, 5: 6})

    def _failsafe_action(self, action: int, modes: dict[int, int]) -> None:
        """Disarm when landed, else switch to the action's mode (LAND if that mode can't be used)."""
        if self.land_complete:
            self._disarm()
            return
        target = modes.get(action)
        if target is None or target == self._mode.number:
            return
        if not self._change_mode(target):
            self._change_mode(9)

    def gcs_heartbeat(self) -> None:
        """A heartbeat from the GCS (the endpoint has checked its system id)."""
        self._gcs_last = self.time_s
        if self.fs_gcs:
            self.fs_gcs = False
            self._text(_SEV_WARNING, "GCS Failsafe Cleared")

    # ------------------------------------------------------------------ arming
    def _arm_refusal(self) -> str | None:
        mode = self._mode
        if self.p["ARMING_CHECK"] != 0:
            if not self.gps_ok:
                return "PreArm: Need 3D Fix"
            if not self.ekf_ok:
                return "PreArm: Need Position Estimate"
            if not self.prearm_ok:
                return "PreArm: EKF attitude is bad"
            if self.fs_battery:
                return "PreArm: Battery 1 low voltage failsafe"
        elif mode.requires_position and not self.ekf_ok:
            return "PreArm: Need Position Estimate"
        if not mode.allows_arming:
            return "Arm: Mode not armable"
        thr = self.rc(3)
        if mode.manual_throttle and thr > 1000 + self.p["RC3_DZ"]:
            return "Arm: Throttle too high"
        if not mode.manual_throttle and mode.number != 4 and thr > 1500 + self.p["THR_DZ"]:
            return "Arm: Throttle too high"
        return None

    def request_arm(self, arm: bool, force: bool = False) -> CommandResult:
        """MAV_CMD_COMPONENT_ARM_DISARM. ``force`` = param2 21196 (skip the checks)."""
        if not arm:
            if not self.armed:
                return CommandResult(True)
            if not force and not self.land_complete:
                return CommandResult(False)
            self._disarm()
            return CommandResult(True)
        if self.armed:
            return CommandResult(True)
        if not force:
            reason = self._arm_refusal()
            if reason is not None:
                self._text(_SEV_CRITICAL, reason)
                return CommandResult(False, reason)
        self.armed = True
        self.armed_at = self.time_s
        self._idle_time = 0.0
        if self.ekf_ok:  # ArduCopter resets home to where it arms, when it knows where that is
            self._set_home()
        self._mode.enter(self)
        self._text(_SEV_INFO, "Arming motors")
        return CommandResult(True)

    def _disarm(self) -> None:
        self.armed = False
        self._idle_time = 0.0
        self.phys.motors_on = False
        self._text(_SEV_INFO, "Disarming motors")

    # ------------------------------------------------------------------ modes
    @property
    def mode(self) -> str:
        """ArduCopter mode name (as pymavlink's mode_mapping_acm)."""
        return self._mode.name

    @property
    def mode_number(self) -> int:
        """ArduCopter mode number (HEARTBEAT.custom_mode)."""
        return self._mode.number

    def _change_mode(self, number: int) -> bool:
        mode = self._modes[number]
        # Copter::set_mode: ignore_checks = !armed; the arming checks cover the mode's needs.
        if self.armed and mode.requires_position and not self.ekf_ok:
            self._text(_SEV_WARNING, f"Mode change to {mode.name} failed: requires position")
            return False
        reason = mode.enter(self)
        if reason is not None:
            self._text(_SEV_WARNING, f"Mode change to {mode.name} failed: {reason}")
            return False
        self._mode = mode
        self.mode_changes += 1
        return True

    def request_mode(self, mode_number: int) -> CommandResult:
        """MAV_CMD_DO_SET_MODE / SET_MODE: change flight mode (same mode: accepted, unchanged)."""
        if mode_number == self._mode.number:
            return CommandResult(True)
        if mode_number not in self._modes:
            text = f"No such mode {mode_number}"
            self._text(_SEV_WARNING, text)
            return CommandResult(False, text)
        before = len(self._texts)
        if self._change_mode(mode_number):
            return CommandResult(True)
        return CommandResult(False, self._texts[before][1] if len(self._texts) > before else "")

    # ------------------------------------------------------------------ GCS commands
    def _guided(self) -> Guided | None:
        m = self._mode
        return m if isinstance(m, Guided) else None

    def request_takeoff(self, alt_rel_m: float) -> CommandResult:
        """MAV_CMD_NAV_TAKEOFF: GUIDED, armed and on the ground only (ArduCopter refuses otherwise)."""
        g = self._guided()
        if g is None or not self.armed or not self.land_complete or not _finite(alt_rel_m) \
                or not alt_rel_m > 0.0:
            return CommandResult(False)
        base = self.home_enu[2] if self.home_enu is not None else self.ez
        g.takeoff(self, base + alt_rel_m)
        return CommandResult(True)

    def set_position_target(self, pos_enu: Sequence[float], yaw_enu_rad: float | None = None) -> bool:
        """GUIDED position target (ENU m); held until replaced. False = ignored (not GUIDED)."""
        g = self._guided()
        x, y, z = (float(v) for v in pos_enu[:3])
        if g is None or not _finite(x, y, z, yaw_enu_rad):
            return False
        if self.home_enu is not None:
            hx, hy, hz = self.home_enu
            if not destination_within_fence(self.p, math.hypot(x - hx, y - hy), z - hz):
                return False  # ArduCopter logs DEST_OUTSIDE_FENCE and keeps its old target
        yaw = None if yaw_enu_rad is None else wrap_pi(math.pi / 2.0 - yaw_enu_rad)
        g.set_position(self, x, y, z, yaw)
        return True

    def set_velocity_target(self, vel_enu: Sequence[float], yaw_enu_rad: float | None = None,
                            yaw_rate: float | None = None) -> bool:
        """GUIDED velocity target (ENU m/s); stops after GUID_TIMEOUT without a new one.

        ``yaw_rate`` is ENU (counter-clockwise positive), like ``yaw_enu_rad``.
        """
        g = self._guided()
        vx, vy, vz = (float(v) for v in vel_enu[:3])
        if g is None or not _finite(vx, vy, vz, yaw_enu_rad, yaw_rate):
            return False
        yaw = None if yaw_enu_rad is None else wrap_pi(math.pi / 2.0 - yaw_enu_rad)
        rate = None if yaw_rate is None else -yaw_rate
        g.set_velocity(self, vx, vy, vz, yaw, rate)
        return True

    def set_attitude_target(self, q_xyzw_enu_flu: Sequence[float], yaw_rate: float | None,
                            thrust: float) -> bool:
        """GUIDED attitude target: FLU->ENU quaternion (x, y, z, w), optional ENU yaw rate, thrust 0..1.

        Thrust is a climb-rate demand (0.5 holds altitude) unless GUID_OPTIONS bit 3 is set.
        """
        g = self._guided()
        q = [float(v) for v in q_xyzw_enu_flu[:4]]
        if g is None or not _finite(*q, yaw_rate, thrust) or not any(q):
            return False
        roll, pitch, yaw = euler_ned_from_rotation(Rotation.from_quat(q))
        rate = None if yaw_rate is None else -yaw_rate
        g.set_attitude(self, roll, pitch, yaw, rate, float(thrust))
        return True

    def set_speed(self, speed_mps: float) -> CommandResult:
        """MAV_CMD_DO_CHANGE_SPEED: horizontal speed of GUIDED navigation."""
        g = self._guided()
        if g is None or not _finite(speed_mps) or not speed_mps > 0.0:
            return CommandResult(False)
        g.speed_override = float(speed_mps)
        if self.pc.xy_pos_goal:
            self.pc.speed_xy = float(speed_mps)
        return CommandResult(True)

    def rc_override(self, channels: Sequence[int]) -> None:
        """RC_CHANNELS_OVERRIDE values: ch1-8 0 = release, 65535 = ignore; ch9-18 0/65535 = ignore,
        65534 = release (MAVLink common.xml)."""
        t = self.time_s
        for i, v in enumerate(channels[:18]):
            v = int(v)
            if i < 8:
                if v == _UINT16_MAX:
                    continue
                if v == 0:
                    self._ovr[i] = 0
                    continue
            else:
                if v in (0, _UINT16_MAX):
                    continue
                if v == _UINT16_MAX - 1:
                    self._ovr[i] = 0
                    continue
            self._ovr[i] = v
            self._ovr_t[i] = t

    # ------------------------------------------------------------------ reports
    @property
    def landed_state(self) -> int:
        """MAV_LANDED_STATE_*, as ArduCopter's EXTENDED_SYS_STATE."""
        if not self.armed or self.land_complete:
            return MAV_LANDED_STATE_ON_GROUND
        if self._mode.landing():
            return MAV_LANDED_STATE_LANDING
        if self._mode.taking_off():
            return MAV_LANDED_STATE_TAKEOFF
        return MAV_LANDED_STATE_IN_AIR

    def position_estimate(self) -> Estimate:
        """The EKF's position: truth plus a small slow error; horizontally frozen after GPS loss."""
        return Estimate(
            pos_enu=np.array([self.ex, self.ey, self.ez]),
            vel_enu=np.array([self.evx, self.evy, self.evz]),
            alt_rel_m=self.alt_rel(),
            geodesy=self.geodesy,
        )

    def attitude(self) -> tuple[float, float, float, float, float, float]:
        """Roll, pitch, yaw (NED/FRD, rad) and their rates (rad/s)."""
        ph = self.phys
        return ph.roll, ph.pitch, ph.yaw, ph.roll_rate, ph.pitch_rate, ph.yaw_rate

    def gps(self) -> GpsReading:
        """The GPS receiver's report: no fix before boot.gps_fix_s and during a gps_loss fault."""
        ph = self.phys
        g = self._gps_err
        geo = self.geodesy((ph.px + g[0], ph.py + g[1], ph.pz + g[2]))
        vel_ned = np.array([ph.vy, ph.vx, -ph.vz])
        if self.gps_ok:
            fix, sats, eph, epv = 3, 12, 0.8, 1.2
        else:
            fix, sats, eph, epv = 1, 0 if self._gps_lost_at is not None else 4, 99.99, 99.99
        cog = math.atan2(ph.vx, ph.vy) % (2.0 * math.pi)
        return GpsReading(geo.lat_deg, geo.lon_deg, geo.alt_m, vel_ned, fix, sats, eph, epv, cog)

    def battery(self) -> BatteryReading:
        """Battery monitor: remaining percent against BATT_CAPACITY."""
        b = self.phys.battery
        cap = self.p["BATT_CAPACITY"]
        remaining = 100.0 * max(0.0, 1.0 - b.consumed_mah / cap) if cap > 0 else 0.0
        return BatteryReading(b.voltage_v, b.current_a, remaining, b.consumed_mah)

    def rc_channels(self) -> tuple[int, ...]:
        """The 16 RC channel PWMs the FC uses (pilot RC with live overrides applied)."""
        return tuple(self.rc(ch) for ch in range(1, 17))

    def pop_statustexts(self) -> list[tuple[int, str]]:
        """(MAV_SEVERITY, text) queued since the last call."""
        out, self._texts = self._texts, []
        return out

    def _text(self, severity: int, text: str) -> None:
        self._texts.append((severity, text))

    @property
    def throttle_pct(self) -> float:
        """Motor output, percent of maximum thrust (VFR_HUD.throttle)."""
        return 100.0 * self.phys.thrust / self.airframe.max_thrust_n

    @property
    def groundspeed_mps(self) -> float:
        """Horizontal speed over ground."""
        return math.hypot(self.phys.vx, self.phys.vy)

    @property
    def airspeed_mps(self) -> float:
        """Speed through the air."""
        ph = self.phys
        w = ph.wind_enu
        return math.sqrt((ph.vx - w[0]) ** 2 + (ph.vy - w[1]) ** 2 + (ph.vz - w[2]) ** 2)

    @property
    def heading_deg(self) -> float:
        """Compass heading, 0..360 degrees."""
        return math.degrees(self.phys.yaw) % 360.0

    @property
    def truth(self) -> TruthState:
        """Ground truth for the rehearsal's scoring only."""
        ph = self.phys
        return TruthState(
            pos_enu=np.array([ph.px, ph.py, ph.pz]),
            vel_enu=np.array([ph.vx, ph.vy, ph.vz]),
            euler_ned=(ph.roll, ph.pitch, ph.yaw),
            on_ground=ph.on_ground,
            crashed=ph.crashed,
        )


def _finite(*values: float | None) -> bool:
    """All given numbers are finite (None counts as absent, so fine)."""
    return all(v is None or math.isfinite(v) for v in values)


def failed_cell_drop_v(ph: MulticopterPhysics) -> float:
    """Voltage lost when one cell of the pack fails (the ``battery_drop`` fault): one cell's share."""
    b = ph.battery
    cells = ph.airframe.battery_cells
    return (b.voltage_v + b.voltage_drop_v) / cells
