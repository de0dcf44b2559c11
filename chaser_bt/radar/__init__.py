"""The ground radar on the mission side (paper section 3.3, appendix A): the datagram schema and
stream reader, the track correlators (Algorithm 1 and ours), calibration, and the feed that turns
the stream into an ENU picture with our own drone filtered out. docs/radar.md describes it all."""

from chaser_bt.radar.correlator import (Algorithm1Correlator, Association, GatedCorrelator, TrackCorrelator,
                                        TrackPoints, make_correlator)
from chaser_bt.radar.feed import RadarFeed, RadarNoise, RadarPicture, RadarTrack
from chaser_bt.radar.geometry import RadarPose
from chaser_bt.radar.report import RadarScan, TrackReport
from chaser_bt.radar.stream import QueueDatagramSource, RadarStreamReader, UdpDatagramSource

__all__ = ["Algorithm1Correlator", "Association", "GatedCorrelator", "TrackCorrelator", "TrackPoints",
           "make_correlator", "RadarFeed", "RadarNoise", "RadarPicture", "RadarTrack",
           "RadarPose", "RadarScan", "TrackReport", "QueueDatagramSource", "RadarStreamReader", "UdpDatagramSource"]
