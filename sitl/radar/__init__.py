"""The simulated ground radar (EchoGuard-like): configuration, the radar model, UDP streaming,
and the paper's radar flights (correlation test, calibration flight) with their scoring."""

from sitl.radar.config import RadarClutter, RadarConfig, RadarFailureRates
from sitl.radar.model import BIRD_LABEL, CLUTTER_LABEL, GroundRadar, ScanTruth
from sitl.radar.udp import RadarUdpSender

__all__ = ["RadarClutter", "RadarConfig", "RadarFailureRates", "GroundRadar", "ScanTruth", "RadarUdpSender",
           "BIRD_LABEL", "CLUTTER_LABEL"]
