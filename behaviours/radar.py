"""Radar behaviours (paper section 2.2.1, state 1 -> 2 and 3): a validated intruder track, and its cue.

Validating a track designates the target: :class:`RadarTrackValidated` writes its
:class:`~chaser_bt.radar.custody.Custody` to ``/target/custody``, and :class:`RadarCue` carries that
custody over every radar picture (:func:`~chaser_bt.radar.custody.track_custody`: across drop-outs,
new ids and id swaps, never to another object) and cues on the designated target alone. The
operator changes the target by writing a track id to ``/radar/operator_confirmed_track``.

Both read the radar through a :class:`chaser_bt.radar.feed.RadarFeed` handed to ``setup`` as
``radar=`` (beside ``link`` and ``clock``); the feed filters our own drone out (the track
correlator, section 3.3), so neither behaviour can ever validate or cue on the ownship.
"""

from __future__ import annotations

import logging
from typing import Any

import py_trees

from behaviours.base import VehicleBehaviour, optional_input, state_port
from behaviours.vision import ESTIMATE_KEY
from chaser_bt.cue import TargetCue, TargetEstimate
from chaser_bt.radar.custody import Custody, CustodyEvent, CustodyParams, Sight, designate, track_custody
from chaser_bt.radar.feed import RadarFeed, RadarPicture, RadarTrack
from chaser_bt.tree import NodeKind, input_port, output_port, register_behaviour

Status = py_trees.common.Status

VALIDATED_TRACK_KEY = "/radar/validated_track"
OPERATOR_CONFIRMATION_KEY = "/radar/operator_confirmed_track"
CUE_KEY = "/target/cue"
CUSTODY_KEY = "/target/custody"

log = logging.getLogger(__name__)


def _log(events: list[CustodyEvent], node: str) -> None:
    for e in events:
        log.info("%s: %s at %.1f s", node, e, e.t)


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
        "custody": input_port(Custody, "The target designated so far (re-validating it changes nothing)",
                              required=False, default_key=CUSTODY_KEY),
        "state": state_port(),
    }
    OUTPUT_PORTS = {
        "validated_track": output_port(int, "Id of the validated track", default_key=VALIDATED_TRACK_KEY),
        "designated": output_port(Custody, "Custody of the target the validated track designates",
                                  default_key=CUSTODY_KEY),
    }

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
                    chosen, why = tr, f"radar confidence {tr.confidence:.2f}"
                    break
        if chosen is None:
            self.feedback_message = f"{len(pic.intruders)} unvalidated track(s), ownship {sorted(pic.ownship_ids)}"
            return Status.FAILURE
        custody, event = designate(chosen, pic.t, why, optional_input(self, "custody"))
        if event is not None:
            _log([event], self.name)
        self._set_output("validated_track", chosen.track_id)
        self._set_output("designated", custody)
        self.feedback_message = f"track {chosen.track_id} validated ({why})"
        return Status.SUCCESS


