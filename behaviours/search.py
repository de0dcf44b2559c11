"""RHCSearch and MaxBeliefSearch: search the airspace around the last cue until something else takes over.

Each tick (paper section 3.4): advance the belief by the elapsed mission time, lower it where
the camera looks from the vehicle's pose, re-plan when the step is reached, and send the step as
one GUIDED position target facing along the move. The belief starts from the cue on
``/target/cue`` and moves as ``dynamics`` says: the paper's random walk at the target's expected
speeds, or drifting with the cue's own velocity (paper section 5), so a target lost while it
flew on is searched for where it went rather than where it was. A cue that has left the grid's area
by less than its half width moves the grid to centre on it (a search that will not start would leave
the aircraft holding while the target flies on); farther, the search fails. The search state is
published on ``/search/belief`` (a SearchSnapshot: belief,
gain, set-point) for plots and logs. RUNNING until halted (vision acquired, the pilot, a timeout);
FAILURE (and hover) without a cue, outside GUIDED or disarmed, when the belief cannot be built, or
when the vehicle flies no closer to its set-points for ``stall_s`` (the autopilot refuses them).
"""

from __future__ import annotations

import abc
import enum
import logging
import math
from typing import Any

import numpy as np
import py_trees

from behaviours.base import CommandingBehaviour, stall_message, state_port
from chaser_bt.control.progress import ClosingWatch
from chaser_bt.cue import TargetCue
from chaser_bt.search import (BeliefError, BeliefGrid, GaussianDynamics, GridSpec, MaxBeliefPlanner,
                              RecedingHorizonPlanner, SearchSession, SearchSnapshot, SensorModel, VelocityDynamics,
                              warm_up_planner)
from chaser_bt.tree import input_port, output_port, register_behaviour
from chaser_bt.vision import CameraModel

Status = py_trees.common.Status
log = logging.getLogger(__name__)


class TargetMotion(enum.Enum):
    """How the search's belief moves while the target is unseen."""

    RANDOM_WALK = "random_walk"  # the paper's: a Gaussian random walk at v_h_mps / v_v_mps
    VELOCITY = "velocity"  # drift with the cue's velocity, spread by sigma_v_h_mps / sigma_v_v_mps (random walk without one)


