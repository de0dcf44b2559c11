"""Streaming to the ground (the paper's fourth task): estimate, radar tracks and video with boxes;
and the operator's designations coming up (:class:`GroundDesignation`).

:class:`StreamToGround` sends, each tick, the ownship's status, the camera's target estimate
(``/target/estimate``) when it is new, the radar tracks (from the ``radar=`` resource, the picture
the radar behaviours see this tick) or else the radar cue (``/target/cue``), and at ``video_hz``
the camera resource's last frame with the pipeline's current box drawn (inline, a CameraSensor's
last frame and track; threaded, a PerceptionWorker's latest result). The wire format is
docs/ground.md (:mod:`chaser_bt.ground.protocol`); with ``key_file`` every datagram carries an
HMAC (:mod:`chaser_bt.ground.auth`). Streaming never fails a mission: it is RUNNING
every tick, whatever the network does (errors are dropped datagrams, counted and logged once).
"""

from __future__ import annotations

from typing import Any

import py_trees

from behaviours.base import VehicleBehaviour, optional_input, state_port
from chaser_bt.cue import TargetCue, TargetEstimate
from behaviours.radar import OPERATOR_CONFIRMATION_KEY
from behaviours.sar import FIND_KEY
from chaser_bt.find import Find
from chaser_bt.ground.auth import StreamSigner
from chaser_bt.ground.designation import designation_summary, take_designations
from chaser_bt.ground.protocol import Box, cue_message, estimate_message, find_message, status_message, tracks_message
from chaser_bt.ground.sender import GroundSender
from chaser_bt.ground.uplink import UplinkReceiver
from chaser_bt.radar.feed import RadarFeed
from chaser_bt.tree import NodeKind, input_port, output_port, register_behaviour
from chaser_bt.vehicle.signing import load_key
from chaser_bt.vision.frame_source import Frame
from chaser_bt.vision.perception import PerceptionWorker
from chaser_bt.vision.pipeline import CameraSensor

Status = py_trees.common.Status


