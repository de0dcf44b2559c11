"""Algorithm 1 on hand-built track sets: each failure mode with the answer worked out by hand.

Scans are 4 Hz (times k/4 are exact in binary floating point, so window edges are exact);
the ownship sits still at the origin and the other drone 50 m east, far outside epsilon = 10 m.
"""

from __future__ import annotations

import numpy as np
import pytest

from chaser_bt.radar.correlator import Algorithm1Correlator, GatedCorrelator, TrackPoints, make_correlator

OWN = np.zeros(3)
OTHER = np.array([50.0, 0.0, 0.0])


def run(tracks_at, t_end: float, correlator=None) -> dict[float, tuple[int | None, int | None]]:
    """Feed scans at k/4 s; tracks_at(t) -> {id: position}. Returns t -> (reported id, stored A)."""
    c = correlator or Algorithm1Correlator(epsilon_m=10.0)
    out = {}
    for k in range(int(t_end * 4) + 1):
        t = k / 4
        c.add_ownship(t, OWN, np.zeros(3))
        tr = tracks_at(t)
        if tr:
            ids = list(tr)
            c.add_tracks(TrackPoints.build(t, ids, [tr[i] for i in ids], np.zeros((len(ids), 3)), 1.0))
        a = c.associate(t)
        out[t] = (a.associated_id, c.associated_id)
    return out


def test_associates_the_track_on_the_gps_at_the_first_scan():
    out = run(lambda t: {7: OTHER, 3: OWN}, 2.0)
    assert out[0.0] == (3, 3)
    assert all(v == (3, 3) for v in out.values())


def test_no_detection_means_no_association():
    out = run(lambda t: {7: OTHER}, 3.0)
    assert all(v == (None, None) for v in out.values())


def test_track_drop_new_id_taken_when_two_windows_agree():
    # Track 1 ends at 10.0 and the ownship returns as track 2 at 10.5. Track 1 is active until
    # 11.0 (reported within 1 s). From 11.0 m0 = 2 but m1, m2 have no winner among active tracks,
    # so A stays 1 (reported as none: it is not active). At 12.5 the window (8.5, 10.5] holds
    # track 2's first report, m1 = 2 = m0, and A becomes 2.
    out = run(lambda t: {1: OWN} if t <= 10.0 else ({2: OWN} if t >= 10.5 else {}), 15.0)
    assert all(out[t] == (1, 1) for t in out if t < 11.0)
    assert all(out[t] == (None, 1) for t in out if 11.0 <= t < 12.5)
    assert all(out[t] == (2, 2) for t in out if t >= 12.5)


def test_track_swap_recovered_when_older_window_turns():
    # Ids exchange after 20.0: track 2 now follows the ownship. N0 favours 2 from 21.25 (5 reports
    # after the swap against 3 before; at 21.0 it is 4:4, a tie kept by A). m1 over (T-4, T-2] turns
    # to 2 first at 23.25 (5:3; at 23.0 it is 4:4), so A stays 1 -- wrongly -- until 23.25.
    def tracks(t):
        return {1: OWN, 2: OTHER} if t <= 20.0 else {1: OTHER, 2: OWN}

    out = run(tracks, 26.0)
    assert all(out[t] == (1, 1) for t in out if t < 23.25)
    assert all(out[t] == (2, 2) for t in out if t >= 23.25)


def test_duplicate_track_does_not_steal_the_association():
    # A parallel track 3 on the ownship from 5.0 to 9.0: equal counts, ties go to the current A.
    out = run(lambda t: {1: OWN, 3: OWN + 0.5} if 5.0 <= t <= 9.0 else {1: OWN}, 12.0)
    assert all(v == (1, 1) for v in out.values())


def test_duplicates_from_the_start_take_the_lowest_id_and_leave_the_other_unassociated():
    c = Algorithm1Correlator(epsilon_m=10.0)
    out = run(lambda t: {9: OWN, 4: OWN + 1.0, 6: OTHER}, 1.0, c)
    assert out[1.0] == (4, 4)
    a = c.associate(1.0)
    assert a.unassociated_ids == (6, 9)  # the paper filters on the associated id alone