class _BeliefSearch(CommandingBehaviour):
    """Shared by both searches; subclasses choose the planner."""

    INPUT_PORTS = {
        "cue": input_port(TargetCue, "Last target cue: the belief starts from it", default_key="/target/cue"),
        "grid_center": input_port(list[float], "ENU centre of the search grid (the radar), m; a cue outside the grid "
                                  "by less than half_width_m moves it onto the cue", default=[0.0, 0.0, 0.0], length=3),
        "half_width_m": input_port(float, "Grid half-width east and north (m)", default=400.0, above=0),
        "z_max_m": input_port(float, "Grid top above the centre's floor (m)", default=200.0, minimum=0),
        "spacing_m": input_port(float, "Grid spacing (m)", default=20.0, above=0),
        "v_h_mps": input_port(float, "Target's expected horizontal speed (m/s)", default=10.0, minimum=0),
        "v_v_mps": input_port(float, "Target's expected vertical speed (m/s)", default=5.0, minimum=0),
        "dynamics": input_port(TargetMotion, "random_walk (the paper's) or velocity (drift with the cue's velocity)",
                               default=TargetMotion.RANDOM_WALK),
        "sigma_v_h_mps": input_port(float, "With velocity: uncertainty of the cue's horizontal velocity (m/s)",
                                    default=3.0, minimum=0),
        "sigma_v_v_mps": input_port(float, "With velocity: uncertainty of the cue's vertical velocity (m/s)",
                                    default=1.5, minimum=0),
        "max_range_m": input_port(float, "Camera detection range (m)", default=80.0, above=0),
        "tilt_deg": input_port(float, "Camera mount tilt below forward (deg)", default=10.0, minimum=-90, maximum=90),
        "p_detect": input_port(float, "Detection probability inside the footprint", default=0.9, minimum=0, maximum=1),
        "replan_s": input_port(float, "Re-plan at least this often (s)", default=2.0, minimum=0),
        "stall_s": input_port(float, "Fail after this long without flying 2 m towards the set-point (s; 0 = never)",
                              default=30.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS = {"belief": output_port(SearchSnapshot, "Belief, belief gain and set-point", default_key="/search/belief")}

    @abc.abstractmethod
    def make_planner(self, sensor: SensorModel):
        """The planner this search flies (RHC or max-belief) over ``sensor``'s footprints."""

    def initialise(self) -> None:
        self._session: SearchSession | None = None
        self._progress = ClosingWatch(window_s=self.get_input("stall_s"))

    def update(self) -> Status:
        state, now = self.state, self._now()
        if state.mode != "GUIDED":
            self.feedback_message = f"vehicle is in {state.mode or 'an unknown mode'}, not GUIDED"
            return Status.FAILURE
        if not state.armed:
            self.feedback_message = "vehicle disarmed"
            return Status.FAILURE
        try:
            if self._session is None:
                self._session = self._start()
            snap = self._session.update(now, state.position_enu, state.attitude, state.yaw_enu_rad)
        except (BeliefError, KeyError, py_trees.ports.NoDataAvailable) as exc:
            self.feedback_message = f"search cannot run: {exc}"
            return Status.FAILURE
        if snap.replanned:
            self._link().goto_enu(snap.target_enu, snap.yaw_enu_rad)
        self._set_output("belief", snap)
        self._progress.observe(now, state.position_enu, snap.target_enu)
        if self._progress.stalled(now):
            to_go = float(np.linalg.norm(np.asarray(snap.target_enu) - state.position_enu))
            self.feedback_message = stall_message(self._progress, now, to_go, state)
            return Status.FAILURE
        self.feedback_message = f"gain {snap.gain:.4f}, to {np.round(snap.target_enu).tolist()}"
        return Status.RUNNING

    def _start(self) -> SearchSession:
        cue = self.get_input("cue")
        if not isinstance(cue, TargetCue):
            raise BeliefError(f"no target cue on the blackboard (got {type(cue).__name__})")
        center, half = self.get_input("grid_center"), self.get_input("half_width_m")
        spec = GridSpec.around(center, half, center[2], center[2] + self.get_input("z_max_m"), self.get_input("spacing_m"))
        off = np.abs(np.asarray(cue.position_enu[:2], float) - np.asarray(center[:2], float))
        if not spec.contains(cue.position_enu) and np.all(off <= 2.0 * half):
            # The target left the area by less than its half width: search around where it went, not hold.
            spec = spec.centred_on(cue.position_enu)
            log.info("%s: the cue lies outside the search area; the grid moves to centre on it", self.name)
        camera = CameraModel(max_range_m=self.get_input("max_range_m"), tilt_rad=math.radians(self.get_input("tilt_deg")),
                             p_detect=self.get_input("p_detect"))
        sensor = SensorModel(camera, spec)
        belief = BeliefGrid.from_cue(spec, cue)
        dynamics = self._dynamics(cue)
        return SearchSession(belief, dynamics, sensor, self.make_planner(sensor), cue.t, replan_s=self.get_input("replan_s"))

    def _dynamics(self, cue: TargetCue) -> GaussianDynamics | VelocityDynamics:
        """The belief's motion model: the cue's velocity when asked for and known, else the random walk."""
        velocity = cue.velocity_enu
        if (self.get_input("dynamics") is TargetMotion.VELOCITY and velocity is not None
                and np.all(np.isfinite(velocity))):
            return VelocityDynamics(np.asarray(velocity, float), self.get_input("sigma_v_h_mps"),
                                    self.get_input("sigma_v_v_mps"))
        return GaussianDynamics(self.get_input("v_h_mps"), self.get_input("v_v_mps"))


@register_behaviour
class RHCSearch(_BeliefSearch):
    """Receding-horizon search (paper Algorithm 2, exact): fly one step of the best h-move path, re-plan."""

    INPUT_PORTS = {
        **_BeliefSearch.INPUT_PORTS,
        "horizon": input_port(int, "Moves per planned path (h; each move more costs about 8x: 8 plans in ~8 s)",
                              default=5, minimum=1, maximum=8),
        "gamma": input_port(float, "Discount factor", default=0.9, minimum=0, maximum=1),
        "threshold": input_port(float, "Minimum path gain; below it go to the belief maximum", default=0.001, minimum=0),
        "node_budget": input_port(int, "0: exact; N > 0: stop after N search nodes (approximate, anytime)", default=0, minimum=0),
    }

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        warm_up_planner()  # the compiled planner is loaded before the flight, not at the first search tick

    def make_planner(self, sensor: SensorModel) -> RecedingHorizonPlanner:
        budget = self.get_input("node_budget")
        return RecedingHorizonPlanner(sensor, self.get_input("horizon"), self.get_input("gamma"), self.get_input("threshold"),
                                      node_budget=budget if budget > 0 else None)


@register_behaviour
class MaxBeliefSearch(_BeliefSearch):
    """Max-belief search (the paper's baseline): fly straight to the most probable cell."""

    def make_planner(self, sensor: SensorModel) -> MaxBeliefPlanner:
        return MaxBeliefPlanner(sensor.spec)
