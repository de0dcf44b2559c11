"""Target custody against hand-worked radar pictures: drop-outs, new ids, id swaps, other objects."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from chaser_bt.radar.custody import Custody, CustodyParams, Sight, designate, track_custody
from chaser_bt.radar.feed import RadarPicture, RadarTrack

COV = np.eye(3) * 4.0  # 2 m per axis: trace 12, the report's share of the gate's sigma


def track(tid: int, t: float, pos, vel=(0.0, 0.0, 0.0), conf: float = 0.95, first: float = 0.0) -> RadarTrack:
    return RadarTrack(tid, t, np.array(pos, float), None if vel is None else np.array(vel, float), COV, conf, first)


def picture(t: float, *tracks: RadarTrack) -> RadarPicture:
    return RadarPicture(t, {tr.track_id: tr for tr in tracks}, None, t)


def fly(c: Custody, pictures, params: CustodyParams | None = None):
    events = []
    for pic in pictures:
        c, ev = track_custody(c, pic, params)
        events += ev
    return c, events


def start(t: float = 0.0, pos=(0.0, 100.0, 30.0), vel=(5.0, 0.0, 0.0)) -> Custody:
    c, ev = designate(track(1, t, pos, vel), t, "test")
    assert ev is not None and ev.kind == "designated"
    return c


def test_the_carrying_track_confirms_the_target():
    c = start()
    c, ev = fly(c, [picture(0.2 * k, track(1, 0.2 * k, (k * 1.0, 100, 30), (5, 0, 0))) for k in range(1, 6)])
    assert ev == [] and c.track_id == 1 and c.t_confirmed == pytest.approx(1.0)
    np.testing.assert_allclose(c.position_enu, (5, 100, 30))
    assert c.confidence(1.0) == 1.0


def test_a_new_id_at_the_predicted_place_takes_over_but_a_bird_seen_beside_the_target_does_not():
    c = start()
    bird = lambda t, x: track(7, t, (x, 100, 30), (5, 0, 0), conf=0.6)
    # The bird flies 30 m behind the target while both are tracked: another object.
    c, _ = fly(c, [picture(0.2, track(1, 0.2, (1, 100, 30), (5, 0, 0)), bird(0.2, -29))])
    assert 7 in c.apart_ids
    # The target's track drops; 1 s later the bird sits on the prediction (x = 6) and a new id is 3 m off it.
    c, ev = fly(c, [picture(0.4, bird(0.4, -28)),
                    picture(1.2, bird(1.2, 6.0), track(9, 1.2, (6, 103, 30), (5, 0, 0), first=1.2))])
    assert [e.kind for e in ev] == ["released", "handover"]
    assert c.track_id == 9 and c.target_id == 1 and c.track_ids == (1, 9)


def test_a_track_outside_the_gate_is_not_the_target_and_a_long_silence_loses_it():
    p = CustodyParams(max_coast_s=3.0)
    c = start()
    # Dropped at t = 0; 2 s later the prediction is x = 10; the gate there is 3.5 sigma of the two
    # reports, 3.5 * sqrt(12 + 12) = 17.1 m, plus 0.5 * 8 * 2^2 = 16 m of manoeuvre: 33.1 m. A new
    # track 60 m off is something else.
    far = track(5, 2.0, (10, 160, 30), (5, 0, 0), first=2.0)
    c, ev = fly(c, [picture(2.0, far)], p)
    assert c.track_id is None and [e.kind for e in ev] == ["released"]
    c, ev = fly(c, [picture(3.5, track(5, 3.5, (17, 160, 30), (5, 0, 0), first=2.0))], p)
    assert c.lost and [e.kind for e in ev] == ["lost"] and c.confidence(3.5) == 0.0
    # Lost: a doubtful new track near it (a bird's 0.6) is not taken; a confident one is.
    c, ev = fly(c, [picture(4.0, track(6, 4.0, (20, 110, 30), (5, 0, 0), conf=0.6, first=4.0))], p)
    assert c.lost and ev == []
    c, ev = fly(c, [picture(4.2, track(8, 4.2, (20, 110, 30), (5, 0, 0), conf=0.9, first=4.2))], p)
    assert not c.lost and c.track_id == 8 and [e.kind for e in ev] == ["reacquired"]


def test_the_velocity_gate_refuses_a_track_flying_the_other_way():
    c = start()
    # On the prediction but 20 m/s off: the gate is 6 + 8 * (0.6 + 1) = 18.8 m/s.
    opposite = track(4, 0.6, (3, 100, 30), (-15, 0, 0), first=0.6)
    c, ev = fly(c, [picture(0.6, opposite)])
    assert c.track_id is None and [e.kind for e in ev] == ["released"]
    same = track(6, 0.8, (4, 100, 30), (5, 0, 0), first=0.8)
    c, ev = fly(c, [picture(0.8, same)])
    assert c.track_id == 6


def test_an_id_swap_is_followed_to_the_object():
    """Two drones pass 4 m apart; the radar exchanges their ids; custody stays with the object."""
    c = start(vel=(5, 0, 0))
    pics = []
    for k in range(1, 11):  # target east at 5 m/s along y = 100; the other comes west along y = 104
        t = 0.2 * k
        target, other = (5 * t, 100, 30), (10 - 5 * t, 104 - 0.0, 30)
        if k < 6:
            pics.append(picture(t, track(1, t, target, (5, 0, 0)), track(2, t, other, (-5, 0, 0), first=0.0)))
        else:  # swapped: id 1 now reports the other drone, id 2 the target
            pics.append(picture(t, track(2, t, target, (5, 0, 0), first=0.0), track(1, t, other, (-5, 0, 0))))
    c, ev = fly(c, [picture(0.0, track(1, 0.0, (0, 100, 30), (5, 0, 0)), track(2, 0.0, (40, 104, 30), (-5, 0, 0)))] + pics)
    assert c.track_id == 2 and c.target_id == 1
    assert [e.kind for e in ev] == ["released", "handover"] and "id swap" in ev[-1].reason
    np.testing.assert_allclose(c.position_enu, (10, 100, 30))


def test_designating_again_changes_nothing_and_another_track_is_a_switch():
    c = start()
    same, ev = designate(track(1, 0.2, (1, 100, 30)), 0.2, "again", c)
    assert same is c and ev is None
    other, ev = designate(track(3, 0.2, (50, 100, 30)), 0.2, "operator", c)
    assert other.target_id == 3 and ev.kind == "switched" and "was target 1" in ev.reason


def test_bad_params_are_refused():
    with pytest.raises(ValueError):
        CustodyParams(gate_sigma=0)
    with pytest.raises(ValueError):
        CustodyParams(vel_lag_s=-1)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(2, 6), st.floats(-300, 300), st.floats(-300, 300), st.floats(-10, 10)),
                min_size=1, max_size=40))
def test_custody_never_names_another_target_and_never_takes_an_object_seen_apart(reports):
    """Whatever the radar reports, the target id stays the designated one, and no track seen 20 m or
    more from the carrying track (and never within 30 m of it: a close pass) ever carries the target."""
    c = start(pos=(0, 0, 30), vel=(0, 0, 0))
    seen_apart_only: set[int] = set()
    for k, (tid, x, y, v) in enumerate(reports, start=1):
        t = 0.2 * k
        pic = picture(t, track(tid, t, (x, y, 30), (v, 0, 0), first=0.0))
        before = c
        c, _ = track_custody(c, pic)
        assert c.target_id == 1
        if c.track_id is not None and c.track_id != before.track_id:
            assert c.track_id not in seen_apart_only
        seen_apart_only |= set(c.apart_ids) - {o.track_id for o in c.beside}


def test_a_dash_at_the_phantoms_acceleration_keeps_the_carrying_track():
    """The target turns about and dashes at 8 m/s^2 from 5 m/s east to 20 m/s west; the radar's
    velocity follows it with a 0.4 s lag (as its tracker does). Custody never lets the track go."""
    c = start(pos=(0, 100, 30), vel=(5, 0, 0))
    x, v, v_radar, dt = 0.0, 5.0, 5.0, 0.2
    pics = []
    for k in range(1, 30):
        v = max(-20.0, v - 8.0 * dt)
        x += v * dt
        v_radar += min(1.0, dt / 0.4) * (v - v_radar)
        pics.append(picture(k * dt, track(1, k * dt, (x, 100, 30), (v_radar, 0, 0))))
    c, ev = fly(c, pics)
    assert ev == [] and c.track_id == 1 and c.velocity_enu[0] < -15.0


def test_custody_held_says_whether_the_tree_still_holds_its_target():
    import py_trees

    from chaser_bt.clock import ManualClock
    from chaser_bt.tree import load_tree_text

    clock = ManualClock(0.0)
    tree = load_tree_text("version: 1\ntrees:\n  T:\n    CustodyHeld: {max_unconfirmed_s: 3.0, min_confidence: 0.5}\n",
                          source="<test>")
    bt = py_trees.trees.BehaviourTree(tree.root)
    bt.setup(link=object(), clock=clock)
    py_trees.blackboard.Blackboard.set("/vehicle/state", None)
    py_trees.blackboard.Blackboard.unset("/target/custody")
    statuses = []
    bt.tick()
    statuses.append(bt.root.status)  # nothing designated
    py_trees.blackboard.Blackboard.set("/target/custody", start(t=0.0))
    for t in (1.0, 2.5, 3.5):  # confidence exp(-t / 4): 0.78, 0.54, 0.42
        clock.set(t)
        bt.tick()
        statuses.append(bt.root.status)
    c = start(t=0.0)
    from dataclasses import replace
    py_trees.blackboard.Blackboard.set("/target/custody", replace(c, lost=True))
    bt.tick()
    statuses.append(bt.root.status)
    S, F = py_trees.common.Status.SUCCESS, py_trees.common.Status.FAILURE
    assert statuses == [F, S, S, F, F]


def test_the_gate_grows_with_the_silence_but_never_past_what_the_target_can_fly():
    """At 5 m/s, unseen for 5 s: it can have turned about at 8 m/s^2 (25 m/s of change in 3.125 s:
    39.1 m) and flown on at 25 m/s for 1.875 s (46.9 m): 85.9 m plus 17.1 m of radar error, 103 m.
    A new track 100 m off the prediction may be it; one 110 m off may not."""
    from chaser_bt.radar.custody import _position_gate

    c = start()
    assert _position_gate(c, track(9, 5.0, (0, 0, 0)), CustodyParams()) == pytest.approx(
        3.5 * math.sqrt(24.0) + 0.5 * 8 * 3.125**2 + 25 * 1.875, abs=1e-9)
    near = fly(c, [picture(5.0, track(9, 5.0, (25 + 100, 100, 30), (5, 0, 0), first=5.0))])[0]
    far = fly(c, [picture(5.0, track(9, 5.0, (25 + 110, 100, 30), (5, 0, 0), first=5.0))])[0]
    assert near.track_id == 9 and far.track_id is None


def _crossing(sight: Sight | None):
    """The target (track 1, 5 m/s east at (0, 100, 30)) drops at t = 0.2. At t = 1.0 two new ids appear
    in its gate: track 8 on the prediction (5, 100, 30), track 9 12 m north of it, (5, 112, 30): by
    the radar alone 8 fits better. The camera, 40 m east of the prediction at the same height,
    looks along its line of sight at ``sight``."""
    c = start()
    c, _ = fly(c, [picture(0.2, track(1, 0.2, (1, 100, 30), (5, 0, 0))), picture(0.6)])
    pic = picture(1.0, track(8, 1.0, (5, 100, 30), (5, 0, 0), first=1.0),
                  track(9, 1.0, (5, 112, 30), (5, 0, 0), first=1.0))
    return track_custody(c, pic, None, sight)


def _looking_at(target) -> Sight:
    camera = np.array([45.0, 100.0, 30.0])
    d = np.asarray(target, float) - camera
    return Sight(1.0, camera, d / np.linalg.norm(d))


def test_without_the_camera_the_best_radar_fit_takes_the_target_over():
    c, ev = _crossing(None)
    assert c.track_id == 8 and ev[-1].kind == "handover" and "line of sight" not in ev[-1].reason


def test_a_track_off_the_cameras_line_of_sight_does_not_take_the_target_over():
    # The camera sees the target at track 9's place, along (-40, 12, 0). Track 8 lies 480 / 41.8 =
    # 11.5 m off that line: with 2 m radar error + 2 m floor per axis (sigma sqrt(8) = 2.83 m) that is
    # 4.1 sigma, beyond 3.5: it waits, and track 9 (on the line) takes over.
    c, ev = _crossing(_looking_at((5.0, 112.0, 30.0)))
    assert c.track_id == 9 and ev[-1].kind == "handover" and "line of sight" in ev[-1].reason
    assert 8 not in c.refused_ids  # not refused for good: the camera may be the one that is wrong
    # Looking at track 8's place instead (due west) puts track 9 12 m off the line (4.2 sigma): track 8.
    c, _ = _crossing(_looking_at((5.0, 100.0, 30.0)))
    assert c.track_id == 8


def test_a_stale_sight_is_not_used():
    stale = _looking_at((5.0, 112.0, 30.0))
    c, _ = _crossing(Sight(0.4, stale.camera_enu, stale.bearing_enu))  # 0.6 s before the reports
    assert c.track_id == 8


def test_a_track_on_the_chasers_own_position_never_takes_the_target_over_nor_confirms_it():
    from chaser_bt.radar.feed import OwnshipFix

    # The target (track 1) flies east at 5 m/s; the chaser 25 m south of it at the same velocity.
    c = start()
    own = lambda t: OwnshipFix(t, np.array([5.0 * t, 75.0, 30.0]), np.array([5.0, 0.0, 0.0]))
    seen = lambda t, *trs: RadarPicture(t, {tr.track_id: tr for tr in trs}, None, t, ownship=own(t))
    # The target's track drops; 2 s later a new, uncorrelated track appears on the chaser (a duplicate
    # of its own): inside the target's grown gate (25 m off the prediction) but where our telemetry is.
    c, ev = fly(c, [seen(1.0, track(1, 1.0, (5, 100, 30), (5, 0, 0))), seen(1.2),
                    seen(3.0, track(5, 3.0, (15.5, 75.5, 30), (5, 0, 0), first=2.9))])
    assert [e.kind for e in ev] == ["released"] and c.track_id is None
    # Without our telemetry the same track would have been taken (the rule is what refuses it).
    c2, ev2 = fly(start(), [picture(1.0, track(1, 1.0, (5, 100, 30), (5, 0, 0))), picture(1.2),
                            picture(3.0, track(5, 3.0, (15.5, 75.5, 30), (5, 0, 0), first=2.9))])
    assert c2.track_id == 5 and ev2[-1].kind == "handover"
    # The carrying id swapped onto the chaser: two reports there release it, none confirms it.
    c3, ev3 = fly(start(), [seen(0.2, track(1, 0.2, (1, 100, 30), (5, 0, 0))), seen(0.4, track(1, 0.4, (2, 75, 30), (5, 0, 0))),
                            seen(0.6, track(1, 0.6, (3, 75, 30), (5, 0, 0)))])
    assert c3.t_confirmed == pytest.approx(0.2) and [e.kind for e in ev3] == ["released"]
    assert "own position" in ev3[0].reason and 1 in c3.apart_ids


def test_the_ownship_test_needs_both_position_and_velocity():
    from chaser_bt.radar.custody import is_ownship
    from chaser_bt.radar.feed import OwnshipFix

    p = CustodyParams()  # 3 sigma of a 2 m report error plus a 2 m floor: 8.5 m; 3 m/s
    own = OwnshipFix(0.0, np.zeros(3), np.array([4.0, 0.0, 0.0]))
    assert is_ownship(track(1, 0.5, (2.0 + 8.0, 0, 0), (4, 0, 0)), own, p)  # 8 m off where it is at 0.5 s
    assert not is_ownship(track(1, 0.5, (2.0 + 9.0, 0, 0), (4, 0, 0)), own, p)
    assert not is_ownship(track(1, 0.5, (2.0, 0, 0), (0, 0, 0)), own, p)  # same place, hovering: not us
    assert is_ownship(track(1, 0.5, (2.0, 0, 0), None), own, p)
    assert not is_ownship(track(1, 0.5, (2.0, 0, 0), (4, 0, 0)), None, p)


def test_a_new_id_born_in_a_close_pass_waits_until_it_fits_the_target_better_than_the_other_drone():
    # The target flies east at 2 m/s along y = 100; another drone crosses it southwards at 6 m/s, 5 m
    # away at t = 1. The target's track drops in the pass; at 1.4 s a new id (9) appears on the other
    # drone: inside the target's gate (a few metres off, 6.3 m/s off a gate of 17), but it fits the
    # drone beside it exactly, so it waits. At 1.6 s the target's own new id (10) fits the target.
    target = lambda t: (2.0 * t, 100.0, 30.0)
    other = lambda t: (2.0, 111.0 - 6.0 * t, 30.0)
    pics = [picture(0.2 * k, track(1, 0.2 * k, target(0.2 * k), (2, 0, 0)), track(2, 0.2 * k, other(0.2 * k), (0, -6, 0)))
            for k in range(0, 6)]
    pics += [picture(1.2), picture(1.4, track(9, 1.4, other(1.4), (0, -6, 0), first=1.4)),
             picture(1.6, track(9, 1.6, other(1.6), (0, -6, 0), first=1.4), track(10, 1.6, target(1.6), (2, 0, 0), first=1.6))]
    c, ev = fly(start(0.0, target(0.0), (2, 0, 0)), pics)
    assert c.track_ids == (1, 10) and [e.kind for e in ev] == ["released", "handover"]
    assert "within 30 m" in ev[0].reason
    # Without the drone beside it (nothing near the target when it dropped), id 9 would have been taken.
    alone = [picture(0.2 * k, track(1, 0.2 * k, target(0.2 * k), (2, 0, 0))) for k in range(0, 6)]
    c2, _ = fly(start(0.0, target(0.0), (2, 0, 0)), alone + pics[6:8])
    assert c2.track_id == 9


def test_a_duplicate_of_the_targets_own_track_takes_it_over_when_the_carrier_drops():
    # The radar reports the target twice (id 1 and a duplicate, id 3, 4 m off at its velocity); id 1
    # ends. The duplicate is not another object beside the target, so nothing waits: it carries on.
    target = lambda t: (5.0 * t, 100.0, 30.0)
    dup = lambda t: (5.0 * t + 4.0, 100.0, 30.0)
    pics = [picture(0.2 * k, track(1, 0.2 * k, target(0.2 * k), (5, 0, 0)), track(3, 0.2 * k, dup(0.2 * k), (5, 0, 0)))
            for k in range(0, 6)]
    pics += [picture(1.2, track(3, 1.2, dup(1.2), (5, 0, 0)))]
    c, ev = fly(start(0.0, target(0.0), (5, 0, 0)), pics)
    assert [e.kind for e in ev] == ["released", "handover"] and c.track_ids == (1, 3)
    assert "within" not in ev[0].reason  # not a crowd


def test_one_report_outside_the_gate_is_one_miss_however_many_ticks_see_it():
    """The tree ticks faster than the radar reports, so a picture can hold the same report twice; one
    odd report (a gust on the tracker's velocity) is one miss, and the next good one keeps the track."""
    c = start(pos=(0, 100, 30), vel=(5, 0, 0))
    odd = track(1, 0.2, (1, 100, 30), (5, 3.8, 0))  # 3.8 m/s off: the carrier's gate is 2 + 8 * 0.2 = 3.6
    c, ev = fly(c, [picture(0.2, odd), picture(0.3, odd)])
    assert ev == [] and c.track_id == 1 and c.misses == 1
    c, ev = fly(c, [picture(0.4, track(1, 0.4, (2, 100, 30), (5, 1.0, 0)))])
    assert ev == [] and c.track_id == 1 and c.misses == 0 and c.t_confirmed == pytest.approx(0.4)
    # Two reports in a row outside the gate still release it.
    c, ev = fly(c, [picture(0.6, track(1, 0.6, (3, 100, 30), (5, 6.0, 0))),
                    picture(0.8, track(1, 0.8, (4, 100, 30), (5, 8.0, 0)))])
    assert [e.kind for e in ev] == ["released"]



def _companion_swap(hidden_at_swap: bool, until_s: float = 20.0, params: CustodyParams | None = None):
    """The target (track 1) flies east at 3 m/s along y = 100; a bird keeps 16 m north of it (track 2)
    at its velocity, so their paths never part. At t = 2.0 the radar swaps the ids: track 1 reports
    the bird, its velocity turning over as the bird turns north: (3, 3, 0) at 2.2 (16 m and 3 m/s
    off: inside the carrier's 17.3 m and 2 + 8 * 0.2 = 3.6 m/s gate), (3, 7, 0) and (3, 11, 0) after
    (misses); track 2 reports the target from then on (``hidden_at_swap``: not in the 2.2 s scan)."""
    target = lambda t: (3.0 * t, 100.0, 30.0)
    bird = lambda t: (3.0 * t, 116.0, 30.0)
    turning = {11: (3.0, 3.0, 0.0), 12: (3.0, 7.0, 0.0)}
    pics = []
    for k in range(0, int(round(until_s / 0.2)) + 1):
        t = 0.2 * k
        if k <= 10:
            pics.append(picture(t, track(1, t, target(t), (3, 0, 0)), track(2, t, bird(t), (3, 0, 0))))
        else:
            swapped = track(1, t, bird(t), turning.get(k, (3, 11, 0)))
            pics.append(picture(t, swapped) if hidden_at_swap and k == 11 else
                        picture(t, track(2, t, target(t), (3, 0, 0)), swapped))
    return fly(start(0.0, target(0.0), (3, 0, 0)), pics, params)


def test_an_id_swap_with_a_bird_keeping_beside_the_target_is_seen_at_once_as_their_offset_reversing():
    # At 2.2 track 1 is 16 m north of track 2, where at 2.0 it was 16 m south: reversed (0 m off the
    # reversal, 32 m off the same offset: 8 sigma of the four reports' 2 m per axis).
    c, ev = _companion_swap(hidden_at_swap=False)
    assert [e.kind for e in ev] == ["handover"] and "offset from each other reversed" in ev[0].reason
    assert ev[0].t == pytest.approx(2.2) and c.track_id == 2 and c.track_ids == (1, 2) and 1 in c.apart_ids
    np.testing.assert_allclose(c.position_enu, (60, 100, 30))


def test_a_swap_seen_late_goes_back_to_the_report_before_it():
    # Track 2 is missing from the 2.2 s scan, so the reversal is not seen and track 1 confirms the bird.
    # The second miss (2.6 s) releases it; custody goes back to its report 2 s before the first miss
    # (2.4 - 2.0 = 0.4 s), when track 2 was the bird: track 2 now fits the target's path (0 m off)
    # better than the bird's (16 m off a 36.5 m gate: 0.44 > 0.2) and takes it over.
    c, ev = _companion_swap(hidden_at_swap=True)
    assert [e.kind for e in ev] == ["released", "handover"] and "back to its report at 0.4 s" in ev[0].reason
    assert "id swap" in ev[1].reason and c.track_id == 2 and not c.lost
    np.testing.assert_allclose(c.position_enu, (60, 100, 30))
    # Without the look-back the release keeps the bird's report of 2.2 s as the target's last.
    c, ev = _companion_swap(hidden_at_swap=True, until_s=2.6, params=CustodyParams(swap_lookback_s=0.0))
    assert ev[0].kind == "released" and "back to" not in ev[0].reason


def test_a_track_far_above_the_prediction_is_not_the_target_however_long_the_coast():
    """A hovering target drops at t = 0. After 10 s the position gate is 3.5 * sqrt(24) = 17.1 m of
    radar error plus 0.5 * 8 * 2.5^2 + 20 * 7.5 = 175 m of manoeuvre: 192 m. In height it is
    3.5 * sqrt(8) = 9.9 m plus 0.5 * 4 * 1.5^2 + 6 * 8.5 = 55.5 m of climb: 65.4 m. A track 70 m
    straight above the prediction is refused; one 60 m above may be the target."""
    from chaser_bt.radar.custody import _position_gate, _vertical_gate

    c = start(vel=(0, 0, 0))
    report = track(9, 10.0, (0, 100, 100), (0, 0, 0), first=10.0)
    assert _position_gate(c, report, CustodyParams()) == pytest.approx(3.5 * math.sqrt(24.0) + 25 + 150, abs=1e-9)
    assert _vertical_gate(c, report, CustodyParams()) == pytest.approx(
        3.5 * math.sqrt(8.0) + 0.5 * 4 * 1.5**2 + 6 * 8.5, abs=1e-9)
    high, _ = fly(c, [picture(10.0, report)])
    assert high.track_id is None and 9 in high.refused_ids
    lower = fly(c, [picture(10.0, track(9, 10.0, (0, 100, 90), (0, 0, 0), first=10.0))])[0]
    assert lower.track_id == 9


def _beside_pass(sight: Sight | None):
    """The target (track 1, 2 m/s east along y = 100) flies with a companion (track 2) 16 m north, at
    its velocity (beyond the 15 m of a duplicate). Track 1 ends after 1.0 s; at 1.2 s a new id (9)
    appears 7 m north of the prediction (2.4, 100): it fits the target (7 m off) better than the
    companion's past (9 m off) by only 2 / 17.3 = 0.12 of a gate, under the crowd margin of 0.2, so
    by the radar alone it waits."""
    target = lambda t: (2.0 * t, 100.0, 30.0)
    other = lambda t: (2.0 * t, 116.0, 30.0)
    pics = [picture(0.2 * k, track(1, 0.2 * k, target(0.2 * k), (2, 0, 0)), track(2, 0.2 * k, other(0.2 * k), (2, 0, 0)))
            for k in range(0, 6)]
    pics.append(picture(1.2, track(2, 1.2, other(1.2), (2, 0, 0)), track(9, 1.2, (2.4, 107, 30), (2, 0, 0), first=1.2)))
    c = start(0.0, target(0.0), (2, 0, 0))
    for pic in pics:
        c, ev = track_custody(c, pic, None, sight)
    return c


def test_in_a_crowd_the_one_track_on_the_cameras_line_of_sight_takes_the_target_over():
    assert _beside_pass(None).track_id is None
    # The camera, 100 m west, sees the target along +x: track 9 lies 7 m off that line (2.5 sigma of
    # sqrt(4 + 4) = 2.83 m), the companion 16 m off (5.7 sigma): only track 9 is on it.
    camera = np.array([-97.6, 100.0, 30.0])
    assert _beside_pass(Sight(1.2, camera, np.array([1.0, 0.0, 0.0]))).track_id == 9
    # Looking 8 m north (track 9 1 m off the line, the companion 8 m: both within 3.5 sigma), the
    # camera cannot name one: it waits.
    d = np.array([100.0, 8.0, 0.0])
    assert _beside_pass(Sight(1.2, camera, d / np.linalg.norm(d))).track_id is None


def test_a_lost_target_is_reacquired_on_an_old_track_only_where_the_camera_sees_it():
    p = CustodyParams(max_coast_s=1.0)
    c = start(vel=(0, 0, 0))
    c, ev = fly(c, [picture(1.5)], p)
    assert c.lost
    # Track 4 has been in the sky since before the loss, confident, 20 m from where the target was lost.
    old = track(4, 2.0, (20, 100, 30), (0, 0, 0), conf=0.9, first=-5.0)
    assert fly(c, [picture(2.0, old)], p)[0].lost
    camera = np.array([20.0, 0.0, 30.0])  # 100 m south of it, looking north at it
    seen, ev = track_custody(c, picture(2.0, old), p, Sight(2.0, camera, np.array([0.0, 1.0, 0.0])))
    assert not seen.lost and seen.track_id == 4 and "line of sight" in ev[0].reason


def _crossing_swap(turning: list[float], end_mps: float):
    """Two drones cross 10 m apart at 10 m/s, the target (track 1) east along y = 100, the other
    (track 2) west along y = 110; at 2.0 s, side by side, the radar swaps their ids. Track 2 then
    reports the target with the velocities ``turning`` (east, m/s; then ``end_mps``): its tracker
    turning over from the other drone's -10 m/s."""
    target = lambda t: (10.0 * t - 10.0, 100.0, 30.0)
    other = lambda t: (30.0 - 10.0 * t, 110.0, 30.0)
    pics = []
    for k in range(0, 26):
        t = 0.2 * k
        if k <= 9:
            pics.append(picture(t, track(1, t, target(t), (10, 0, 0)), track(2, t, other(t), (-10, 0, 0))))
        else:
            v = turning[k - 10] if k - 10 < len(turning) else end_mps
            pics.append(picture(t, track(2, t, target(t), (v, 0, 0)), track(1, t, other(t), (-v, 0, 0))))
    c, ev = fly(start(0.0, target(0.0), (10, 0, 0)), pics)
    return c, ev, target(5.0)


def test_after_a_swap_the_new_carriers_lagging_velocity_is_not_the_targets():
    # -4, 0, 3 m/s... judged on velocity (14 and 10 m/s off the target's 10) track 2 would be released
    # at once; for vel_lag_s (1 s) custody judges its position only and keeps the target's velocity.
    c, ev, at_end = _crossing_swap([-4.0, 0.0, 3.0, 5.5, 7.0, 8.0, 9.0, 9.5], 10.0)
    assert [e.kind for e in ev] == ["handover"] and ev[0].t == pytest.approx(2.0)
    assert c.track_id == 2 and c.misses == 0
    np.testing.assert_allclose(c.position_enu, at_end)
    # The target speeds up meanwhile: the first velocity judged after the second (14 m/s at 3.2 s)
    # is 4 m/s off the kept 10, outside 2 + 8 * 0.2 but inside the 2 + 8 * 1.4 its 1.4 s unmeasured allow.
    c, ev, _ = _crossing_swap([-4.0, 0.0, 3.0, 6.0, 9.0, 12.0, 14.0, 15.5], 16.0)
    assert [e.kind for e in ev] == ["handover"] and c.track_id == 2 and c.velocity_enu[0] == 16.0
