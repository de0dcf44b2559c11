"""On-board vision (paper section 3.1): the camera model, detector, trackers, pixel <-> ENU and range.

Modules: :mod:`camera` (CameraModel), :mod:`detector` (the torch detector, its training and
evaluation), :mod:`trackers`, :mod:`projection`, :mod:`range`, :mod:`frame_source`, :mod:`pipeline`.
Only the camera model is imported here, so that using it does not load torch or OpenCV.
"""

from chaser_bt.vision.camera import CameraModel

__all__ = ["CameraModel"]