@register_behaviour
class RadarCue(_RadarBehaviour):
    """Write the designated target's radar cue (ENU position, covariance, velocity, time) to ``cue``
    and its custody to ``custody``.

    The target is the one ``designated`` holds (RadarTrackValidated writes it), else the ``track``
    given, else the most confident track (then designated here). Custody follows it across radar
    drop-outs, new ids and id swaps and never hands it to another object; while the camera follows
    the target (``sight``), a new track must also lie on its line of sight; an operator's track id on
    ``operator_track`` switches the target. SUCCESS with a cue of the target no older than
    ``max_age_s``; FAILURE while the radar does not confirm it (cue lost: search).
    """

    NODE_KIND = NodeKind.ACTION
    INPUT_PORTS = {
        "designated": input_port(Custody, "The designated target's custody", required=False, default_key=CUSTODY_KEY),
        "track": input_port(int, "Track id to designate when nothing is designated yet", required=False,
                            default_key=VALIDATED_TRACK_KEY),
        "operator_track": input_port(int, "Track id the operator designates: switches the target", required=False,
                                     default_key=OPERATOR_CONFIRMATION_KEY),
        "max_age_s": input_port(float, "A cue older than this is lost (s)", default=2.0, minimum=0),
        "max_coast_s": input_port(float, "Unconfirmed this long, the target is lost (s)", default=15.0, above=0),
        "sight": input_port(TargetEstimate, "The camera's estimate of the target it follows: a new track must lie on "
                            "its line of sight", required=False, default_key=ESTIMATE_KEY),
        "state": state_port(),
    }
    OUTPUT_PORTS = {
        "cue": output_port(TargetCue, "The designated target's cue", default_key=CUE_KEY),
        "custody": output_port(Custody, "The designated target's custody", default_key=CUSTODY_KEY),
    }

    def update(self) -> Status:
        pic = self.picture()
        custody = self._designated(pic)
        if custody is None:
            self.feedback_message = "no intruder track"
            return Status.FAILURE
        estimate = optional_input(self, "sight")
        sight = Sight.of(estimate) if isinstance(estimate, TargetEstimate) else None
        custody, events = track_custody(custody, pic, CustodyParams(max_coast_s=self.get_input("max_coast_s")), sight)
        _log(events, self.name)
        self._set_output("custody", custody)
        if custody.track_id is None or pic.t - custody.t_confirmed > self.get_input("max_age_s"):
            state = "lost" if custody.lost else f"coasting {custody.since_confirmed(pic.t):.1f} s"
            self.feedback_message = f"target {custody.target_id} {state}"
            return Status.FAILURE
        self._set_output("cue", custody.cue())
        self.feedback_message = (f"target {custody.target_id} on track {custody.track_id} at "
                                 f"{custody.position_enu.round(1).tolist()}, age {pic.t - custody.t_confirmed:.1f} s")
        return Status.SUCCESS

    def _designated(self, pic: RadarPicture) -> Custody | None:
        """The custody to carry: the designated one, switched by the operator, or one designated now."""
        custody: Custody | None = optional_input(self, "designated")
        operator = optional_input(self, "operator_track")
        tracks = {tr.track_id: tr for tr in pic.intruders}
        if operator is not None and operator in tracks and (custody is None or operator not in custody.track_ids):
            custody, event = designate(tracks[operator], pic.t, "operator", custody)
            _log([event] if event else [], self.name)
        if custody is not None:
            return custody
        chosen: RadarTrack | None = tracks.get(optional_input(self, "track")) or (pic.intruders[0] if pic.intruders else None)
        if chosen is None:
            return None
        custody, event = designate(chosen, pic.t, f"radar confidence {chosen.confidence:.2f}")
        _log([event] if event else [], self.name)
        return custody


@register_behaviour
class CustodyHeld(VehicleBehaviour):
    """SUCCESS while the designated target is held: designated, not lost, confirmed by the radar within
    ``max_unconfirmed_s`` and at ``min_confidence`` or more; FAILURE otherwise (a safety branch or a
    fallback can act on a target the mission no longer holds)."""

    NODE_KIND = NodeKind.CONDITION
    INPUT_PORTS = {
        "custody": input_port(Custody, "The designated target's custody", required=False, default_key=CUSTODY_KEY),
        "max_unconfirmed_s": input_port(float, "Unconfirmed longer than this, the target is not held (s)", default=5.0,
                                        minimum=0),
        "min_confidence": input_port(float, "Least custody confidence that holds it (0..1)", default=0.0, minimum=0,
                                     maximum=1),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def update(self) -> Status:
        custody: Custody | None = optional_input(self, "custody")
        now = self._now()
        if custody is None:
            self.feedback_message = "no target designated"
            return Status.FAILURE
        unconfirmed, confidence = custody.since_confirmed(now), custody.confidence(now)
        self.feedback_message = (f"target {custody.target_id} {'lost' if custody.lost else 'held'}, unconfirmed "
                                 f"{unconfirmed:.1f} s, confidence {confidence:.2f}")
        held = (not custody.lost and unconfirmed <= self.get_input("max_unconfirmed_s")
                and confidence >= self.get_input("min_confidence"))
        return Status.SUCCESS if held else Status.FAILURE
