"""Test helpers: CVAT-format exports (YOLO 1.1, COCO 1.0) and a short video written from rendered frames.

The layouts follow CVAT's exporters (docs.cvat.ai, "YOLO" and "COCO" formats): a video task's
frames are ``frame_000000.PNG``...; YOLO's lists carry darknet's ``data/`` prefix.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import cv2
import numpy as np

from sitl.bench.camera_dataset import DatasetRenderer, frame_boxes

W, H = 160, 120


def rendered_frames(count: int, seed: int = 3) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """``count`` tiny rendered frames (160 x 120) and their (N, 5) pixel labels (class, x0, y0, x1, y1)."""
    renderer = DatasetRenderer("heldout", W, H, ground_size_px=256)
    rng = np.random.default_rng(seed)
    frames = [renderer.sample(rng) for _ in range(count)]
    return [f.image for f in frames], [frame_boxes(f) for f in frames]


def _png(image: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", image)
    assert ok
    return buf.tobytes()


def write_yolo11(path: Path, classes, boxes_px: list[np.ndarray], images: list[np.ndarray] | None,
                 label_text: dict[int, str] | None = None, image_bytes: dict[int, bytes] | None = None,
                 leave_out: tuple[int, ...] = ()) -> Path:
    """A CVAT "YOLO 1.1" zip; ``images`` None writes none (exported without images); ``label_text``
    replaces a frame's label file, ``image_bytes`` its image, ``leave_out`` drops images from the zip."""
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("obj.data", f"classes = {len(classes)}\ntrain = data/train.txt\nnames = data/obj.names\nbackup = backup/\n")
        z.writestr("obj.names", "".join(c + "\n" for c in classes))
        z.writestr("train.txt", "".join(f"data/obj_train_data/frame_{i:06d}.PNG\n" for i in range(len(boxes_px))))
        for i, b in enumerate(boxes_px):
            lines = [f"{int(c)} {(x0 + x1) / 2 / W:.6f} {(y0 + y1) / 2 / H:.6f} {(x1 - x0) / W:.6f} {(y1 - y0) / H:.6f}\n"
                     for c, x0, y0, x1, y1 in b]
            z.writestr(f"obj_train_data/frame_{i:06d}.txt", (label_text or {}).get(i, "".join(lines)))
            if images is not None and i not in leave_out:
                z.writestr(f"obj_train_data/frame_{i:06d}.PNG", (image_bytes or {}).get(i) or _png(images[i]))
    return path


def coco_document(classes, boxes_px: list[np.ndarray], size=(W, H)) -> dict:
    """CVAT's instances_default.json for frames frame_000000.PNG ... with (N, 5) pixel boxes."""
    images = [{"id": i + 1, "width": size[0], "height": size[1], "file_name": f"frame_{i:06d}.PNG", "license": 0,
               "flickr_url": "", "coco_url": "", "date_captured": 0} for i in range(len(boxes_px))]
    anns = []
    for i, b in enumerate(boxes_px):
        for c, x0, y0, x1, y1 in b:
            anns.append({"id": len(anns) + 1, "image_id": i + 1, "category_id": int(c) + 1, "segmentation": [],
                         "area": float((x1 - x0) * (y1 - y0)), "bbox": [float(x0), float(y0), float(x1 - x0), float(y1 - y0)],
                         "iscrowd": 0, "attributes": {"occluded": False, "rotation": 0.0, "track_id": 0, "keyframe": True}})
    return {"licenses": [{"name": "", "id": 0, "url": ""}], "info": {"contributor": "", "date_created": "", "description": "",
            "url": "", "version": "", "year": ""}, "categories": [{"id": k + 1, "name": c, "supercategory": ""} for k, c in enumerate(classes)],
            "images": images, "annotations": anns}


def write_coco10(path: Path, classes, boxes_px: list[np.ndarray], images: list[np.ndarray] | None, doc: dict | None = None) -> Path:
    """A CVAT "COCO 1.0" zip: annotations/instances_default.json and, with ``images``, images/frame_NNNNNN.PNG."""
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("annotations/instances_default.json", json.dumps(doc or coco_document(classes, boxes_px)))
        for i, img in enumerate(images or []):
            z.writestr(f"images/frame_{i:06d}.PNG", _png(img))
    return path


def write_video(path: Path, images: list[np.ndarray], fps: float = 10.0) -> Path:
    """A Motion-JPEG .avi of ``images`` (cv2.VideoWriter)."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (W, H))
    assert writer.isOpened()
    for img in images:
        writer.write(img)
    writer.release()
    return path
