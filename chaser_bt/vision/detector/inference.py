"""Run the trained detector on BGR frames: letterbox, forward, decode, confidence filter, NMS, and
the box refiner shipped beside the weights when there is one (:mod:`chaser_bt.vision.detector.refine`).

The default weights ship in ``chaser_bt/vision/weights/tiny_yolo.pt`` and load without any
download; :data:`SHIPPED_WEIGHTS` names every shipped model (``tiny_yolo``: s1000 and phantom;
``person_yolo``: person, for search and rescue) and :func:`shipped_detector` loads one by name. Torch uses ``threads`` intra-op threads (1 measured fastest on the shared 2-core CPU:
see docs/vision.md). An ONNX copy can be exported with :func:`export_onnx`; with ``backend="auto"`` onnxruntime
runs it when it is installed and the copy beside the weights is not older than them. An int8 copy
(``<stem>.int8.onnx``, :mod:`chaser_bt.vision.detector.quantize`, ``chaser-bt quantize-detector``) is
preferred over the float one by "auto" under the same rule.

With onnxruntime the detector runs without torch (whose import costs seconds at start-up): the ONNX
copies carry what the network is (class names, stride, IoU-aware scores) in their metadata
(:func:`~chaser_bt.vision.detector.onnx_copy.write_metadata`), the head is decoded in numpy, and the box refiner runs its own ONNX copy.
Torch is imported only for the torch backend or a copy without that metadata.
"""

from __future__ import annotations

import functools
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from chaser_bt.vision.detection import Detection
from chaser_bt.vision.detector.augment import letterbox
from chaser_bt.vision.detector.onnx_copy import METADATA_KEY, fresh, have_onnxruntime, ort_session, read_metadata, write_metadata
from chaser_bt.vision.detector.refine import BoxRefiner, refiner_path

__all__ = ["Detection", "Detector", "DEFAULT_WEIGHTS", "DEFAULT_ONNX", "BACKENDS", "SHIPPED_WEIGHTS", "shipped_detector", "load_model", "nms",
           "export_onnx", "int8_path", "network_input", "decode_head", "write_metadata", "read_metadata", "METADATA_KEY"]

_WEIGHTS_DIR = Path(__file__).resolve().parent.parent / "weights"
DEFAULT_WEIGHTS = _WEIGHTS_DIR / "tiny_yolo.pt"
DEFAULT_ONNX = DEFAULT_WEIGHTS.with_suffix(".onnx")
#: The detectors shipped in the package, by the name a tree uses.
SHIPPED_WEIGHTS: dict[str, Path] = {"tiny_yolo": DEFAULT_WEIGHTS, "person_yolo": _WEIGHTS_DIR / "person_yolo.pt"}
_MAX_NMS = 300
#: What ``Detector(backend=...)`` accepts.
BACKENDS = ("auto", "torch", "onnx", "onnx-int8")


def int8_path(weights: str | Path) -> Path:
    """Where the int8 ONNX copy of ``weights`` lives: beside them, ``<stem>.int8.onnx``."""
    p = Path(weights)
    return p.with_name(p.stem + ".int8.onnx")


def network_input(letterboxed_bgr: np.ndarray) -> np.ndarray:
    """A letterboxed BGR image as the network takes it: (1, 3, H, W), RGB, float32 in [0, 1]."""
    # Channel by channel into the planar buffer: the same values as a transpose, cast and divide, in a
    # sixth of the time (no strided copy of the whole image; measured on the chase's detector frames).
    out = np.empty((1, 3) + letterboxed_bgr.shape[:2], np.float32)
    for c in range(3):
        np.divide(letterboxed_bgr[..., 2 - c], np.float32(255.0), out=out[0, c], dtype=np.float32)
    return out


def _load_blob(path: str | Path) -> dict:
    import torch

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"detector weights not found: {p}")
    if p.is_file() and p.stat().st_size == 0:  # torch.load would say only "EOFError: Ran out of input"
        raise ValueError(f"{p}: empty file, not detector weights")
    return torch.load(p, map_location="cpu", weights_only=False)


def load_model(path: str | Path = DEFAULT_WEIGHTS):
    """The detector (a torch ``TinyYolo``) with weights from ``path`` (a file saved by training), in eval mode, float32."""
    return _model(_load_blob(path))


def _model(blob: dict):
    from chaser_bt.vision.detector.model import DetectorConfig, TinyYolo

    model = TinyYolo(DetectorConfig.from_dict(blob["config"]))
    model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in blob["state_dict"].items()})
    return model.eval()


def _detector_metadata(blob: dict) -> dict:
    """What an ONNX copy of the detector saved as ``blob`` carries in its metadata."""
    return {"config": dict(blob["config"]), "obj_iou": float(blob.get("obj_iou", 0.0))}


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-x))


