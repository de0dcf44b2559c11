"""Radar track correlators (paper section 3.3): the paper's Algorithm 1 and our gated method.

Both implement :class:`TrackCorrelator`; :func:`make_correlator` builds one by name
(``"alg1"`` or ``"gated"``) so a mission file or benchmark can choose.
"""

from __future__ import annotations

from typing import Any

from chaser_bt.radar.correlator.base import Association, CorrelationWindow, TrackCorrelator, TrackPoints
from chaser_bt.radar.correlator.gated import GatedCorrelator
from chaser_bt.radar.correlator.paper import Algorithm1Correlator

__all__ = ["Association", "CorrelationWindow", "TrackCorrelator", "TrackPoints", "Algorithm1Correlator",
           "GatedCorrelator", "CORRELATORS", "make_correlator"]

CORRELATORS: dict[str, type[TrackCorrelator]] = {
    Algorithm1Correlator.name: Algorithm1Correlator,
    GatedCorrelator.name: GatedCorrelator,
}


def make_correlator(name: str, **params: Any) -> TrackCorrelator:
    """The correlator called ``name`` with keyword ``params``; ValueError names the choices."""
    try:
        cls = CORRELATORS[name]
    except KeyError:
        raise ValueError(f"unknown correlator {name!r}; choose one of {', '.join(sorted(CORRELATORS))}") from None
    return cls(**params)
