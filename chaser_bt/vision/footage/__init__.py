"""Real footage for the detector: CVAT exports (YOLO 1.1, COCO 1.0) and recorded video, split by
contiguous chunks into the YOLO folders ``chaser-bt train-detector`` reads (docs/vision.md,
"Your own footage")."""

from chaser_bt.vision.footage.archive import ExportArchive
from chaser_bt.vision.footage.cvat import FootageError, FootageLabels, LabelledFrame, read_export
from chaser_bt.vision.footage.importer import ImportSummary, import_footage
from chaser_bt.vision.footage.split import chunk_split
from chaser_bt.vision.footage.video import VideoFrames

__all__ = ["ExportArchive", "FootageError", "FootageLabels", "LabelledFrame", "read_export", "ImportSummary",
           "import_footage", "chunk_split", "VideoFrames"]