def decode_head(raw: np.ndarray, stride: int, min_objectness: float = 0.0) -> np.ndarray:
    """:func:`chaser_bt.vision.detector.model.decode` in numpy, for one image: (1, 5 + C, H, W) raw head
    output -> (N, 5 + C) x0, y0, x1, y1 (input pixels), objectness, class probabilities, for the N
    cells whose objectness is at least ``min_objectness`` (a box's score is objectness times a class
    probability, so none scoring below it is lost), in cell order."""
    _, c, h, w = raw.shape
    r = raw[0].reshape(c, h * w)
    obj = _sigmoid(r[0])
    cells = np.flatnonzero(obj >= min_objectness)
    r = r[:, cells]
    gx, gy = (cells % w).astype(raw.dtype), (cells // w).astype(raw.dtype)
    cx = (gx + 2.0 * _sigmoid(r[1]) - 0.5) * stride
    cy = (gy + 2.0 * _sigmoid(r[2]) - 0.5) * stride
    bw, bh = (stride * np.exp(np.clip(r[k], -4.0, 4.5)) for k in (3, 4))
    return np.column_stack([cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2, obj[cells], _sigmoid(r[5:]).T])


def nms(boxes: np.ndarray, scores: np.ndarray, iou_threshold: float) -> list[int]:
    """Greedy non-maximum suppression; indices kept, best first."""
    order = np.argsort(-scores)
    keep: list[int] = []
    while len(order):
        i = int(order[0])
        keep.append(i)
        rest = order[1:]
        lt = np.maximum(boxes[i, :2], boxes[rest, :2])
        rb = np.minimum(boxes[i, 2:], boxes[rest, 2:])
        inter = np.prod(np.clip(rb - lt, 0, None), axis=1)
        area = np.prod(boxes[rest, 2:] - boxes[rest, :2], axis=1) + np.prod(boxes[i, 2:] - boxes[i, :2])
        order = rest[inter / np.maximum(area - inter, 1e-9) <= iou_threshold]
    return keep


class Detector:
    """Frames in, :class:`Detection` lists out.

    Args:
        weights: weights file (default: the shipped one).
        image_size: letterbox size (the network input is image_size x image_size; 416 or 832).
        conf_threshold: minimum score (objectness x class probability) kept.
        iou_threshold: NMS overlap.
        threads: torch (process-wide) or onnxruntime intra-op threads.
        multi_label: report every class above the threshold for a box, not just the best (for AP).
        refiner: the second stage re-placing each box from a full-resolution crop, and re-scoring it when
            it was trained to (:class:`chaser_bt.vision.detector.refine.BoxRefiner`): "auto" = the one shipped
            beside ``weights`` when there is one, a path, or None for none.
        backend: "torch"; "onnx" to run ``onnx_path`` with onnxruntime (optional dependency, measured
            faster on this CPU); "onnx-int8" to run the int8 copy (``onnx_path``, default
            :func:`int8_path` of ``weights``; faster again on a CPU with VNNI); "auto" = onnx-int8 when
            onnxruntime is installed, ``onnx_path`` is not given and the int8 copy exists and is not
            older than ``weights``, else onnx when ``onnx_path`` (default the .onnx copy) exists and is
            not older than ``weights``, else torch. An int8 copy that "auto" picked but onnxruntime
            cannot load is skipped with a warning naming it; an explicit backend's unloadable file is
            an error naming it (FileNotFoundError when missing, ValueError otherwise).
        onnx_path: the ONNX file to run (default: beside ``weights``, ``<stem>.onnx`` for "onnx",
            ``<stem>.int8.onnx`` for "onnx-int8").
    """

    def __init__(self, weights: str | Path = DEFAULT_WEIGHTS, image_size: int = 416, conf_threshold: float = 0.25,
                 iou_threshold: float = 0.45, threads: int = 1, max_detections: int = 20, backend: str = "auto",
                 onnx_path: str | Path | None = None, multi_label: bool = False,
                 refiner: str | Path | None = "auto") -> None:
        if image_size % 32:
            raise ValueError(f"image_size must be a multiple of 32, got {image_size}")
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(repr(b) for b in BACKENDS)}, got {backend!r}")
        weights = Path(weights)
        session = None
        if backend == "auto":
            backend = "torch"
            if have_onnxruntime():
                if onnx_path is None and fresh(int8_path(weights), weights):
                    try:
                        session, backend, onnx_path = ort_session(int8_path(weights), threads), "onnx-int8", int8_path(weights)
                    except ValueError as exc:
                        warnings.warn(f"{exc}; running the float model", RuntimeWarning, stacklevel=2)
                if session is None:
                    onnx_path = weights.with_suffix(".onnx") if onnx_path is None else Path(onnx_path)
                    backend = "onnx" if fresh(onnx_path, weights) else "torch"
        elif onnx_path is None:
            onnx_path = int8_path(weights) if backend == "onnx-int8" else weights.with_suffix(".onnx")
        #: "torch", "onnx" or "onnx-int8": what runs the network.
        self.backend = backend
        #: The ONNX file onnxruntime runs (None with torch).
        self.onnx_path = Path(onnx_path) if backend != "torch" else None
        self.weights = weights
        self._threads = threads
        if backend != "torch" and session is None:
            session = ort_session(self.onnx_path, threads)
        self._session = session
        meta = read_metadata(session) if session is not None else {}
        if "config" not in meta:  # the torch backend, or a copy exported before copies carried their metadata
            import torch

            torch.set_num_threads(threads)
            blob = _load_blob(weights)
            meta = _detector_metadata(blob)
            self.__dict__["model"] = _model(blob)
        #: The weights were trained to score a box by its predicted IoU (``obj_iou``): a low score means a badly placed box.
        self.scores_are_iou = float(meta.get("obj_iou", 0.0)) > 0.0
        self.class_names = tuple(meta["config"]["class_names"])
        self.stride = int(meta["config"]["stride"])
        self.image_size = image_size
        self.conf_threshold = conf_threshold
        self.iou_threshold = iou_threshold
        self.max_detections = max_detections
        self.multi_label = multi_label
        if refiner == "auto":
            refiner = refiner_path(weights) if refiner_path(weights).exists() else None
        self.refiner = BoxRefiner(refiner, threads=threads) if refiner is not None else None

    @functools.cached_property
    def model(self):
        """The torch network (loaded on first use when onnxruntime runs the detector)."""
        import torch

        torch.set_num_threads(self._threads)
        return load_model(self.weights)

    def __call__(self, frame_bgr: np.ndarray) -> list[Detection]:
        return self.detect(frame_bgr)

    def detect(self, frame_bgr: np.ndarray, conf_threshold: float | None = None) -> list[Detection]:
        """The detections in a frame scoring at least ``conf_threshold`` (None: the detector's own)."""
        threshold = self.conf_threshold if conf_threshold is None else conf_threshold
        h, w = frame_bgr.shape[:2]
        if h == w <= self.image_size and h % self.stride == 0:  # a focus window: a size the network takes as it is
            img, scale, (px, py) = frame_bgr, 1.0, (0, 0)
        else:
            img, scale, (px, py) = letterbox(frame_bgr, self.image_size)
        x = network_input(img)
        if self._session is not None:
            raw = self._session.run(None, {"images": x})[0]
        else:
            import torch

            with torch.inference_mode():
                raw = self.model(torch.from_numpy(x)).numpy()
        out = decode_head(raw, self.stride, threshold)
        if self.multi_label:  # one candidate per class and cell (darknet's evaluation), NMS per class
            n, c = len(out), out.shape[1] - 5
            cls = np.repeat(np.arange(c)[None], n, 0).ravel()
            score = (out[:, 4:5] * out[:, 5:]).ravel()
            boxes = np.repeat(out[:, :4], c, 0)
        else:
            cls = out[:, 5:].argmax(1)
            score = out[:, 4] * out[np.arange(len(out)), 5 + cls]
            boxes = out[:, :4]
        m = np.flatnonzero(score >= threshold)
        m = m[np.argsort(-score[m])[:_MAX_NMS]]  # the best few hundred candidates go to the (quadratic) NMS
        boxes, score, cls = boxes[m], score[m], cls[m]
        offset = cls[:, None] * 1e5 if self.multi_label else 0.0  # per-class NMS by shifting classes apart
        keep = nms(boxes + offset, score, self.iou_threshold)[: self.max_detections]
        dets = []
        for i in keep:
            b = (boxes[i] - np.array([px, py, px, py])) / scale
            b = np.clip(b, [0, 0, 0, 0], [w, h, w, h])
            dets.append(Detection((float(b[0]), float(b[1]), float(b[2]), float(b[3])), float(score[i]), int(cls[i]), self.class_names[int(cls[i])]))
        if self.refiner is None:
            return dets
        dets = self.refiner(frame_bgr, dets)
        if self.refiner.config.scores:  # re-scored (never upwards): the threshold holds for the new scores
            dets = sorted((d for d in dets if d.score >= threshold), key=lambda d: -d.score)
        return dets


