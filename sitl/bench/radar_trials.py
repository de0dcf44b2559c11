"""The paper's radar flights, simulated: the correlation test (section 4) and a calibration flight
(appendix A), plus the scoring of a correlator against the radar's truth.

Both flights use scripted paths (:mod:`sitl.world.targets`) rather than the MAVLink vehicle so twenty
500-second seeds run in seconds; the radar model, its failure modes and the GPS noise are the same
as in a full simulation. Only scoring reads the truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from chaser_bt.geo import GeoPoint, LocalFrame
from chaser_bt.radar.correlator import TrackCorrelator
from chaser_bt.radar.feed import RadarNoise, scan_to_points
from chaser_bt.radar.geometry import RadarPose
from chaser_bt.radar.report import RadarScan
from sitl.world.radar.config import RadarClutter, RadarConfig, RadarFailureRates
from sitl.world.radar.model import GroundRadar, ScanTruth
from sitl.world.targets import (
    TargetPath,
    WaypointPath,
    circle_points,
    downrange_and_back_points,
)

__all__ = ["GpsNoise", "RadarFlight", "simulate_flight", "correlation_test_flight", "calibration_test_flight",
           "AssociationScore", "score_correlator", "PAPER_TEST_RADAR", "handheld_guess", "to_recording"]

OWNSHIP = "ownship"
FIELD = GeoPoint(42.5445, -71.6105, 80.0)

#: The correlation test's radar: 5 Hz, EchoGuard noise, ids that drop about every 20 s per track,
#: swap on half of the close passes, and duplicate now and then; a little clutter and a few birds.
PAPER_TEST_RADAR = RadarConfig(
    position=FIELD, yaw_rad=0.0, pitch_rad=math.radians(10.0), rate_hz=5.0,
    failures=RadarFailureRates(drop_per_s=1 / 20, swap_prob=0.5, swap_distance_m=10.0,
                               duplicate_per_s=1 / 40, duplicate_duration_s=6.0),
    clutter=RadarClutter(false_tracks_per_s=0.2, birds_per_s=0.02),
)


@dataclass(frozen=True)
class GpsNoise:
    """Ownship GPS: white noise plus a slowly wandering bias (first-order Gauss-Markov)."""

    rate_hz: float = 5.0
    sigma_h_m: float = 0.3
    sigma_v_m: float = 0.6
    bias_h_m: float = 0.7
    bias_v_m: float = 1.0
    bias_tau_s: float = 60.0
    sigma_vel_mps: float = 0.1


@dataclass
class RadarFlight:
    """A recorded flight: scans and their truth, ownship GPS (ENU, frame at ``frame.origin``)."""

    frame: LocalFrame
    true_pose: RadarPose
    config: RadarConfig
    scans: list[tuple[RadarScan, ScanTruth]]
    gps_t: np.ndarray
    gps_enu: np.ndarray
    gps_vel: np.ndarray
    ownship_in_coverage: np.ndarray  # per scan
    noise: RadarNoise = field(default_factory=RadarNoise)

    @property
    def duration_s(self) -> float:
        return float(self.gps_t[-1] - self.gps_t[0]) if self.gps_t.size else 0.0


def simulate_flight(paths: dict[str, TargetPath], config: RadarConfig, seed: int, duration_s: float,
                    gps: GpsNoise = GpsNoise()) -> RadarFlight:
    """Fly ``paths`` (one must be ``"ownship"``) past the radar for ``duration_s``."""
    rng = np.random.default_rng(seed)
    frame = LocalFrame(FIELD)
    radar = GroundRadar(config, frame, np.random.default_rng([seed, 1]))
    scans, cover = [], []
    for t in np.arange(0.0, duration_s, 1.0 / config.rate_hz):
        objs = {k: (p.position_enu(t), p.velocity_enu(t)) for k, p in paths.items()}
        out = radar.scan(float(t), objs)
        if out is not None:
            scans.append(out)
            cover.append(radar.in_coverage(objs[OWNSHIP][0]))
    gt = np.arange(0.0, duration_s, 1.0 / gps.rate_hz) + 0.013  # GPS not in step with the radar
    own = paths[OWNSHIP]
    pos = np.array([own.position_enu(t) for t in gt])
    vel = np.array([own.velocity_enu(t) for t in gt])
    a = math.exp(-1.0 / (gps.rate_hz * gps.bias_tau_s))
    sb = np.array([gps.bias_h_m, gps.bias_h_m, gps.bias_v_m])
    bias = rng.normal(0.0, sb)
    biases = np.empty_like(pos)
    for k in range(len(gt)):
        bias = a * bias + math.sqrt(1 - a * a) * rng.normal(0.0, sb)
        biases[k] = bias
    white = rng.normal(0.0, [gps.sigma_h_m, gps.sigma_h_m, gps.sigma_v_m], pos.shape)
    noise = RadarNoise(config.sigma_range_m, config.sigma_az_rad, config.sigma_el_rad)
    return RadarFlight(frame, radar.pose, config, scans, gt, pos + biases + white,
                       vel + rng.normal(0.0, gps.sigma_vel_mps, vel.shape), np.array(cover, bool), noise)


def correlation_test_flight(seed: int, duration_s: float = 500.0, config: RadarConfig = PAPER_TEST_RADAR) -> RadarFlight:
    """The paper's correlation test (section 4): two drones for ~500 s flying circles, the ownship
    also 100 m downrange and back, in front of a radar with drops, swaps and duplicates."""
    # Counter-clockwise laps from the circle's east point (heading north), then 100 m further north
    # and back with 10 m-radius turns at both ends, into the next laps: no jumps in velocity.
    leg = downrange_and_back_points((40.0, 150.0, 30.0), math.pi / 2, 100.0, turn_radius_m=10.0)
    bottom = [(30.0 - 10.0 * math.cos(a), 150.0 - 10.0 * math.sin(a), 30.0)
              for a in np.linspace(0.0, math.pi, 13)[1:]]  # heading south -> east -> north
    own_pts = circle_points((0.0, 150.0, 30.0), 40.0, phase_rad=0.0, laps=2) + leg[1:] + bottom[:-1]
    ownship = WaypointPath(tuple(own_pts), speed_mps=6.0, loop=True)
    intruder = WaypointPath(tuple(circle_points((35.0, 185.0, 34.0), 35.0, phase_rad=float(seed % 7), clockwise=True,
                                                laps=1)), speed_mps=5.0, loop=True)
    return simulate_flight({OWNSHIP: ownship, "intruder": intruder}, config, seed, duration_s)


def calibration_test_flight(seed: int, duration_s: float = 216.0) -> RadarFlight:
    """A 3 min 36 s calibration flight like the paper's (appendix A): circles and vertical passes in
    front of the radar; ids drop often (the paper recorded 22 tracks), some clutter and birds."""
    cfg = replace(PAPER_TEST_RADAR, yaw_rad=math.radians(35.0), pitch_rad=math.radians(8.0), roll_rad=math.radians(1.5),
                  failures=RadarFailureRates(drop_per_s=1 / 10, duplicate_per_s=1 / 60),
                  clutter=RadarClutter(false_tracks_per_s=0.05, birds_per_s=0.02))
    u = np.array([math.sin(cfg.yaw_rad), math.cos(cfg.yaw_rad), 0.0])  # boresight, horizontal
    left = np.array([-u[1], u[0], 0.0])
    c1 = tuple(90.0 * u + np.array([0, 0, 20.0]))
    pts = circle_points(c1, 25.0, laps=2)
    for k, (side, rng_m) in enumerate(((-30.0, 70.0), (0.0, 110.0), (30.0, 80.0))):
        base = rng_m * u + side * left
        pts += [tuple(base + [0, 0, 10.0]), tuple(base + [0, 0, 60.0]), tuple(base + 5 * u + [0, 0, 60.0]),
                tuple(base + 5 * u + [0, 0, 10.0])]
    pts += circle_points(tuple(150.0 * u + np.array([0, 0, 40.0])), 35.0, laps=1)
    return simulate_flight({OWNSHIP: WaypointPath(tuple(pts), speed_mps=5.0, loop=True)}, cfg, seed, duration_s)


@dataclass(frozen=True)
class AssociationScore:
    """Per 1 s window of flight with the ownship in radar coverage, the association state held for
    most of the window's scans: right (a track following the ownship), wrong, or none."""

    windows: int
    assoc_frac: float
    wrong_frac: float
    updates: int
    wall_s: float


