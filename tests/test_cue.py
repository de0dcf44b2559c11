"""Target cues and estimates validate what they carry."""

import numpy as np
import pytest

from chaser_bt.cue import TargetCue, TargetEstimate


def test_cue_age_is_measured_from_its_time():
    cue = TargetCue(t=10.0, position_enu=[1, 2, 3])
    assert cue.age(12.5) == pytest.approx(2.5)
    assert cue.position_enu.dtype == float and cue.covariance_enu.shape == (3, 3)


@pytest.mark.parametrize("position", [[1, 2], [1, 2, np.nan], "abc"])
def test_cue_rejects_a_bad_position(position):
    with pytest.raises(ValueError, match="position"):
        TargetCue(t=0.0, position_enu=position)


def test_estimate_requires_a_unit_bearing_and_a_confidence_in_range():
    TargetEstimate(t=0.0, position_enu=[0, 40, 0], bearing_enu=[0, 1, 0], range_m=40.0, confidence=0.8)
    with pytest.raises(ValueError, match="bearing"):
        TargetEstimate(t=0.0, position_enu=[0, 40, 0], bearing_enu=[0, 2, 0])
    with pytest.raises(ValueError, match="confidence"):
        TargetEstimate(t=0.0, position_enu=[0, 40, 0], confidence=1.5)


def test_cue_position_is_carried_on_its_velocity_when_it_has_one():
    moving = TargetCue(t=10.0, position_enu=np.array([1.0, 2.0, 3.0]), velocity_enu=np.array([2.0, -1.0, 0.5]))
    assert moving.position_at(12.0) == pytest.approx([5.0, 0.0, 4.0])
    assert moving.position_at(10.0) == pytest.approx([1.0, 2.0, 3.0])
    still = TargetCue(t=10.0, position_enu=np.array([1.0, 2.0, 3.0]))
    assert still.position_at(99.0) == pytest.approx([1.0, 2.0, 3.0])


def test_a_coasted_cue_moves_on_its_velocity_and_widens_by_the_manoeuvre_allowance():
    cue = TargetCue(10.0, np.array([0.0, 100.0, 30.0]), np.eye(3) * 4.0, np.array([5.0, 0.0, 0.0]), "radar", 3)
    later = cue.coasted(12.0, 6.0)  # 2 s on: 10 m east; (0.5 * 6 * 4)^2 = 144 m^2 more on each axis
    np.testing.assert_allclose(later.position_enu, [10.0, 100.0, 30.0])
    np.testing.assert_allclose(np.diag(later.covariance_enu), [148.0, 148.0, 148.0])
    assert later.t == 12.0 and later.track_id == 3 and later.age(12.0) == 0.0
    assert cue.coasted(9.0, 6.0).covariance_enu[0, 0] == 4.0  # never backwards