def shipped_detector(name: str, **kwargs) -> Detector:
    """The shipped detector called ``name`` (a key of :data:`SHIPPED_WEIGHTS`); ``kwargs`` go to :class:`Detector`.

    Raises:
        ValueError: an unknown name (the message lists the known ones).
        FileNotFoundError: the weights are not in the package.
    """
    if name not in SHIPPED_WEIGHTS:
        raise ValueError(f"unknown detector {name!r}; shipped: {sorted(SHIPPED_WEIGHTS)}")
    return Detector(SHIPPED_WEIGHTS[name], **kwargs)


def export_onnx(weights: str | Path, out_path: str | Path, image_size: int = 416) -> Path:
    """Export the raw network (input 1x3xHxW in [0, 1], output the head logits) to ONNX with what it is in its
    metadata (class names, stride, IoU-aware scores; :func:`write_metadata`); needs the onnx package."""
    import torch

    blob = _load_blob(weights)
    torch.onnx.export(_model(blob), (torch.zeros(1, 3, image_size, image_size),), str(out_path), input_names=["images"],
                      output_names=["raw"], opset_version=17, dynamic_axes={"images": {2: "h", 3: "w"}, "raw": {2: "gh", 3: "gw"}},
                      dynamo=False)
    write_metadata(out_path, _detector_metadata(blob))
    return Path(out_path)
