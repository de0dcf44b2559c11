"""Run the trained detector on BGR frames: letterbox, forward, decode, confidence filter, NMS, and
the box refiner shipped beside the weights when there is one (:mod:`chaser_bt.vision.detector.refine`).

The default weights ship in ``chaser_bt/vision/weights/tiny_yolo.pt`` and load without any
download; :data:`SHIPPED_WEIGHTS` names every shipped model (``tiny_yolo``: s1000 and phantom;
``person_yolo``: person, for search and rescue) and :func:`shipped_detector` loads one by name. Torch uses ``threads`` intra-op threads (1 measured fastest on the shared 2-core CPU:
see docs/vision.md). An ONNX copy can be exported with :func:`export_onnx`; with ``backend="auto"`` onnxruntime
runs it when it is installed and the copy beside the weights is not older than them. An int8 copy
(``<stem>.int8.onnx``, :mod:`chaser_bt.vision.detector.quantize`, ``chaser-bt quantize-detector``) is
preferred over the float one by "auto" under the same rule.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import torch

from chaser_bt.vision.detection import Detection
from chaser_bt.vision.detector.augment import letterbox
from chaser_bt.vision.detector.model import DetectorConfig, TinyYolo, decode
from chaser_bt.vision.detector.refine import BoxRefiner, refiner_path

__all__ = ["Detection", "Detector", "DEFAULT_WEIGHTS", "DEFAULT_ONNX", "BACKENDS", "SHIPPED_WEIGHTS", "shipped_detector", "load_model", "nms",
           "export_onnx", "int8_path", "network_input"]

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
    return (np.ascontiguousarray(letterboxed_bgr[..., ::-1].transpose(2, 0, 1), np.float32) / 255.0)[None]


def _fresh(copy: Path, weights: Path) -> bool:
    """``copy`` exists and is not older than ``weights`` (1 s of slack for file systems and checkouts)."""
    return copy.exists() and weights.exists() and copy.stat().st_mtime >= weights.stat().st_mtime - 1.0


def _load_blob(path: str | Path) -> dict:
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"detector weights not found: {p}")
    return torch.load(p, map_location="cpu", weights_only=False)


def load_model(path: str | Path = DEFAULT_WEIGHTS) -> TinyYolo:
    """The detector with weights from ``path`` (a file saved by training), in eval mode, float32."""
    return _model(_load_blob(path))


def _model(blob: dict) -> TinyYolo:
    model = TinyYolo(DetectorConfig.from_dict(blob["config"]))
    model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in blob["state_dict"].items()})
    return model.eval()


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
        refiner: the second stage re-placing each box from a full-resolution crop
            (:class:`chaser_bt.vision.detector.refine.BoxRefiner`): "auto" = the one shipped beside ``weights``
            when there is one, a path, or None for none.
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
            if _have_onnxruntime():
                if onnx_path is None and _fresh(int8_path(weights), weights):
                    try:
                        session, backend, onnx_path = _session(int8_path(weights), threads), "onnx-int8", int8_path(weights)
                    except ValueError as exc:
                        warnings.warn(f"{exc}; running the float model", RuntimeWarning, stacklevel=2)
                if session is None:
                    onnx_path = weights.with_suffix(".onnx") if onnx_path is None else Path(onnx_path)
                    backend = "onnx" if _fresh(onnx_path, weights) else "torch"
        elif onnx_path is None:
            onnx_path = int8_path(weights) if backend == "onnx-int8" else weights.with_suffix(".onnx")
        #: "torch", "onnx" or "onnx-int8": what runs the network.
        self.backend = backend
        #: The ONNX file onnxruntime runs (None with torch).
        self.onnx_path = Path(onnx_path) if backend != "torch" else None
        torch.set_num_threads(threads)
        blob = _load_blob(weights)
        self.model = _model(blob)
        #: The weights were trained to score a box by its predicted IoU (``obj_iou``): a low score means a badly placed box.
        self.scores_are_iou = float(blob.get("obj_iou", 0.0)) > 0.0
        self.class_names = self.model.config.class_names
        self._session = session
        if backend != "torch" and session is None:
            self._session = _session(self.onnx_path, threads)
        self.image_size = image_size
        self.conf_threshold = conf_threshold
        self.iou_threshold = iou_threshold
        self.max_detections = max_detections
        self.multi_label = multi_label
        if refiner == "auto":
            refiner = refiner_path(weights) if refiner_path(weights).exists() else None
        self.refiner = BoxRefiner(refiner) if refiner is not None else None

    def __call__(self, frame_bgr: np.ndarray) -> list[Detection]:
        img, scale, (px, py) = letterbox(frame_bgr, self.image_size)
        x = torch.from_numpy(network_input(img))
        with torch.inference_mode():
            raw = self.model(x) if self._session is None else torch.from_numpy(self._session.run(None, {"images": x.numpy()})[0])
            out = decode(raw, self.model.config.stride)[0].numpy()
        if self.multi_label:  # one candidate per class and cell (darknet's evaluation), NMS per class
            n, c = len(out), out.shape[1] - 5
            cls = np.repeat(np.arange(c)[None], n, 0).ravel()
            score = (out[:, 4:5] * out[:, 5:]).ravel()
            boxes = np.repeat(out[:, :4], c, 0)
        else:
            cls = out[:, 5:].argmax(1)
            score = out[:, 4] * out[np.arange(len(out)), 5 + cls]
            boxes = out[:, :4]
        m = np.flatnonzero(score >= self.conf_threshold)
        m = m[np.argsort(-score[m])[:_MAX_NMS]]  # the best few hundred candidates go to the (quadratic) NMS
        boxes, score, cls = boxes[m], score[m], cls[m]
        offset = cls[:, None] * 1e5 if self.multi_label else 0.0  # per-class NMS by shifting classes apart
        keep = nms(boxes + offset, score, self.iou_threshold)[: self.max_detections]
        h, w = frame_bgr.shape[:2]
        dets = []
        for i in keep:
            b = (boxes[i] - np.array([px, py, px, py])) / scale
            b = np.clip(b, [0, 0, 0, 0], [w, h, w, h])
            dets.append(Detection((float(b[0]), float(b[1]), float(b[2]), float(b[3])), float(score[i]), int(cls[i]), self.class_names[int(cls[i])]))
        return dets if self.refiner is None else self.refiner(frame_bgr, dets)


def shipped_detector(name: str, **kwargs) -> Detector:
    """The shipped detector called ``name`` (a key of :data:`SHIPPED_WEIGHTS`); ``kwargs`` go to :class:`Detector`.

    Raises:
        ValueError: an unknown name (the message lists the known ones).
        FileNotFoundError: the weights are not in the package.
    """
    if name not in SHIPPED_WEIGHTS:
        raise ValueError(f"unknown detector {name!r}; shipped: {sorted(SHIPPED_WEIGHTS)}")
    return Detector(SHIPPED_WEIGHTS[name], **kwargs)


def _session(path: Path, threads: int):
    """An onnxruntime CPU session of ``path``; FileNotFoundError or ValueError naming the file when it cannot load."""
    import onnxruntime

    if not path.is_file():
        raise FileNotFoundError(f"detector ONNX model not found: {path}")
    opts = onnxruntime.SessionOptions()
    opts.intra_op_num_threads = threads
    opts.inter_op_num_threads = 1
    try:
        return onnxruntime.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own classes (InvalidProtobuf, Fail, ...)
        raise ValueError(f"{path}: onnxruntime cannot load it ({type(exc).__name__}: {str(exc).strip()[:200]})") from None


def _have_onnxruntime() -> bool:
    try:
        import onnxruntime  # noqa: F401
    except ImportError:
        return False
    return True


def export_onnx(weights: str | Path, out_path: str | Path, image_size: int = 416) -> Path:
    """Export the raw network (input 1x3xHxW in [0, 1], output the head logits) to ONNX (needs the onnx package)."""
    model = load_model(weights)
    torch.onnx.export(model, (torch.zeros(1, 3, image_size, image_size),), str(out_path), input_names=["images"],
                      output_names=["raw"], opset_version=17, dynamic_axes={"images": {2: "h", 3: "w"}, "raw": {2: "gh", 3: "gw"}},
                      dynamo=False)
    return Path(out_path)
