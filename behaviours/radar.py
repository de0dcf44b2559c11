"""Radar behaviours (paper section 2.2.1, state 1 -> 2 and 3): a validated intruder track, and its cue.

Both read the radar through a :class:`chaser_bt.radar.feed.RadarFeed` handed to ``setup`` as
``radar=`` (beside ``link`` and ``clock``); the feed filters our own drone out (the track
correlator, section 3.3), so neither behaviour can ever validate or cue on the ownship.
"""

from __future__ import annotations

from typing import Any

import py_trees

from behaviours.base import VehicleBehaviour, optional_input, state_port
from chaser_bt.cue import TargetCue
from chaser_bt.radar.feed import RadarFeed, RadarPicture, select_intruder
from chaser_bt.tree import NodeKind, input_port, output_port, register_behaviour

Status = py_trees.common.Status

VALIDATED_TRACK_KEY = "/radar/validated_track"
OPERATOR_CONFIRMATION_KEY = "/radar/operator_confirmed_track"
CUE_KEY = "/target/cue"


class _RadarBehaviour(VehicleBehaviour):
    """Takes the radar feed from setup and updates it with the ownship's state once per tick."""

    REQUIRES_RESOURCES = ("radar",)  # checked before the flight (chaser_bt.mission.resources)

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        if not isinstance(kwargs.get("radar"), RadarFeed):
            raise KeyError(f"{self.name}: setup() needs radar=RadarFeed(...) (the mission runner passes it)")
        self.radar: RadarFeed = kwargs["radar"]

    def picture(self) -> RadarPicture:
        s = self.state
        return self.radar.update(self._now(), s.position_enu, s.velocity_enu)


@register_behaviour
class RadarTrackValidated(_RadarBehaviour):
    """SUCCESS when a radar track that is not our own drone is validated, by the operator (a track id
    written to ``operator_confirmation``) or by the radar's confidence held for ``min_track_age_s``;
    writes its id to ``validated_track``. FAILURE otherwise."""

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS = {
        "min_confidence": input_port(float, "Radar track confidence that validates (0..1)", default=0.8, minimum=0, maximum=1),
        "min_track_age_s": input_port(float, "The track must have lived this long (s)", default=1.0, minimum=0),
        "operator_confirmation": input_port(int, "Track id the operator confirmed", required=False,
                                            default_key=OPERATOR_CONFIRMATION_KEY),
        "state": state_port(),
    }
    OUTPUT_PORTS = {"validated_track": output_port(int, "Id of the validated track", default_key=VALIDATED_TRACK_KEY)}

    def update(self) -> Status:
        pic = self.picture()
        confirmed = optional_input(self, "operator_confirmation")
        min_conf, min_age = self.get_input("min_confidence"), self.get_input("min_track_age_s")
        chosen = None
        for tr in pic.intruders:
            if tr.track_id == confirmed:
                chosen, why = tr, "operator confirmed"
                break
        else:
            for tr in pic.intruders:
                if tr.confidence >= min_conf and pic.t - tr.first_seen_t >= min_age:
                    chosen, why = tr, f"confidence {tr.confidence:.2f}"
                    break
        if chosen is None:
            self.feedback_message = f"{len(pic.intruders)} unvalidated track(s), ownship {sorted(pic.ownship_ids)}"
            return Status.FAILURE
        self._set_output("validated_track", chosen.track_id)
        self.feedback_message = f"track {chosen.track_id} validated ({why})"
        return Status.SUCCESS


@register_behaviour
class RadarCue(_RadarBehaviour):
    """Write the intruder's radar cue (ENU position, covariance, velocity, time) to ``cue``.

    Follows the validated track, or after a drop the nearest other track to the last cue. SUCCESS
    with a cue no older than ``max_age_s``; FAILURE when the radar has none (cue lost: search).
    """

    NODE_KIND = NodeKind.ACTION
    INPUT_PORTS = {
        "track": input_port(int, "Preferred track id (the validated one)", required=False,
                            default_key=VALIDATED_TRACK_KEY),
        "max_age_s": input_port(float, "A cue older than this is lost (s)", default=2.0, minimum=0),
        "state": state_port(),
    }
    OUTPUT_PORTS = {"cue": output_port(TargetCue, "The intruder cue", default_key=CUE_KEY)}

    def initialise(self) -> None:
        self._last: TargetCue | None = None

    def update(self) -> Status:
        pic = self.picture()
        last = self._last.position_enu if self._last is not None else None
        tr = select_intruder(pic, optional_input(self, "track"), last)
        if tr is None or pic.t - tr.t > self.get_input("max_age_s"):
            self.feedback_message = "no intruder track"
            return Status.FAILURE
        self._last = tr.to_cue()
        self._set_output("cue", self._last)
        self.feedback_message = f"track {tr.track_id} at {tr.position_enu.round(1).tolist()}, age {pic.t - tr.t:.1f} s"
        return Status.SUCCESS
