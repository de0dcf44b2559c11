"""GoTo: fly to a waypoint in GUIDED and succeed inside the acceptance radius."""

from __future__ import annotations

import enum

import numpy as np
import py_trees

from behaviours.base import CommandingBehaviour, send_speed_after_target, stall_message, state_port
from chaser_bt.control.progress import ProgressWatch
from chaser_bt.geo import GeoPoint
from chaser_bt.tree import input_port, register_behaviour

Status = py_trees.common.Status


class WaypointFrame(enum.Enum):
    """How GoTo reads its waypoint."""

    ENU = "enu"  # [east, north, up] metres from the mission origin (the vehicle's home by default)
    GLOBAL = "global"  # [lat_deg, lon_deg, alt_m above home]


@register_behaviour
class GoTo(CommandingBehaviour):
    """Send one GUIDED position target and wait until the vehicle is within ``acceptance_radius_m``.

    ArduCopter holds a position target until it is replaced (DESIGN §5); the target is re-sent every
    ``resend_s`` anyway, so a lost datagram costs a second, not the mission. FAILURE when the vehicle
    leaves GUIDED (a failsafe or the pilot took over), is disarmed, or gets no closer for ``stall_s``
    (:class:`~chaser_bt.control.progress.ProgressWatch`: ArduCopter's fence refuses a target outside it
    and holds): the tree decides what comes next, instead of waiting for the battery.
    """

    INPUT_PORTS = {
        "waypoint": input_port(list[float], "[east, north, up] m (frame enu) or [lat_deg, lon_deg, alt_m] (frame global)", length=3),
        "frame": input_port(WaypointFrame, "enu or global", default=WaypointFrame.ENU),
        "acceptance_radius_m": input_port(float, "Arrived when this close to the waypoint (m)", default=2.0, minimum=0),
        "speed_mps": input_port(float, "Horizontal speed (m/s); 0 keeps the vehicle's WPNAV_SPEED", default=0.0, minimum=0),
        "resend_s": input_port(float, "Re-send the target this often (s)", default=1.0, minimum=0),
        "stall_s": input_port(float, "Fail after this long without getting 2 m closer (s; 0 = never)", default=30.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._target_enu: np.ndarray | None = None
        self._last_sent_s = -np.inf
        self._progress = ProgressWatch(window_s=self.get_input("stall_s"))
        self._speed_sent = False

    def update(self) -> Status:
        state, link = self.state, self._link()
        if state.mode != "GUIDED":
            self.feedback_message = f"vehicle is in {state.mode or 'an unknown mode'}, not GUIDED"
            return Status.FAILURE
        if not state.armed:
            self.feedback_message = "vehicle disarmed"
            return Status.FAILURE
        if self._target_enu is None:
            target = self._resolve_target()
            if target is None:
                return Status.FAILURE
            self._target_enu = target
        now = self._now()
        if now - self._last_sent_s >= self.get_input("resend_s"):
            link.goto_enu(self._target_enu)
            self._last_sent_s = now
            self._speed_sent = self._speed_sent or send_speed_after_target(link, self.get_input("speed_mps"))
        distance = float(np.linalg.norm(state.position_enu - self._target_enu))
        if distance <= self.get_input("acceptance_radius_m"):
            self.feedback_message = f"arrived ({distance:.1f} m)"
            return Status.SUCCESS
        self._progress.observe(now, distance)
        if self._progress.stalled(now):
            self.feedback_message = stall_message(self._progress, now, distance, state)
            return Status.FAILURE
        self.feedback_message = f"{distance:.0f} m to go"
        return Status.RUNNING

    def _resolve_target(self) -> np.ndarray | None:
        waypoint = self.get_input("waypoint")
        # A literal was checked by validate; a blackboard-wired value is checked here, before it flies.
        problem = self.INPUT_PORTS["waypoint"].violation(waypoint)
        if problem is not None:
            self.feedback_message = f"waypoint {problem}"
            return None
        if self.get_input("frame") is WaypointFrame.ENU:
            return np.asarray(waypoint, dtype=float)
        frame, home = self._link().frame, self.state.home
        if frame is None or home is None:
            self.feedback_message = "vehicle home not known yet"
            return None
        lat, lon, alt_rel = waypoint
        return frame.point_to_enu(GeoPoint(lat, lon, home.alt_m + alt_rel))

