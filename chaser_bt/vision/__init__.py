"""On-board vision: the camera model (and, later, detector, trackers, pixel <-> ENU, range)."""

from chaser_bt.vision.camera import CameraModel

__all__ = ["CameraModel"]