def score_correlator(flight: RadarFlight, correlator: TrackCorrelator, pose: RadarPose | None = None,
                     perf_counter=None) -> AssociationScore:
    """Replay ``flight`` through ``correlator`` (one decision per scan) and score it against truth."""
    import time

    perf = perf_counter or time.perf_counter
    pose = pose or flight.true_pose
    correlator.reset()
    label: dict[int, str] = {}
    state = np.zeros(len(flight.scans), np.int8)  # 1 right, -1 wrong, 0 none
    gi = 0
    wall = 0.0
    for k, (scan, truth) in enumerate(flight.scans):
        label.update(truth.labels)
        start = perf()
        while gi < flight.gps_t.size and flight.gps_t[gi] <= scan.t:
            correlator.add_ownship(flight.gps_t[gi], flight.gps_enu[gi], flight.gps_vel[gi])
            gi += 1
        correlator.add_tracks(scan_to_points(scan, pose, flight.noise))
        a = correlator.associate(scan.t).associated_id
        wall += perf() - start
        if a is not None:
            state[k] = 1 if label.get(a) == OWNSHIP else -1
    t = np.array([s.t for s, _ in flight.scans])
    win = np.floor(t).astype(int)
    right = wrong = n = 0
    for w in np.unique(win):
        sel = win == w
        if flight.ownship_in_coverage[sel].mean() < 0.5:
            continue
        n += 1
        s = state[sel]
        values, counts = np.unique(s, return_counts=True)
        held = values[np.argmax(counts)] if counts.max() * 2 > s.size else 0
        right += held == 1
        wrong += held == -1
    return AssociationScore(n, right / n if n else math.nan, wrong / n if n else math.nan, len(flight.scans), wall)


