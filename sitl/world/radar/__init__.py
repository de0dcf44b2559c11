"""The simulated ground radar (EchoGuard-like): configuration, the radar model and UDP streaming.

The paper's radar flights and their scoring are the bench's (:mod:`sitl.bench.radar_trials`)."""

from sitl.world.radar.config import RadarClutter, RadarConfig, RadarFailureRates
from sitl.world.radar.model import BIRD_LABEL, CLUTTER_LABEL, GroundRadar, ScanTruth
from sitl.world.radar.udp import RadarUdpSender

__all__ = ["RadarClutter", "RadarConfig", "RadarFailureRates", "GroundRadar", "ScanTruth", "RadarUdpSender",
           "BIRD_LABEL", "CLUTTER_LABEL"]
