"""RHCSearch and MaxBeliefSearch flown against the simulator, with a cue written as a mission input."""

from __future__ import annotations

import numpy as np
import py_trees
import pytest

from chaser_bt.cue import TargetCue
from chaser_bt.search import SearchSnapshot

from flight_helpers import runner_for, take_off

Status = py_trees.common.Status

CUE_ENU = np.array([120.0, 80.0, 40.0])


def write_cue(t: float, position=CUE_ENU) -> None:
    py_trees.blackboard.Blackboard.set("/target/cue", TargetCue(t, np.asarray(position, float), np.diag([30.0, 30.0, 10.0]) ** 2, source="radar"))


def snapshots(vehicle, runner, seconds: float) -> list[SearchSnapshot]:
    """Tick for ``seconds`` of sim time, collecting each tick's published search state."""
    out = []
    vehicle.track = []

    def tick() -> bool:
        vehicle.track.append(vehicle.sim.truth.pos_enu.copy())
        if runner.tick_if_due():
            snap = py_trees.blackboard.Blackboard.get("/search/belief") if py_trees.blackboard.Blackboard.exists("/search/belief") else None
            if snap is not None and (not out or snap.t != out[-1].t):
                out.append(snap)
        return runner.finished

    vehicle.run_until(tick, seconds)
    return out


def test_rhc_search_flies_steps_towards_the_cue_and_publishes_the_belief(vehicle):
    take_off(vehicle, 40)
    write_cue(vehicle.clock.now())
    runner = runner_for(vehicle, "RHCSearch: {horizon: 5, gamma: 0.9}")
    start = vehicle.sim.truth.pos_enu.copy()
    snaps = snapshots(vehicle, runner, 40.0)
    assert runner.status == Status.RUNNING, runner.tip_message()
    assert len(snaps) > 100
    # The belief is advanced and lowered each tick, with the mass accounted for.
    last = snaps[-1]
    assert last.belief.ledger.observed > 0.05
    assert last.belief.total() + last.belief.ledger.removed == pytest.approx(1.0, abs=1e-9)
    assert max(s.gain for s in snaps) > 0.01
    # Each set-point was one step (<= one cell diagonal) from where the vehicle was when it planned.
    replans = [s for s in snaps if s.replanned and not s.plan.fell_back]
    assert len(replans) >= 5
    assert all(np.max(np.abs(s.plan.path[1] - s.plan.path[0])) == 1 for s in replans)
    # Flown by the simulator: it closed in on the cue, searching where the belief was.
    end = vehicle.sim.truth.pos_enu
    assert np.linalg.norm(end[:2] - CUE_ENU[:2]) < np.linalg.norm(start[:2] - CUE_ENU[:2]) - 60.0


def test_max_belief_search_heads_for_the_most_probable_cell(vehicle):
    take_off(vehicle, 40)
    write_cue(vehicle.clock.now())
    runner = runner_for(vehicle, "MaxBeliefSearch: {}")
    snaps = snapshots(vehicle, runner, 30.0)
    assert runner.status == Status.RUNNING, runner.tip_message()
    np.testing.assert_allclose(snaps[0].target_enu, CUE_ENU, atol=20.0)
    # It flew to the cue; once the camera had lowered the belief there, the maximum moved on.
    closest = min(np.linalg.norm(p[:2] - CUE_ENU[:2]) for p in vehicle.track)
    assert closest < 25.0
    assert np.linalg.norm(snaps[-1].target_enu - CUE_ENU) > 20.0


def test_search_without_a_cue_fails_and_hovers(vehicle):
    take_off(vehicle, 20)
    runner = runner_for(vehicle, "RHCSearch: {horizon: 2}")
    assert vehicle.fly(runner, 2.0) == Status.FAILURE
    assert "cue" in runner.tree.root.feedback_message
    assert vehicle.link.last_setpoint is not None


def test_search_with_a_cue_off_the_grid_fails_with_the_reason(vehicle):
    take_off(vehicle, 20)
    write_cue(vehicle.clock.now(), [5000.0, 0.0, 40.0])
    runner = runner_for(vehicle, "MaxBeliefSearch: {}")
    assert vehicle.fly(runner, 2.0) == Status.FAILURE
    assert "outside the search grid" in runner.tree.root.feedback_message


def test_a_cue_just_outside_the_grid_moves_the_grid_onto_it_and_the_search_flies(vehicle):
    """The target left the +-400 m area by 50 m: the search centres its grid on the cue (its lattice
    kept) instead of failing and leaving the aircraft to hold while the target flies on."""
    take_off(vehicle, 40)
    write_cue(vehicle.clock.now(), [450.0, 0.0, 40.0])
    runner = runner_for(vehicle, "RHCSearch: {horizon: 2}")
    snaps = snapshots(vehicle, runner, 4.0)
    assert runner.status == Status.RUNNING, runner.tip_message()
    spec = snaps[-1].belief.spec
    assert spec.contains([450.0, 0.0, 40.0]) and spec.shape[:2] == (41, 41)
    assert spec.origin_enu[0] == pytest.approx(40.0) and spec.origin_enu[1] == pytest.approx(-400.0)


def _belief_centre(snap: SearchSnapshot) -> np.ndarray:
    p = snap.belief.p / snap.belief.p.sum()
    return np.einsum("ijk,ijkl->l", p, snap.belief.spec.centers())


def test_velocity_dynamics_drift_the_belief_with_the_cue_and_the_random_walk_does_not(vehicle):
    """A cue 5 s old moving 8 m/s east: after 15 s of search the belief's centre has drifted
    east by about 8 x (5 + 15) = 160 m less what the camera took away near it (the grid is +-400 m,
    the chaser searches from far west of it); with the paper's random walk it stays at the cue."""
    take_off(vehicle, 40)
    t0 = vehicle.clock.now()
    cue = TargetCue(t0 - 5.0, CUE_ENU, np.diag([20.0, 20.0, 10.0]) ** 2, np.array([8.0, 0.0, 0.0]), "radar")
    centres = {}
    for motion in ("velocity", "random_walk"):
        py_trees.blackboard.Blackboard.set("/target/cue", cue)
        runner = runner_for(vehicle, f"RHCSearch: {{horizon: 3, gamma: 0.9, dynamics: {motion}}}")
        snaps = snapshots(vehicle, runner, 15.0)
        assert runner.status == Status.RUNNING, runner.tip_message()
        centres[motion] = _belief_centre(snaps[-1])
    drift = centres["velocity"] - CUE_ENU
    assert 100.0 < drift[0] < 200.0 and abs(drift[1]) < 30.0
    assert np.linalg.norm(centres["random_walk"][:2] - CUE_ENU[:2]) < 30.0