def test_epsilon_is_a_strict_threshold():
    c = Algorithm1Correlator(epsilon_m=10.0)
    out = run(lambda t: {1: np.array([10.0, 0.0, 0.0]), 2: np.array([0.0, 9.99, 0.0])}, 1.0, c)
    assert out[1.0] == (2, 2)


def test_gated_takes_a_new_id_after_a_drop_within_two_scans():
    out = run(lambda t: {1: OWN} if t <= 10.0 else ({2: OWN} if t >= 10.5 else {}), 13.0, GatedCorrelator())
    assert out[10.5] == (1, 1) and out[10.75] == (2, 2)


def test_gated_recovers_after_a_swap_on_velocity_and_position():
    def tracks(t):
        return {1: OWN, 2: OTHER} if t <= 20.0 else {1: OTHER, 2: OWN}

    out = run(tracks, 24.0, GatedCorrelator())
    # Rejecting track 1 needs two inconsistent reports (20.25, 20.5). Track 2 was seen 50 m from our
    # track: another object, reclaimed only when every report of the last 2 s is on our GPS: those
    # from 20.25 on, so at 22.25.
    assert out[20.25][0] != 2 and out[20.5] == (None, None)
    assert all(out[t][0] is None for t in out if 20.5 <= t < 22.25)
    assert all(out[t] == (2, 2) for t in out if t >= 22.25)


def test_gated_files_duplicates_under_the_ownship():
    c = GatedCorrelator()
    run(lambda t: {1: OWN, 3: OWN + 0.5, 6: OTHER}, 2.0, c)
    a = c.associate(2.0)
    assert a.associated_id == 1 and a.ownship_ids == {1, 3} and a.unassociated_ids == (6,)


def test_gated_never_takes_a_drone_seen_beside_us_for_us_when_our_track_drops():
    """A drone 13 m away flies with us (sigma 8 m: inside the 32 m gate). While our track (1) is
    reported, track 2 is seen beside it: another object. Our track drops at t = 3 s; track 2 stays in
    the picture, unassociated, until our new track (3) appears at t = 4 s and is taken."""
    beside = np.array([13.0, 0.0, 0.0])
    c, out = GatedCorrelator(), {}
    for k in range(0, 25):
        t = k / 4
        c.add_ownship(t, OWN, np.zeros(3))
        tracks = {1: OWN + 0.5, 2: beside} if t < 3.0 else ({2: beside} if t < 4.0 else {2: beside, 3: OWN - 0.5})
        ids = list(tracks)
        c.add_tracks(TrackPoints.build(t, ids, [tracks[i] for i in ids], np.zeros((len(ids), 3)), 8.0))
        out[t] = c.associate(t)
    assert out[2.75].associated_id == 1 and out[2.75].unassociated_ids == (2,)
    assert all(2 not in out[t].ownship_ids and 2 in out[t].unassociated_ids for t in out if t >= 0.5)
    assert out[4.25].associated_id == 3 and out[6.0].ownship_ids == {3}


def _close_pass(gap: bool) -> dict:
    """Another drone (track 2) is seen 15 m beside our track (1) until t = 3 s, when our track drops
    for good. Track 2 then passes over our GPS: 2 m off for 1 s (t = 4 to 5, four reports whose mean
    offset is under the 5 m floor), then 12 m off again. With ``gap``, the radar does not report
    track 2 for 1.5 s (t = 3 to 4.5), longer than a track stays active. A bird (track 3) is reported
    200 m away throughout. Returns t -> Association."""
    c, out = GatedCorrelator(), {}
    for k in range(0, 33):
        t = k / 4
        c.add_ownship(t, OWN, np.zeros(3))
        offset = 15.0 if t < 3.0 else (2.0 if 4.0 <= t < 5.0 else 12.0)
        tracks = {2: np.array([offset, 0.0, 0.0]), 3: np.array([200.0, 0.0, 0.0])}
        if t < 3.0:
            tracks[1] = OWN + 0.5
        if gap and 3.0 <= t < 4.5:
            del tracks[2]
        ids = list(tracks)
        c.add_tracks(TrackPoints.build(t, ids, [tracks[i] for i in ids], np.zeros((len(ids), 3)), 8.0))
        out[t] = c.associate(t)
    return out


