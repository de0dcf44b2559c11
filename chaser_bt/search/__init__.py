"""Probabilistic search for a lost target (paper section 3.4, Algorithm 2).

A :class:`BeliefGrid` over the airspace, advanced by target dynamics (:class:`GaussianDynamics`,
:class:`VelocityDynamics`), lowered by the camera's :class:`SensorModel` where it looked and saw
nothing, and two planners on it: the exact :class:`RecedingHorizonPlanner` (Algorithm 2) and the
:class:`MaxBeliefPlanner` baseline. :class:`SearchSession` ties them together for a behaviour.
"""

from chaser_bt.search.belief import BeliefError, BeliefGrid, GridSpec, MassLedger, box_mask, corridor_mask
from chaser_bt.search.dynamics import GaussianDynamics, VelocityDynamics
from chaser_bt.search.max_belief import MaxBeliefPlanner
from chaser_bt.search.rhc import PlanResult, RecedingHorizonPlanner, warm_up_planner
from chaser_bt.search.sensor import SensorModel, level_attitude
from chaser_bt.search.session import SearchSession, SearchSnapshot

__all__ = [
    "BeliefError", "BeliefGrid", "GridSpec", "MassLedger", "box_mask", "corridor_mask",
    "GaussianDynamics", "VelocityDynamics", "MaxBeliefPlanner", "PlanResult", "RecedingHorizonPlanner", "warm_up_planner",
    "SensorModel", "level_attitude", "SearchSession", "SearchSnapshot",
]
