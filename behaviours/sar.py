"""Search-and-rescue leaves: the operator's last-known position as the cue, the find, the loiter over it.

The search-and-rescue mission (trees/sar.yaml, docs/sar.md) is the chase with three slots swapped:

- :class:`OperatorCue` replaces the radar: the operator's last-known position (ENU or lat/lon) and
  its uncertainty become the :class:`~chaser_bt.cue.TargetCue` on ``/target/cue`` that fly-out and
  RHC search read. The cue is live (re-written every tick, SUCCESS) until the vehicle has reached
  it; then it is spent: no longer written, so it ages like a radar cue whose track ended (FAILURE),
  which moves the mission from fly-out to search exactly as a lost radar cue does in the chase.
- :class:`ReportFind` turns the camera's person estimates into a :class:`~chaser_bt.find.Find`
  (ground fixes, robust median): a candidate on ``/sar/candidate`` until a closer look confirms it
  (:class:`~chaser_bt.find.FindCheck`), then the find on ``/sar/find``, logged.
- :class:`FindCandidate` and :class:`LoiterOverFind` (on the candidate): the closer look; then
  LoiterOverFind holds over the find in GUIDED instead of following.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import py_trees

from behaviours.base import CommandingBehaviour, VehicleBehaviour, optional_input, state_port
from behaviours.goto import WaypointFrame
from behaviours.hover import MAX_HOLD_S
from behaviours.vision import ESTIMATE_KEY
from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.control.cue_approach import approach_point
from chaser_bt.find import Find, FindCheck, FindEstimator, FindVerdict
from chaser_bt.geo import GeoPoint
from chaser_bt.tree import NodeKind, input_port, output_port, register_behaviour

Status = py_trees.common.Status
log = logging.getLogger(__name__)

CUE_KEY = "/target/cue"
FIND_KEY = "/sar/find"
CANDIDATE_KEY = "/sar/candidate"


@register_behaviour
class OperatorCue(VehicleBehaviour):
    """Write the operator's last-known position as the cue each tick; SUCCESS until the vehicle reaches it.

    The cue carries the tick's time (the operator's report stands until checked) and a covariance
    of ``sigma_m`` horizontally and ``sigma_up_m`` vertically; a lat/lon waits for the vehicle's
    home (FAILURE meanwhile). Once the vehicle has come within ``reached_m`` of the point
    horizontally the cue is spent: it is no longer written (it goes stale from the moment of
    arrival, and the search's belief starts from it) and the node FAILS from then on.
    """

    NODE_KIND = NodeKind.ACTION
    INPUT_PORTS = {
        "position": input_port(list[float], "Last-known position: [east, north, up] m (frame enu) or "
                                            "[lat_deg, lon_deg, alt_m above home] (frame global)", length=3),
        "frame": input_port(WaypointFrame, "enu or global", default=WaypointFrame.ENU),
        "sigma_m": input_port(float, "Horizontal 1-sigma uncertainty of the position (m)", default=50.0, minimum=0),
        "sigma_up_m": input_port(float, "Vertical 1-sigma uncertainty (m)", default=2.0, minimum=0),
        "reached_m": input_port(float, "The cue is spent once the vehicle is this close horizontally (m); 0 = never",
                                default=10.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS = {"cue": output_port(TargetCue, "The operator's cue", default_key=CUE_KEY)}

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        self._position: np.ndarray | None = None
        self._spent = False

    def update(self) -> Status:
        if self._spent:
            self.feedback_message = "last-known position reached: cue spent"
            return Status.FAILURE
        if self._position is None:
            self._position = self._resolve()
            if self._position is None:
                return Status.FAILURE
            log.info("operator cue at %s m ENU, sigma %.0f m", np.round(self._position, 1).tolist(), self.get_input("sigma_m"))
        sh, sv = self.get_input("sigma_m"), self.get_input("sigma_up_m")
        self._set_output("cue", TargetCue(t=self._now(), position_enu=self._position,
                                          covariance_enu=np.diag([sh**2, sh**2, sv**2]), source="operator"))
        away = float(np.hypot(*(self.state.position_enu[:2] - self._position[:2])))
        reached = self.get_input("reached_m")
        if reached > 0 and away <= reached:
            self._spent = True
            log.info("operator cue reached (%.1f m): spent", away)
            self.feedback_message = "last-known position reached: cue spent"
            return Status.FAILURE
        self.feedback_message = f"last-known position {away:.0f} m away"
        return Status.SUCCESS

    def _resolve(self) -> np.ndarray | None:
        position = self.get_input("position")
        # A literal was checked by validate; a blackboard-wired value is checked here, before it flies.
        problem = self.INPUT_PORTS["position"].violation(position)
        if problem is not None:
            self.feedback_message = f"position {problem}"
            return None
        if self.get_input("frame") is WaypointFrame.ENU:
            return np.asarray(position, dtype=float)
        frame, home = self._link().frame, self.state.home
        if frame is None or home is None:
            self.feedback_message = "vehicle home not known yet"
            return None
        lat, lon, alt_rel = position
        return frame.point_to_enu(GeoPoint(lat, lon, home.alt_m + alt_rel))


@register_behaviour
class ReportFind(VehicleBehaviour):
    """Fix the person on the ground from each fresh, confident camera estimate; write the find once confirmed.

    Once ``min_fixes`` fixes agree over ``min_span_s`` they make a candidate, written to ``candidate``
    (FAILURE: the tree flies closer, LoiterOverFind on the candidate). ``check_fixes`` new agreeing
    fixes from within ``check_range_m``, spanning ``min_span_s``, confirm it: it is written to
    ``find``, logged, refined on every later tick, and the node succeeds from then on. A candidate
    the vehicle has been within ``check_range_m`` of for ``check_timeout_s`` without that is
    rejected: ``candidate`` is cleared and fixes in its place are ignored
    (:class:`~chaser_bt.find.FindCheck`). ``check_range_m`` 0 reports the first candidate. Fixes are
    kept for the whole mission.
    """

    NODE_KIND = NodeKind.ACTION
    INPUT_PORTS = {
        "estimate": input_port(TargetEstimate, "The camera's person estimate", required=False, default_key=ESTIMATE_KEY),
        "min_confidence": input_port(float, "Least estimate confidence used (0..1)", default=0.3, minimum=0, maximum=1),
        "max_age_s": input_port(float, "Older estimates are not used (s)", default=0.5, minimum=0),
        "plane_z_m": input_port(float, "ENU height of the box centre's plane (m; about half a person above ground)",
                                default=0.5),
        "max_range_m": input_port(float, "Farthest fix along the line of sight (m)", default=60.0, minimum=0),
        "gate_m": input_port(float, "Fixes farther than this from their median do not agree (m)", default=10.0, minimum=0),
        "min_fixes": input_port(int, "Agreeing fixes needed for a find", default=5, minimum=1),
        "min_span_s": input_port(float, "The agreeing fixes must span this long (s): one false detection carried by "
                                        "the trackers does not", default=2.0, minimum=0),
        "check_range_m": input_port(float, "A closer look: new fixes from within this range (m) confirm a candidate; "
                                           "0 = report the first candidate", default=0.0, minimum=0),
        "check_fixes": input_port(int, "New close fixes that confirm a candidate", default=3, minimum=1),
        "check_timeout_s": input_port(float, "Reject a candidate not confirmed after this long near it (s)", default=15.0,
                                      above=0),
        "state": state_port(),
    }
    OUTPUT_PORTS = {
        "find": output_port(Find, "The person's position, geodetic point and confidence", default_key=FIND_KEY),
        "candidate": output_port(Find, "A find waiting for the closer look (cleared when rejected)",
                                 default_key=CANDIDATE_KEY),
    }

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        self._estimator: FindEstimator | None = None
        self._check: FindCheck | None = None
        self._last_t = -np.inf
        self._reported: Find | None = None
        self._has_candidate = False

    def update(self) -> Status:
        if self._estimator is None:
            gate = self.get_input("gate_m")
            self._estimator = FindEstimator(self.get_input("plane_z_m"), self.get_input("max_range_m"), gate,
                                            self.get_input("min_fixes"), self.get_input("min_span_s"))
            if self.get_input("check_range_m") > 0:
                self._check = FindCheck(self.get_input("check_range_m"), self.get_input("check_fixes"),
                                        self.get_input("min_span_s"), self.get_input("check_timeout_s"), gate)
        est: TargetEstimate | None = optional_input(self, "estimate")
        if (est is not None and est.t > self._last_t and est.age(self._now()) <= self.get_input("max_age_s")
                and est.confidence >= self.get_input("min_confidence")):
            self._last_t = est.t
            self._estimator.add(est)
        find = self._estimator.find(self._link().frame)
        if find is None:
            self._clear_candidate()
            self.feedback_message = f"{self._estimator.fix_count} ground fix(es), no find yet"
            return Status.FAILURE
        if self._check is not None:
            verdict = self._check.update(self._now(), self.state.position_enu, find, self._estimator)
            if verdict is FindVerdict.REJECTED:
                dropped = self._estimator.reject(find.position_enu)
                self._clear_candidate()
                log.warning("candidate find at %s m rejected: not seen again within %.0f m for %.0f s (%d fixes dropped)",
                            np.round(find.position_enu[:2], 1).tolist(), self._check.close_m, self._check.timeout_s, dropped)
                self.feedback_message = f"candidate at {np.round(find.position_enu[:2], 1).tolist()} m rejected"
                return Status.FAILURE
            if verdict is FindVerdict.PENDING:
                self._set_output("candidate", find)
                self._has_candidate = True
                self.feedback_message = (f"candidate at {np.round(find.position_enu[:2], 1).tolist()} m: "
                                         f"{self._check.close_fixes(find, self._estimator)} of {self._check.confirm_fixes} "
                                         f"close fixes, looking closer")
                return Status.FAILURE
        self._clear_candidate()
        self._set_output("find", find)
        if self._reported is None or np.linalg.norm(find.position_enu - self._reported.position_enu) > 1.0:
            log.info("person found: %s", find.to_dict())
            self._reported = find
        self.feedback_message = (f"find at {np.round(find.position_enu[:2], 1).tolist()} m, +-{find.std_m:.1f} m, "
                                 f"{find.fixes} fixes")
        return Status.SUCCESS

    def _clear_candidate(self) -> None:
        if self._has_candidate:
            self.reset_port("candidate")
            self._has_candidate = False


@register_behaviour
class FindCandidate(VehicleBehaviour):
    """SUCCESS while a candidate find waits for the closer look (ReportFind's ``candidate``), else FAILURE."""

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS = {
        "candidate": input_port(Find, "The candidate find", required=False, default_key=CANDIDATE_KEY),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def update(self) -> Status:
        candidate: Find | None = optional_input(self, "candidate")
        if candidate is None:
            self.feedback_message = "no candidate"
            return Status.FAILURE
        self.feedback_message = f"candidate at {np.round(candidate.position_enu[:2], 1).tolist()} m"
        return Status.SUCCESS


@register_behaviour
class LoiterOverFind(CommandingBehaviour):
    """Hold in GUIDED over the find at ``height_m``, facing it from ``standoff_m`` away; RUNNING.

    Re-targets when the find moves by more than ``retarget_m`` and re-sends every ``resend_s``.
    SUCCESS after ``duration_s`` (0 = hold until halted); FAILURE without a find or outside GUIDED.
    """

    INPUT_PORTS = {
        "find": input_port(Find, "The find to hold over", required=False, default_key=FIND_KEY),
        "height_m": input_port(float, "Holding height above home (m)", default=20.0, above=0),
        "standoff_m": input_port(float, "Horizontal distance from the find, on the vehicle's side (m); 0 = above it",
                                 default=0.0, minimum=0),
        "duration_s": input_port(float, "Hold this long (s); 0 = until halted", default=0.0, minimum=0,
                                 maximum=MAX_HOLD_S),
        "retarget_m": input_port(float, "Move the station when the find moves this much (m)", default=2.0, minimum=0),
        "resend_s": input_port(float, "Re-send the position target this often (s)", default=1.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def initialise(self) -> None:
        self._anchor: np.ndarray | None = None  # the find position the station was computed for
        self._station = None  # CueApproach: goal and the yaw facing the find
        self._sent_s = -np.inf
        self._started_s = self._now()

    def update(self) -> Status:
        state, now = self.state, self._now()
        if state.mode != "GUIDED":
            self.feedback_message = f"vehicle is in {state.mode or 'an unknown mode'}, not GUIDED"
            return Status.FAILURE
        find: Find | None = optional_input(self, "find")
        if find is None:
            self.feedback_message = "no find to hold over"
            return Status.FAILURE
        if self._anchor is None or np.linalg.norm(find.position_enu - self._anchor) > self.get_input("retarget_m"):
            self._anchor = find.position_enu.copy()
            # The fly-to-cue geometry, with the find as the cue: on the vehicle's side of it, facing it.
            self._station = approach_point(state.position_enu, find.position_enu, standoff_m=self.get_input("standoff_m"),
                                           min_alt_m=self.get_input("height_m"), height_above_m=0.0)
            self._sent_s = -np.inf
        assert self._station is not None
        if now - self._sent_s >= self.get_input("resend_s"):
            self._link().goto_enu(self._station.goal_enu, self._station.yaw_enu_rad)
            self._sent_s = now
        held, duration = now - self._started_s, self.get_input("duration_s")
        if duration > 0 and held >= duration:
            self.feedback_message = f"held over the find {held:.0f} s"
            return Status.SUCCESS
        off = float(np.linalg.norm(state.position_enu - self._station.goal_enu))
        self.feedback_message = f"over the find at {np.round(find.position_enu[:2], 1).tolist()} m ({off:.0f} m from station)"
        return Status.RUNNING
