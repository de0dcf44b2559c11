"""Follow behaviours (paper section 3.2): keep the target in view from above and behind.

- :class:`TargetTelemetryCue` writes the target's own MAVLink position to ``/target/telemetry``.
- :class:`FollowGlobal` follows that cue (the paper's "follow global coordinates").
- :class:`CVFollow` follows the camera's :class:`~chaser_bt.cue.TargetEstimate` from
  ``/target/estimate``, optionally with range from telemetry (as the paper's July 2021 flight).
- :class:`HoverOnStale` guards any follow subtree: target data older than ``max_age_s`` halts the
  child and sends hover; fresh data ticks the child again.

Both follow leaves run :class:`~chaser_bt.control.follow.FollowController`, fly ALT_HOLD through
RC override (``output: alt_hold``, the paper's way) or GUIDED velocity (``output: guided``), switch
the vehicle into that mode themselves (centred throttle first, DESIGN §5), hover at once when the
target data is stale, and hover on halt or failure (CommandingBehaviour).
"""

from __future__ import annotations

import enum
import logging
import math
from dataclasses import replace
from typing import Any, Iterator, Mapping

import numpy as np
import py_trees

from behaviours.base import CommandingBehaviour, VehicleBehaviour, optional_input, state_port
from behaviours.vision import ESTIMATE_KEY
from chaser_bt.control.follow import FollowConfig, FollowController
from chaser_bt.control.sticks import StickMap
from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.target_telemetry import TargetTelemetry
from chaser_bt.tree import NodeKind, input_port, output_port, register_behaviour

Status = py_trees.common.Status
log = logging.getLogger(__name__)

TELEMETRY_KEY = "/target/telemetry"
#: The stick mapping's parameters; where ArduCopter 4.7 renamed one, both names (a vehicle answers one).
STICK_PARAMS = (("ANGLE_MAX", "ATC_ANGLE_MAX"), ("PILOT_Y_RATE",), ("PILOT_SPEED_UP", "PILOT_SPD_UP"),
                ("PILOT_SPEED_DN", "PILOT_SPD_DN"), ("THR_DZ",), ("RC1_DZ",), ("RC2_DZ",), ("RC4_DZ",))


class FollowOutput(enum.Enum):
    """How the follow loops reach the autopilot."""

    ALT_HOLD = "alt_hold"  # RC_CHANNELS_OVERRIDE sticks in ALT_HOLD (the paper)
    GUIDED = "guided"  # SET_POSITION_TARGET velocity + yaw rate in GUIDED
    GUIDED_HEADING = "guided_heading"  # velocity + the heading at the target: the autopilot's yaw controller turns


