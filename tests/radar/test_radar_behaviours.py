"""RadarTrackValidated and RadarCue against the simulator: the ownship hovers in the radar's view
beside a circling intruder; neither behaviour may ever validate or cue on our own drone."""

from __future__ import annotations

import numpy as np
import py_trees
import pytest

from chaser_bt.geo import GeoPoint
from chaser_bt.radar.feed import RadarFeed, RadarNoise
from chaser_bt.radar.geometry import RadarPose
from chaser_bt.radar.stream import QueueDatagramSource
from chaser_bt.tree import load_tree_text
from sitl.bench.in_process import InProcessVehicle
from sitl.world.radar import RadarConfig
from sitl.world.scenario import BootParams, Scenario, ScriptedTarget
from sitl.world.targets import CirclePath

Status = py_trees.common.Status
HOME = GeoPoint(42.5445, -71.6105, 80.0)


@pytest.fixture(scope="module")
def flight():
    """Airborne 20 m over home; radar 100 m south looking north; intruder circling 150 m north."""
    radar = RadarConfig(GeoPoint(42.5436, -71.6105, 81.0), pitch_rad=np.radians(10.0), pd=1.0)
    scn = Scenario("radar-behaviours", HOME, boot=BootParams(1.0, 2.0, 3.0), radar=radar,
                   targets=(ScriptedTarget("intruder", CirclePath((0.0, 150.0, 30.0), 30.0, 5.0)),))
    v = InProcessVehicle(scn, seed=2)
    assert v.run_until(lambda: v.link.state.ready_to_arm and v.link.frame is not None, 30)
    v.link.set_mode("GUIDED")
    v.run_until(lambda: v.link.state.mode == "GUIDED", 5)
    v.link.arm()
    v.run_until(lambda: v.link.state.armed, 5)
    v.link.takeoff(20.0)
    assert v.run_until(lambda: v.link.state.alt_rel_m > 19.0, 60)
    queue = QueueDatagramSource()
    v.sim.add_radar_consumer(queue.push)
    labels: dict[int, str] = {}
    pose = RadarPose.from_geodetic(v.link.frame, radar.position, radar.yaw_rad, radar.pitch_rad, radar.roll_rad)
    feed = RadarFeed(queue, pose, noise=RadarNoise(radar.sigma_range_m, radar.sigma_az_rad, radar.sigma_el_rad))
    return v, feed, labels


def tick_tree(flight, body: str, seconds: float, before=None) -> tuple[py_trees.trees.BehaviourTree, list[Status]]:
    v, feed, labels = flight
    tree = load_tree_text("version: 1\ntrees:\n  Test:\n    " + body + "\n", source="<test>")
    bt = py_trees.trees.BehaviourTree(tree.root)
    bt.setup(link=v.link, clock=v.clock, radar=feed)
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key("/vehicle/state", access=py_trees.common.Access.WRITE)
    statuses = []
    end = v.sim.time_s + seconds
    while v.sim.time_s < end:
        for _ in range(5):  # 10 Hz ticks over 50 Hz physics
            v.step()
            if v.sim.radar_truth is not None:
                labels.update(v.sim.radar_truth.labels)
        bb.set("/vehicle/state", v.link.state)
        if before:
            before()
        bt.tick()
        statuses.append(bt.root.status)
    return bt, statuses


def read(key: str):
    bb = py_trees.blackboard.Client(name="reader")
    bb.register_key(key, access=py_trees.common.Access.READ)
    return bb.get(key)


def test_cue_follows_the_intruder_and_never_the_ownship(flight):
    v, feed, labels = flight
    bt, st = tick_tree(flight, "RadarCue: {}", 8.0)
    assert st[-1] == Status.SUCCESS
    cue = read("/target/cue")
    assert labels[cue.track_id] == "intruder" and cue.source == "radar"
    truth = v.sim.scenario.targets[0].path.position_enu(cue.t)
    assert np.linalg.norm(cue.position_enu - truth) < 8.0
    assert cue.covariance_enu.shape == (3, 3) and cue.age(v.clock.now()) < 0.5
    own = feed.update(v.clock.now()).ownship_ids
    assert own and all(labels[i] == "ownship" for i in own)


def test_track_is_validated_by_confidence_and_is_the_intruder(flight):
    _, _, labels = flight
    _, st = tick_tree(flight, "RadarTrackValidated: {min_confidence: 0.8, min_track_age_s: 1.0}", 3.0)
    assert st[-1] == Status.SUCCESS and labels[read("/radar/validated_track")] == "intruder"


def test_operator_confirmation_validates_but_not_our_own_track(flight):
    v, feed, labels = flight
    bb = py_trees.blackboard.Client(name="operator")
    bb.register_key("/radar/operator_confirmed_track", access=py_trees.common.Access.WRITE)
    ownship = next(iter(feed.update(v.clock.now()).ownship_ids))
    bb.set("/radar/operator_confirmed_track", ownship)
    _, st = tick_tree(flight, "RadarTrackValidated: {min_confidence: 1.0}", 1.0)
    assert set(st) == {Status.FAILURE}  # confidence never reaches 1.0 and the ownship cannot be confirmed
    intruder = next(i for i in feed.update(v.clock.now()).tracks if labels.get(i) == "intruder")
    bb.set("/radar/operator_confirmed_track", intruder)
    _, st = tick_tree(flight, "RadarTrackValidated: {min_confidence: 1.0}", 0.5)
    assert st[-1] == Status.SUCCESS and read("/radar/validated_track") == intruder


def test_cue_fails_when_the_radar_goes_quiet(flight):
    v, feed, _ = flight
    v.sim.surroundings.radar = None  # the radar goes quiet
    _, st = tick_tree(flight, "RadarCue: {max_age_s: 2.0}", 3.5)
    assert st[0] == Status.SUCCESS and st[-1] == Status.FAILURE
