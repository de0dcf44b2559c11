"""The fuzz suite on a flying mission: the patrol with a hostile peer on the vehicle's link (one
case of each kind in ``sitl/bench/hostile.py``; ``benchmarks/bench_fuzz.py`` runs many more)."""

from __future__ import annotations

import pytest

from sitl.bench.hostile import KINDS, SAFE_END, run_case


@pytest.mark.parametrize("seed", range(1, len(KINDS) + 1), ids=lambda s: KINDS[s % len(KINDS)])
def test_no_exception_no_set_point_outside_the_envelope_and_the_aircraft_left_safe(seed):
    case = run_case(seed)
    assert case["injected"] > 0
    assert not case["raised"], case["message"]
    assert case["unsafe_commands"] == []
    assert case["final_state"] in SAFE_END, case
    if case["kind"] in ("bytes", "home"):  # garbage between frames and one absurd home change nothing
        assert case["mission_outcome"] == "completed", case["message"]
    if case["kind"] == "home":
        assert case["dropped"] == {"home_range": 1}
    if case["kind"] in ("clone", "fields"):  # a second sender under the vehicle's ids: not believed, never "crashed"
        assert case["mission_outcome"] == "error", case