def handheld_guess(flight: RadarFlight, seed: int) -> tuple[GeoPoint, tuple[float, float, float]]:
    """The paper's starting point: the radar's position from a handheld GPS (metres off) and its
    attitude from a phone compass (degrees off)."""
    rng = np.random.default_rng([seed, 7])
    pos = flight.true_pose.position_enu + rng.normal(0.0, [2.5, 2.5, 1.5])
    y, p, r = flight.true_pose.yaw_pitch_roll
    err = np.radians(rng.normal(0.0, [6.0, 2.0, 2.0]))
    return flight.frame.to_geodetic(pos), (y + err[0], p + err[1], r + err[2])


def to_recording(flight: RadarFlight, guess: tuple[GeoPoint, tuple[float, float, float]]):
    """``flight`` as a recorded calibration flight (chaser_bt.radar.recording), GPS in geodetic."""
    from chaser_bt.radar.recording import CalibrationRecording

    lla = np.array([[g.lat_deg, g.lon_deg, g.alt_m] for g in (flight.frame.to_geodetic(p) for p in flight.gps_enu)])
    return CalibrationRecording(guess[0], guess[1], tuple(s for s, _ in flight.scans), flight.gps_t.copy(), lla)


def main(argv: list[str] | None = None) -> int:
    """``python -m sitl.bench.radar_trials FILE.jsonl [--seed N]``: write the simulated calibration flight.

    The file is what ``chaser-bt calibrate`` reads (docs/radar.md): the radar's scans, the drone's
    GPS and the handheld guess of the radar's pose, all drawn from the seed.
    """
    import argparse

    from chaser_bt.cli_args import ChaserParser, output_file, seed
    from chaser_bt.radar.recording import write_recording

    parser = ChaserParser(prog="python -m sitl.bench.radar_trials",
                          description="write a simulated radar calibration flight (appendix A) for `chaser-bt calibrate`")
    parser.add_argument("out", type=output_file, metavar="FILE.jsonl", help="calibration recording to write")
    parser.add_argument("--seed", type=seed, default=1, metavar="N", help="seed of the flight, the noise and the guess (default 1)")
    parser.add_argument("--duration-s", type=float, default=216.0, metavar="S", help="flight length, s (default 216)")
    args: argparse.Namespace = parser.parse_args(argv)
    flight = calibration_test_flight(args.seed, args.duration_s)
    write_recording(args.out, to_recording(flight, handheld_guess(flight, args.seed)))
    print(f"calibration flight written to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