@pytest.mark.parametrize("gap", [False, True])
def test_gated_never_takes_a_drone_seen_beside_us_for_us_in_a_close_pass(gap):
    """One second on our GPS is not two: track 2 is never the ownship, and stays in the picture
    whenever it is reported (a report gap does not make it a stranger)."""
    out = _close_pass(gap)
    assert out[2.75].associated_id == 1
    assert all(out[t].associated_id != 2 and 2 not in out[t].ownship_ids for t in out)
    assert all(2 in out[t].unassociated_ids for t in out if t >= 4.5)


def test_gated_reclaims_a_track_seen_beside_us_after_two_seconds_on_our_gps():
    """The same drone stays 2 m off our GPS from t = 4 s on (sigma 2 m: the gate is 8 m, so its
    reports 15 m off are not on our GPS): every report of the last 2 s on it from t = 6.0 (4.0 ..
    6.0), so ours from then (an id swap with our own track), not before."""
    c, out = GatedCorrelator(), {}
    for k in range(0, 33):
        t = k / 4
        c.add_ownship(t, OWN, np.zeros(3))
        tracks = {2: np.array([15.0 if t < 4.0 else 2.0, 0.0, 0.0])}
        if t < 3.0:
            tracks[1] = OWN + 0.5
        ids = list(tracks)
        c.add_tracks(TrackPoints.build(t, ids, [tracks[i] for i in ids], np.zeros((len(ids), 3)), 2.0))
        out[t] = c.associate(t)
    assert all(out[t].associated_id is None for t in out if 3.75 <= t < 6.0)  # ours is held to 3.5
    assert all(out[t].associated_id == 2 for t in out if t >= 6.0)


def test_make_correlator_by_name():
    assert isinstance(make_correlator("alg1", epsilon_m=5.0), Algorithm1Correlator)
    assert isinstance(make_correlator("gated"), GatedCorrelator)
    with pytest.raises(ValueError, match="alg1, gated"):
        make_correlator("nope")


def _follow_scans(c: GatedCorrelator) -> dict:
    """A drone 24 m away, reported alone until t = 2 s, then with our own track (1 m off the GPS);
    sigma 8 m (the gate is 32 m wide). Returns t -> Association."""
    follow = np.array([24.0, 0.0, 0.0])
    out = {}
    for k in range(0, 25):
        t = k / 4
        c.add_ownship(t, OWN, np.zeros(3))
        tracks = {2: follow} if t < 2.0 else {1: OWN + 1.0, 2: follow}
        ids = list(tracks)
        c.add_tracks(TrackPoints.build(t, ids, [tracks[i] for i in ids], np.zeros((len(ids), 3)), 8.0))
        out[t] = c.associate(t)
    return out


def test_gated_gives_a_drone_we_follow_inside_a_wide_gate_back_to_the_picture():
    """At long range the gate is wide: a drone 24 m away at our velocity passes it. Held on that
    drone's track (ours was not reported yet), the correlator switches to our own track as soon as
    it is confirmed, its residual being far lower (1.7 / 32 against 24 / 32); and the other drone is
    not filed under the ownship (it is no duplicate: 24 m > ambiguity_m)."""
    out = _follow_scans(GatedCorrelator())
    assert out[1.75].associated_id == 2  # only the other drone in the gate: taken, for now
    # Our track is confirmed after two reports (2.0, 2.25): the switch is immediate.
    assert out[2.25].associated_id == 1 and out[2.25].ownship_ids == {1} and out[2.25].unassociated_ids == (2,)
    assert all(out[t].associated_id == 1 and out[t].ownship_ids == {1} for t in out if t >= 2.25)
    # With a margin larger than the difference in residuals, the held track stays.
    assert _follow_scans(GatedCorrelator(switch_margin=10.0))[6.0].associated_id == 2
