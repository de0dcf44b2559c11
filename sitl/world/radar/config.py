"""The ground radar's configuration: pose, coverage, noise, detection, clutter and failure modes.

Defaults follow an Echodyne EchoGuard (120 deg x 80 deg field of view) with the noise that gives
the paper's calibration residuals (appendix A): range 0.5 m, azimuth 0.4 deg, elevation 1 deg.
The scenario's ``radar:`` section (sitl/scenarios/README.md) fills these; angles there are in
degrees, here in radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from chaser_bt.geo import GeoPoint

__all__ = ["RadarFailureRates", "RadarClutter", "RadarConfig", "RadarSignature", "REFERENCE_RCS_M2"]

#: The radar cross-section (m^2) the configured ``pd`` holds for out to ``max_range_m``: the small end
#: of a Phantom-class quadcopter (0.01-0.03 m^2), so such a drone anywhere in coverage is seen at ``pd``.
REFERENCE_RCS_M2 = 0.01


@dataclass(frozen=True)
class RadarFailureRates:
    """The track-id failures the paper names (section 3.3), each at a rate.

    Attributes:
        drop_per_s: per track and second, the chance the track ends; the object comes back under a
            new id after ``drop_gap_s``.
        drop_gap_s: how long a dropped object goes untracked.
        swap_prob: per close encounter of two tracked objects, the chance their ids exchange.
        swap_distance_m: objects closer than this are in a close encounter.
        duplicate_per_s: per track and second, the chance a parallel duplicate track starts.
        duplicate_duration_s: how long a duplicate lives.
        duplicate_offset_m: 1-sigma constant offset of a duplicate from the object.
    """

    drop_per_s: float = 0.0
    drop_gap_s: float = 0.4
    swap_prob: float = 0.0
    swap_distance_m: float = 10.0
    duplicate_per_s: float = 0.0
    duplicate_duration_s: float = 6.0
    duplicate_offset_m: float = 1.5


@dataclass(frozen=True)
class RadarClutter:
    """False tracks (short, near stationary) and birds (slow wanderers), Poisson in time."""

    false_tracks_per_s: float = 0.0
    false_track_life_s: float = 2.0
    birds_per_s: float = 0.0
    bird_life_s: float = 20.0
    bird_speed_mps: float = 6.0


@dataclass(frozen=True)
class RadarConfig:
    """A ground radar.

    Attributes:
        position: geodetic position of the radar.
        yaw_rad, pitch_rad, roll_rad: boresight heading (clockwise from north), pitch up, roll right.
        fov_az_rad, fov_el_rad: full field of view (centred on the boresight).
        min_range_m, max_range_m: detection range.
        rate_hz: scans per second (one datagram each).
        sigma_range_m, sigma_az_rad, sigma_el_rad: 1-sigma measurement noise.
        sigma_vel_mps, vel_tau_s: the tracker's velocity: a first-order lag of the object's with
            white noise.
        pd: probability of detecting an object in coverage on one scan.
        coast_s: a track with no detection for this long ends.
        confidence_tau_s: track confidence rises as 1 - exp(-age / tau) (capped by object class).
        off_at_s: the radar stops (no more datagrams) at this simulator time; None = never.
        reference_rcs_m2, pfa: the detection model of objects with a radar cross-section of their own
            (:class:`RadarSignature`, :func:`sitl.world.radar.model.detection_probability`): an object
            of ``reference_rcs_m2`` at ``max_range_m`` is detected with probability ``pd`` at the false
            alarm probability ``pfa``.
        udp_host, udp_port: where to send datagrams; port None = no UDP.
        radar_id: the ``radar_id`` in every datagram.
    """

    position: GeoPoint
    yaw_rad: float = 0.0
    pitch_rad: float = 0.0
    roll_rad: float = 0.0
    fov_az_rad: float = math.radians(120.0)
    fov_el_rad: float = math.radians(80.0)
    min_range_m: float = 10.0
    max_range_m: float = 1000.0
    rate_hz: float = 5.0
    sigma_range_m: float = 0.5
    sigma_az_rad: float = math.radians(0.4)
    sigma_el_rad: float = math.radians(1.0)
    sigma_vel_mps: float = 0.3
    vel_tau_s: float = 0.4
    pd: float = 0.95
    coast_s: float = 1.0
    confidence_tau_s: float = 2.0
    failures: RadarFailureRates = field(default_factory=RadarFailureRates)
    clutter: RadarClutter = field(default_factory=RadarClutter)
    off_at_s: float | None = None
    reference_rcs_m2: float = REFERENCE_RCS_M2
    pfa: float = 1e-6
    udp_host: str = "127.0.0.1"
    udp_port: int | None = None
    radar_id: str = "echoguard-sim"


@dataclass(frozen=True)
class RadarSignature:
    """How one object shows on the radar: a scenario's per-object ``radar:`` mapping.

    Attributes:
        rcs_m2: radar cross-section; None: detected at ``pd`` wherever it is in coverage (today's
            model). Given, the detection probability falls with range and RCS by the radar equation
            (:func:`sitl.world.radar.model.detection_probability`).
        pd: this object's detection probability in place of the radar's ``pd``; None: the radar's.
        drop_per_s: this object's track drop rate in place of ``failures.drop_per_s``; None: the radar's.
    """

    rcs_m2: float | None = None
    pd: float | None = None
    drop_per_s: float | None = None