@register_behaviour
class StreamToGround(VehicleBehaviour):
    """Send status, estimate, tracks and video to ``host:port`` over UDP; always RUNNING."""

    NODE_KIND = NodeKind.ACTION
    USES_RESOURCES = ("camera", "radar")  # the video and the tracks, when the flight has them
    INPUT_PORTS = {
        "host": input_port(str, "Ground station address", default="127.0.0.1"),
        "port": input_port(int, "Ground station UDP port", default=14600, minimum=1, maximum=65535),
        "video_hz": input_port(float, "Video frames per second (0: no video)", default=5.0, minimum=0),
        "jpeg_quality": input_port(int, "JPEG quality of the video (1-100)", default=70, minimum=1, maximum=100),
        "key_file": input_port(str, "Sign every datagram with this key file (MAVLink signing's format; "
                                    "empty: unsigned)", default=""),
        "link_id": input_port(int, "This sender's link id in the signatures (0-255)", default=0, minimum=0, maximum=255),
        "estimate": input_port(TargetEstimate, "The camera's target estimate", required=False,
                               default_key="/target/estimate"),
        "cue": input_port(TargetCue, "The radar cue (sent when there is no radar resource)", required=False,
                          default_key="/target/cue"),
        "find": input_port(Find, "A search-and-rescue find (sent when it changes)", required=False, default_key=FIND_KEY),
        "state": state_port(),
    }
    OUTPUT_PORTS: dict = {}

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        camera, radar = kwargs.get("camera"), kwargs.get("radar")
        self.camera: CameraSensor | PerceptionWorker | None = (
            camera if isinstance(camera, (CameraSensor, PerceptionWorker)) else None)
        if isinstance(self.camera, CameraSensor):
            self.camera.whole_frames = True  # the video shows whole frames, not the pipeline's regions of interest
        self.radar: RadarFeed | None = radar if isinstance(radar, RadarFeed) else None
        self.sender: GroundSender | None = None
        self._host: str | None = None
        self._last_estimate_t: float | None = None
        self._last_cue_t: float | None = None
        self._last_find_t: float | None = None
        self._last_frame_index: int | None = None
        self._next_frame_t = float("-inf")
        key_file = self.get_input("key_file")
        # Loaded before take-off: a key file that cannot be read stops the mission here, not in flight.
        self.signer = StreamSigner(load_key(key_file), self.get_input("link_id")) if key_file else None

    def initialise(self) -> None:
        host, port = self.get_input("host"), self.get_input("port")
        if self.sender is None or self.sender.address[1] != port or self._host != host:
            if self.sender is not None:
                self.sender.close()
            self._host = host
            try:
                self.sender = GroundSender(host, port, signer=self.signer)
            except ValueError as e:  # a bad address: say so, keep the mission flying
                self.sender = None
                self.feedback_message = f"not streaming: {e}"

    def update(self) -> Status:
        if self.sender is None:
            return Status.RUNNING
        try:
            self._send_all()
        except ValueError as e:  # an unusable port value (jpeg_quality) or an oversized message
            self.feedback_message = f"not sent: {e}"
        return Status.RUNNING

    def _send_all(self) -> None:
        now, s, out = self._now(), self.state, self.sender
        frame = self.link.frame if self.link is not None else None
        origin = None if frame is None else (frame.origin.lat_deg, frame.origin.lon_deg, frame.origin.alt_m)
        out.send_message("status", now, status_message(
            position_enu=s.position_enu, velocity_enu=s.velocity_enu, yaw_enu_rad=s.yaw_enu_rad, mode=s.mode,
            armed=s.armed, alt_rel_m=s.alt_rel_m, origin=origin, counters=out.counters.as_dict()))
        est = optional_input(self, "estimate")
        if isinstance(est, TargetEstimate) and est.t != self._last_estimate_t:
            self._last_estimate_t = est.t
            out.send_message("estimate", now, estimate_message(est))
        if self.radar is not None:
            pic = self.radar.update(now, s.position_enu, s.velocity_enu)
            out.send_message("tracks", now, tracks_message(pic.tracks.values(), pic.ownship_ids))
        cue = optional_input(self, "cue")
        if isinstance(cue, TargetCue) and cue.t != self._last_cue_t:
            self._last_cue_t = cue.t
            out.send_message("cue", now, cue_message(cue))
        find = optional_input(self, "find")
        if isinstance(find, Find) and find.t != self._last_find_t:
            self._last_find_t = find.t
            out.send_message("find", now, find_message(find))
        self._send_video(now)
        c = out.counters
        self.feedback_message = f"{c.messages} messages, {c.frames} frames, {c.errors} dropped"

    def _send_video(self, now: float) -> None:
        hz = self.get_input("video_hz")
        if self.camera is None or not hz > 0 or now < self._next_frame_t - 1e-6:
            return
        frame, boxes = self._latest_view()
        if frame is None or frame.index == self._last_frame_index:
            return
        self._last_frame_index = frame.index
        period = 1.0 / hz
        self._next_frame_t = self._next_frame_t + period if self._next_frame_t + period > now else now + period
        self.sender.send_frame(frame.image, frame.t, boxes, self.get_input("jpeg_quality"))

    def _latest_view(self) -> tuple[Frame | None, list[Box]]:
        """The camera's latest frame and the box followed in it."""
        if isinstance(self.camera, PerceptionWorker):
            result = self.camera.latest()
            if result is None:
                return None, []
            return result.frame, [] if result.box is None else [Box(result.box, result.label)]
        track = self.camera.pipeline.track
        return self.camera.last_frame, [] if track is None else [Box(track.box, track.label)]

    def shutdown(self) -> None:
        if self.sender is not None:
            self.sender.close()
            self.sender = None


@register_behaviour
class GroundDesignation(VehicleBehaviour):
    """The operator's designations from the ground: each signed ``designate`` command the ``uplink=``
    resource (a :class:`~chaser_bt.ground.uplink.UplinkReceiver`, ``chaser-bt run --uplink``) believed,
    and each signed MAVLink designation from a ground station the vehicle link believed
    (:mod:`chaser_bt.vehicle.designation`), writes its radar track id to ``operator_track`` (the radar
    behaviours validate it, or switch the chase to it), in the order they came
    (:func:`~chaser_bt.ground.designation.take_designations`). Always SUCCESS: without the resource
    the uplink is off, and nothing the network sends can fail the mission. Several nodes may share
    the sources (whichever ticks reads them).
    """

    NODE_KIND = NodeKind.ACTION
    USES_RESOURCES = ("uplink",)  # off without it
    INPUT_PORTS = {"state": state_port()}
    OUTPUT_PORTS = {"operator_track": output_port(int, "The track id the operator designated",
                                                  default_key=OPERATOR_CONFIRMATION_KEY)}

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        uplink = kwargs.get("uplink")
        self.uplink: UplinkReceiver | None = uplink if isinstance(uplink, UplinkReceiver) else None

    def update(self) -> Status:
        for designation in take_designations(self.uplink, self.link):
            self._set_output("operator_track", designation.track_id)
        self.feedback_message = designation_summary(self.uplink, self.link)
        return Status.SUCCESS