@register_behaviour
class TargetTelemetryCue(VehicleBehaviour):
    """Write the target's own MAVLink position (another system id) to ``cue``; FAILURE if none fresh.

    Uses the ``target_telemetry`` resource (a TargetTelemetry) when the runner passes one, else
    listens on the vehicle link itself from setup on.
    """

    NODE_KIND = NodeKind.ACTION
    USES_RESOURCES = ("target_telemetry",)  # else it listens on the link itself
    INPUT_PORTS = {
        "sysid": input_port(int, "Target's MAVLink system id (0 = whichever foreign system spoke last)", default=0, minimum=0, maximum=255),
        "max_age_s": input_port(float, "A position older than this is no cue (s)", default=2.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS = {"cue": output_port(TargetCue, "The target's position", default_key=TELEMETRY_KEY)}

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        tel = kwargs.get("target_telemetry")
        self.telemetry = tel if isinstance(tel, TargetTelemetry) else TargetTelemetry.attach(self.link, self._now)

    def update(self) -> Status:
        sysid = self.get_input("sysid") or None
        cue = self.telemetry.cue(self._link().frame, sysid)
        if cue is None or cue.age(self._now()) > self.get_input("max_age_s"):
            self.feedback_message = "no fresh target telemetry"
            return Status.FAILURE
        self._set_output("cue", cue)
        self.feedback_message = f"target {cue.track_id} at {cue.position_enu.round(1).tolist()}"
        return Status.SUCCESS


class _Follow(CommandingBehaviour):
    """Shared by the follow leaves: mode switch, controller, one command per control step."""

    _via = ""  # what the target data came from when not the leaf's own target, for the feedback message

    COMMON_PORTS = {
        "slant_range_m": input_port(float, "Slant range set-point (m)", default=40.0, above=0),
        "elevation_deg": input_port(float, "Elevation above the target set-point (deg)", default=40.0, minimum=-90, maximum=90),
        "output": input_port(FollowOutput, "alt_hold (RC override), guided (velocity and yaw rate) or guided_heading "
                             "(velocity and the heading at the target)", default=FollowOutput.ALT_HOLD),
        "use_roll": input_port(bool, "Roll loop: full horizontal control", default=False),
        "feed_forward": input_port(bool, "Feed the target's velocity forward", default=False),
        "stale_after_s": input_port(float, "Hover when target data is older than this (s)", default=2.0, minimum=0),
        "max_lean_deg": input_port(float, "Lean limit (deg) below the vehicle's ANGLE_MAX; 0 = ANGLE_MAX", default=0.0, minimum=0, maximum=90),
        "measured_rates": input_port(bool, "Derivative terms from the target's measured velocity (else from the "
                                     "filtered process variables)", default=True),
        "give_up_after_s": input_port(float, "FAILURE after this long stale (s); 0 = keep hovering", default=0.0, minimum=0),
        "min_range_m": input_port(float, "Closer than this slant range (m), GUIDED backs off along the line of sight "
                                  "and climbs; 0 = off", default=0.0, minimum=0),
        "max_closing_mps": input_port(float, "GUIDED closes on the set-point at most this much faster than the target "
                                      "moves (m/s); 0 = no limit", default=0.0, minimum=0, maximum=50),
        "state": state_port(),
    }

    def target(self) -> TargetCue | None:
        return optional_input(self, "target")

    def config_options(self) -> dict[str, Any]:
        """Further FollowConfig fields from this leaf's own ports."""
        return {}

    @classmethod
    def check_ports(cls, values: Mapping[str, Any], child_count: int) -> list[tuple[str, str]]:
        """Settings the controller refuses are a validation problem where the literals show them."""
        slant, floor = values.get("slant_range_m"), values.get("min_range_m")
        if isinstance(slant, (int, float)) and isinstance(floor, (int, float)) and floor >= slant > 0:
            return [("min_range_m", f"min_range_m must be below slant_range_m ({slant:g} m), got {floor:g}")]
        return []

    def initialise(self) -> None:
        out = self._output = self.get_input("output")
        self._mode = "ALT_HOLD" if out is FollowOutput.ALT_HOLD else "GUIDED"
        self._mode_cmd = None
        self._stale_since: float | None = None
        self._sent_t: float | None = None
        try:  # settings wired from the blackboard are only known now
            config = FollowConfig(slant_range_m=self.get_input("slant_range_m"),
                                  elevation_rad=math.radians(self.get_input("elevation_deg")),
                                  use_roll=self.get_input("use_roll"), feed_forward=self.get_input("feed_forward"),
                                  stale_after_s=self.get_input("stale_after_s"),
                                  max_lean_rad=math.radians(self.get_input("max_lean_deg")) or None,
                                  measured_rates=self.get_input("measured_rates"),
                                  min_range_m=self.get_input("min_range_m"),
                                  max_closing_mps=self.get_input("max_closing_mps"), **self.config_options())
        except ValueError as e:
            self.controller = None
            self._refused = f"follow settings refused: {e}"
            log.error("%s: %s", self.name, self._refused)
            return
        link = self._link()
        for names in STICK_PARAMS:  # the stick mapping is the vehicle's: ask for its parameters
            if not any(name in link.params for name in names):
                for name in names:
                    link.request_param(name)
        self.controller = FollowController(config, StickMap.from_params(link.params))
        if self.state.mode != self._mode:
            if self._mode == "ALT_HOLD":
                link.rc_override(1500, 1500, 1500, 1500)  # centred throttle before ALT_HOLD or it sinks
            self._mode_cmd = link.set_mode(self._mode)

    def update(self) -> Status:
        link, state, now = self._link(), self.state, self._now()
        if self.controller is None:
            self.feedback_message = self._refused
            return Status.FAILURE
        if self._mode_cmd is not None:
            if not self._mode_cmd.done:
                self.feedback_message = f"switching to {self._mode}"
                return Status.RUNNING
            if not self._mode_cmd.ok:
                self.feedback_message = f"{self._mode} refused: {self._mode_cmd.reason}"
                return Status.FAILURE
            self._mode_cmd = None
        if state.mode != self._mode:
            self.feedback_message = f"vehicle left {self._mode} for {state.mode}"
            return Status.FAILURE
        self.controller.stick_map = StickMap.from_params(link.params)  # as the parameters arrive
        cmd = self.controller.update(now, state.position_enu, state.velocity_enu, state.yaw_enu_rad, self.target())
        if cmd.hover:
            self._stale_since = now if self._stale_since is None else self._stale_since
            link.hover()
            self.feedback_message = f"hover: {cmd.reason}"
            give_up = self.get_input("give_up_after_s")
            return Status.FAILURE if give_up > 0 and now - self._stale_since >= give_up else Status.RUNNING
        self._stale_since = None
        if cmd.t != self._sent_t:  # a new control step (5 Hz); the link re-sends held sticks itself
            self._sent_t = cmd.t
            if self._output is FollowOutput.ALT_HOLD:
                link.rc_override(*cmd.sticks.as_tuple())
            elif self._output is FollowOutput.GUIDED_HEADING:
                link.velocity_enu(cmd.velocity_enu, yaw_enu_rad=cmd.heading_enu)
            else:
                link.velocity_enu(cmd.velocity_enu, yaw_rate=cmd.yaw_rate)
        pv = cmd.pv
        self.feedback_message = (f"{self._via}az {math.degrees(pv.azimuth_rad):+.0f} deg, ground {pv.ground_range_m:.1f} m, "
                                 f"height {pv.rel_height_m:.1f} m")
        return Status.RUNNING


@register_behaviour
class FollowGlobal(_Follow):
    """Follow the target's global position (its telemetry cue) with the paper's three PID loops; RUNNING."""

    INPUT_PORTS = {"target": input_port(TargetCue, "Target position cue", required=False, default_key=TELEMETRY_KEY),
                   **_Follow.COMMON_PORTS}
    OUTPUT_PORTS: dict = {}


@register_behaviour
class CVFollow(_Follow):
    """Follow the camera's target estimate (bearing from vision); range from ``range_cue`` when fresh, and
    the target's velocity (for ``feed_forward``) from ``velocity_cue`` when fresh; RUNNING."""

    INPUT_PORTS = {
        "target": input_port(TargetEstimate, "Vision target estimate", required=False, default_key=ESTIMATE_KEY),
        "range_cue": input_port(TargetCue, "Optional cue whose distance replaces the vision range (remap it to "
                                "{@target/telemetry} for the target's own GPS); unset: range from vision", required=False),
        "velocity_cue": input_port(TargetCue, "Optional cue whose velocity is the target's (remap it to the radar cue, "
                                   "{@target/cue}); unset: differenced vision positions", required=False),
        "coast_cue": input_port(TargetCue, "Optional cue the follow flies on while the vision estimate is stale and this "
                                "is fresh (remap it to the radar cue, {@target/cue}); unset: hover on stale data",
                                required=False),
        "range_smoothing_s": input_port(float, "Vision range low-pass time constant (s): keep the bearing, slow the "
                                        "range; 0 = use the estimate as it is", default=0.0, minimum=0),
        **_Follow.COMMON_PORTS,
    }
    OUTPUT_PORTS: dict = {}

    def config_options(self) -> dict[str, Any]:
        return {"range_smoothing_s": self.get_input("range_smoothing_s")}

    def _fresh(self, port: str) -> TargetCue | None:
        cue: TargetCue | None = optional_input(self, port)
        return cue if cue is not None and cue.age(self._now()) <= self.get_input("stale_after_s") else None

    def target(self) -> TargetCue | None:
        est: TargetEstimate | None = optional_input(self, "target")
        self._via = ""
        if est is None or est.age(self._now()) > self.get_input("stale_after_s"):
            coast = self._fresh("coast_cue")
            if coast is not None:
                self._via = f"on {coast.source} cue: "
                return coast
        if est is None:
            return None
        moving = self._fresh("velocity_cue")
        if moving is not None and moving.velocity_enu is not None:
            est = replace(est, velocity_enu=moving.velocity_enu)
        ranged = self._fresh("range_cue")
        if ranged is None:
            return est
        camera = est.position_enu - est.range_m * est.bearing_enu if math.isfinite(est.range_m) else self.state.position_enu
        rng = float(np.linalg.norm(ranged.position_enu - camera))
        return TargetCue(t=est.t, position_enu=camera + rng * est.bearing_enu, covariance_enu=est.covariance_enu,
                         velocity_enu=est.velocity_enu, source="vision+telemetry-range", track_id=est.track_id)


@register_behaviour
class HoverOnStale(py_trees.ports.PortsMixin, py_trees.decorators.Decorator):
    """Tick the child while target data is fresh; when older than ``max_age_s``, halt it and hover.

    RUNNING while hovering; FAILURE once stale for ``give_up_after_s`` (0 = never), so a fallback
    can take over (paper section 2.2.1: from follow back to fly-to-cue or search). With ``face`` set
    to another sensor's cue (the radar's) and that cue fresh, the hover turns the nose, and a fixed
    camera, towards it: a target that passed under or beside the chaser is behind it, where the
    camera cannot find it again while the heading is held. With ``coast`` set to another sensor's cue
    and that cue fresh, stale data is no hover: the child flies on that cue (CVFollow's ``coast_cue``),
    keeping pace with a target the camera lost for a moment instead of stopping while it flies on.
    """

    INPUT_PORTS = {
        "target": input_port(TargetCue, "The data whose age is watched", required=False, default_key=ESTIMATE_KEY),
        "max_age_s": input_port(float, "Stale after this long without new data (s)", default=2.0, minimum=0),
        "give_up_after_s": input_port(float, "FAILURE after this long stale (s); 0 = never", default=0.0, minimum=0),
        "face": input_port(TargetCue, "Optional cue the hover turns towards while fresh (remap it to the radar cue, "
                           "{@target/cue}); unset: the heading is held", required=False),
        "face_max_age_s": input_port(float, "The face cue is fresh this long (s)", default=2.0, minimum=0),
        "coast": input_port(TargetCue, "Optional cue that keeps the child flying while the watched data is stale and "
                            "this is fresh, max_age_s (remap it to the cue the child flies on then, CVFollow's "
                            "coast_cue); unset: hover", required=False),
    }
    OUTPUT_PORTS: dict = {}

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour) -> None:
        super().__init__(name=name, child=child)
        self.link = None
        self.clock = None
        self._stale_since: float | None = None

    def setup(self, **kwargs: Any) -> None:
        self.link, self.clock = kwargs.get("link"), kwargs.get("clock")
        if self.link is None or self.clock is None:
            raise KeyError(f"{self.name}: setup() needs link and clock (the mission runner passes them)")

    def initialise(self) -> None:
        self._stale_since = None

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.status != Status.RUNNING:
            self.initialise()
        now = self.clock.now()
        if self._stale(now):
            if self.decorated.status == Status.RUNNING:
                self.decorated.stop(Status.INVALID)  # the child hovers on halt
            yaw = self._towards_face(now)
            self.link.hover(yaw)
            self._stale_since = now if self._stale_since is None else self._stale_since
            give_up = self.get_input("give_up_after_s")
            self.feedback_message = "target data stale: hover" + ("" if yaw is None else ", facing the cue")
            self.status = Status.FAILURE if give_up > 0 and now - self._stale_since >= give_up else Status.RUNNING
            if self.status != Status.RUNNING:
                self.stop(self.status)
            yield self
            return
        self._stale_since = None
        yield from self.decorated.tick()
        self.status = self.decorated.status
        self.feedback_message = self.decorated.feedback_message
        if self.status != Status.RUNNING:
            self.stop(self.status)
        yield self

    def _stale(self, now: float) -> bool:
        """Neither the watched data nor the ``coast`` cue is younger than ``max_age_s``."""
        max_age = self.get_input("max_age_s")
        return all(cue is None or cue.age(now) > max_age
                   for cue in (optional_input(self, "target"), optional_input(self, "coast")))

    def _towards_face(self, now: float) -> float | None:
        """The ENU yaw from the aircraft to a fresh ``face`` cue; None without one (or on top of it)."""
        cue: TargetCue | None = optional_input(self, "face")
        if cue is None or cue.age(now) > self.get_input("face_max_age_s"):
            return None
        d = np.asarray(cue.position_enu[:2], float) - np.asarray(self.link.state.position_enu[:2], float)
        if not np.all(np.isfinite(d)) or float(np.hypot(*d)) < 1.0:
            return None
        return math.atan2(float(d[1]), float(d[0]))

    def update(self) -> Status:
        """Unused: :meth:`tick` decides the status."""
        return self.status
