"""Second-stage box refinement: a detection's box re-placed from a full-resolution crop around it.

The detector sees a 640 x 480 frame shrunk to 416 and places boxes on a stride-8 grid, so a box's
centre is off by a pixel or two, more over clutter (a road under the target). As in two-stage
detectors (R-CNN's box head), a small network looks again at a square crop of the frame around each
detection (``context`` times its larger side, resized to ``input_px``) and regresses the target's
box in crop coordinates. It is trained on rendered frames with the labels jittered the way the
detector errs (:func:`make_refiner_set`, :func:`train_refiner`) and ships beside the detector whose
classes it knows, as ``<detector>_refiner.pt`` (:func:`refiner_path`), with an ONNX copy
(``<detector>_refiner.onnx``, :func:`refiner_onnx_path`) that onnxruntime runs.

A refiner may also score (``RefinerConfig.scores``; R-CNN's box head classifies as well as regresses):
trained besides on crops around the detector's own false boxes on the training frames
(:func:`false_detections`, :func:`make_negative_set`), it says how likely each crop holds a target,
and the detection's score becomes the detector's times that probability. The full-resolution
crop sees a target the 416 input shrank away, which is where a single-stage detector's false boxes on
bushes and rocks are told apart.

This module runs the refiner without torch when that copy is there (torch costs seconds to import and
the copy runs a crop in a third of torch's time); the network, its training and the export are in
:mod:`chaser_bt.vision.detector.refine_net` (torch), whose names are also reachable from here.
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import cv2
import numpy as np

from chaser_bt.vision.detection import Detection
from chaser_bt.vision.detector.evaluate import iou_matrix
from chaser_bt.vision.detector.onnx_copy import fresh, have_onnxruntime, ort_session, read_metadata, write_metadata

__all__ = ["RefinerConfig", "BoxRefinerNet", "BoxRefiner", "refiner_path", "refiner_onnx_path", "crop_window", "jitter_boxes",
           "make_refiner_set", "false_detections", "make_negative_set", "train_refiner", "load_refiner_net", "export_refiner_onnx"]
_TORCH_NAMES = ("BoxRefinerNet", "train_refiner")


def __getattr__(name: str) -> Any:  # the torch half, imported when asked for (PEP 562)
    if name in _TORCH_NAMES:
        from chaser_bt.vision.detector import refine_net

        return getattr(refine_net, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def refiner_path(detector_weights: str | Path) -> Path:
    """Where the refiner paired with ``detector_weights`` lives: beside it, named ``<stem>_refiner.pt``."""
    p = Path(detector_weights)
    return p.with_name(f"{p.stem}_refiner.pt")


def refiner_onnx_path(refiner_weights: str | Path) -> Path:
    """The refiner's ONNX copy: beside its weights, ``<stem>.onnx``."""
    return Path(refiner_weights).with_suffix(".onnx")


@dataclass(frozen=True)
class RefinerConfig:
    """Crop geometry and network width; ``scores``: the network also scores each crop (a target or not)."""

    input_px: int = 64
    context: float = 1.6
    min_side_px: float = 24.0
    widths: tuple[int, ...] = (16, 32, 64, 64)
    scores: bool = False

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "RefinerConfig":
        return cls(int(d["input_px"]), float(d["context"]), float(d["min_side_px"]), tuple(d["widths"]), bool(d.get("scores", False)))


def crop_window(box: Sequence[float], config: RefinerConfig) -> tuple[float, float, float]:
    """(x0, y0, side) of the square crop around ``box``: ``context`` times its larger side, at least ``min_side_px``."""
    cx, cy = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
    side = max(config.context * max(box[2] - box[0], box[3] - box[1]), config.min_side_px)
    return cx - side / 2, cy - side / 2, side


def _crops(image: np.ndarray, windows: Sequence[tuple[float, float, float]], px: int) -> np.ndarray:
    """(N, px, px, 3) crops of ``image`` (outside the frame: border replicated), by affine warps."""
    out = np.empty((len(windows), px, px, 3), np.uint8)
    for k, (x0, y0, side) in enumerate(windows):
        s = px / side
        m = np.array([[s, 0.0, -x0 * s], [0.0, s, -y0 * s]])
        out[k] = cv2.warpAffine(image, m, (px, px), flags=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out


def _fractions(boxes: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """(N, 4) frame-pixel boxes as fractions of their (N, 3) x0, y0, side crop windows."""
    return (boxes - windows[:, [0, 1, 0, 1]]) / windows[:, [2, 2, 2, 2]]


class BoxRefiner:
    """Detections in, the same detections with refined boxes out.

    Args:
        weights: a file written by :func:`train_refiner`.
        max_shift: a refined box whose centre moved more than this many of the old box's sizes is
            not trusted and the old box kept (the crop held something else).
        backend: "auto" = onnxruntime on the ONNX copy (:func:`refiner_onnx_path`) when it is installed
            and the copy exists, carries its crop geometry and is not older than ``weights``, else torch;
            "torch" or "onnx" to choose (an "onnx" copy that is missing or cannot load is an error).
        threads: onnxruntime's intra-op threads (torch's are process-wide: the detector sets them).
    """

    def __init__(self, weights: str | Path, max_shift: float = 0.5, backend: str = "auto", threads: int = 1) -> None:
        p = Path(weights)
        if not p.exists():
            raise FileNotFoundError(f"box refiner weights not found: {p}")
        if backend not in ("auto", "torch", "onnx"):
            raise ValueError(f"backend must be 'auto', 'torch' or 'onnx', got {backend!r}")
        self.max_shift = max_shift
        self._session = self._net = None
        onnx = refiner_onnx_path(p)
        if backend == "onnx" or (backend == "auto" and fresh(onnx, p)):
            try:
                if not have_onnxruntime():
                    raise ValueError("onnxruntime is not installed")
                session = ort_session(onnx, threads)
                meta = read_metadata(session)
                if "refiner_config" not in meta:
                    raise ValueError(f"{onnx}: no refiner_config in its metadata (export it with export_refiner_onnx)")
                self._session, self.config = session, RefinerConfig.from_dict(meta["refiner_config"])
            except (ValueError, FileNotFoundError) as exc:
                if backend == "onnx":
                    raise
                warnings.warn(f"{exc}; running the refiner in torch", RuntimeWarning, stacklevel=2)
        if self._session is None:
            self._net = load_refiner_net(p)
            self.config = self._net.config
        #: "onnx" or "torch": what runs the network.
        self.backend = "onnx" if self._session is not None else "torch"

    @property
    def net(self):
        """The torch network (loaded on first use when onnxruntime runs the refiner)."""
        if self._net is None:
            raise AttributeError("this refiner runs its ONNX copy; load the torch network with load_refiner_net")
        return self._net

    def _run(self, crops: np.ndarray, given: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(N, P, P, 3) BGR crops and (N, 4) given boxes (crop fractions) -> (N, 4) refined fractions and,
        for a scoring refiner, (N,) target probabilities (else None)."""
        if self._session is not None:
            x = np.ascontiguousarray(crops[..., ::-1].transpose(0, 3, 1, 2), np.float32) / np.float32(255.0)
            out = self._session.run(None, {"crops": x, "boxes": given})
        else:
            import torch

            from chaser_bt.vision.detector.refine_net import _to_tensor

            with torch.inference_mode():
                out = self._net(_to_tensor(crops), torch.from_numpy(given))
            out = [t.numpy() for t in out] if isinstance(out, tuple) else [out.numpy()]
        prob = 1.0 / (1.0 + np.exp(-out[1].reshape(-1).astype(float))) if len(out) > 1 else None
        return out[0], prob

    def refine(self, image: np.ndarray, boxes: Sequence[Sequence[float]]) -> tuple[np.ndarray, np.ndarray | None]:
        """(N, 4) refined boxes (frame pixels) for ``boxes`` and, for a scoring refiner, (N,) probabilities
        that each box's crop holds a target (else None)."""
        if len(boxes) == 0:
            return np.zeros((0, 4)), (np.zeros(0) if self.config.scores else None)
        old = np.asarray(boxes, float)
        windows = [crop_window(b, self.config) for b in old]
        w = np.array(windows, float)
        frac, prob = self._run(_crops(image, windows, self.config.input_px), _fractions(old, w).astype(np.float32))
        out = w[:, [0, 1, 0, 1]] + frac * w[:, [2, 2, 2, 2]]
        size = np.maximum(old[:, 2:] - old[:, :2], 1.0).max(1)
        shift = np.linalg.norm(0.5 * (out[:, :2] + out[:, 2:] - old[:, :2] - old[:, 2:]), axis=1)
        bad = (shift > self.max_shift * size) | (out[:, 2] <= out[:, 0]) | (out[:, 3] <= out[:, 1])
        out[bad] = old[bad]
        return out, prob

    def boxes(self, image: np.ndarray, boxes: Sequence[Sequence[float]]) -> np.ndarray:
        """(N, 4) refined boxes (frame pixels) for ``boxes``."""
        return self.refine(image, boxes)[0]

    def __call__(self, image: np.ndarray, detections: Sequence[Detection]) -> list[Detection]:
        """The detections with refined boxes; a scoring refiner multiplies each score by its probability
        that the crop holds a target (the geometric mean ranks the same but moved boxes under 0.25 over it:
        person precision at 0.25 on held-out families 0.46 against 0.81, docs/vision.md)."""
        h, w = image.shape[:2]
        new, prob = self.refine(image, [d.box for d in detections])
        new = np.clip(new, 0, [w, h, w, h])
        scores = [d.score for d in detections] if prob is None else [d.score * p for d, p in zip(detections, prob)]
        return [Detection(tuple(float(v) for v in b), float(s), d.class_id, d.class_name) for b, s, d in zip(new, scores, detections)]


def jitter_boxes(box: np.ndarray, n: int, rng: np.random.Generator, shift_sigma: float = 0.12, scale_sigma: float = 0.2) -> np.ndarray:
    """``n`` boxes around ``box`` as a detector misplaces it: centre moved by N(0, shift_sigma * size)
    per axis (a fifth of them three times as far), each side's length scaled by exp(N(0, scale_sigma))."""
    x0, y0, x1, y1 = box
    w, h = x1 - x0, y1 - y0
    far = np.where(rng.random(n) < 0.2, 3.0, 1.0)[:, None]
    c = np.array([(x0 + x1) / 2, (y0 + y1) / 2]) + rng.normal(0, shift_sigma, (n, 2)) * far * np.array([w, h])
    s = np.array([w, h]) * np.exp(rng.normal(0, scale_sigma, (n, 2)))
    return np.concatenate([c - s / 2, c + s / 2], 1)


def make_refiner_set(images: Sequence[np.ndarray], boxes: Sequence[np.ndarray], config: RefinerConfig, per_label: int,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Crops (N, P, P, 3), the jittered boxes they were cut around and the label boxes (both (N, 4),
    crop fractions) from frames and their (M, 5) class, x0, y0, x1, y1 labels: ``per_label`` crops
    around jittered copies of each label (none for labels under 2 px, or frames without one)."""
    crops = [np.zeros((0, config.input_px, config.input_px, 3), np.uint8)]
    given, targets = [np.zeros((0, 4))], [np.zeros((0, 4))]
    for image, labels in zip(images, boxes):
        for lb in np.asarray(labels, float).reshape(-1, 5)[:, 1:]:
            if min(lb[2] - lb[0], lb[3] - lb[1]) < 2.0:
                continue
            jittered = jitter_boxes(lb, per_label, rng)
            windows = [crop_window(b, config) for b in jittered]
            crops.append(_crops(image, windows, config.input_px))
            w = np.array(windows, float)
            given.append(_fractions(jittered, w))
            targets.append(_fractions(lb[None, :], w))
    return np.concatenate(crops), np.concatenate(given).astype(np.float32), np.concatenate(targets).astype(np.float32)


def false_detections(detect: Callable[[np.ndarray], Sequence[Detection]], images: Sequence[np.ndarray],
                     labels: Sequence[np.ndarray], max_iou: float = 0.3) -> list[np.ndarray]:
    """Per frame, the (K, 4) boxes ``detect`` finds that overlap no label (IoU below ``max_iou``): the
    detector's false boxes, the negatives a scoring refiner learns from (hard-negative mining)."""
    out = []
    for image, lab in zip(images, labels):
        boxes = np.array([d.box for d in detect(image)], float).reshape(-1, 4)
        gt = np.asarray(lab, float).reshape(-1, 5)[:, 1:]
        keep = np.ones(len(boxes), bool) if len(gt) == 0 else iou_matrix(boxes, gt).max(1) < max_iou
        out.append(boxes[keep])
    return out


def make_negative_set(images: Sequence[np.ndarray], false_boxes: Sequence[np.ndarray], config: RefinerConfig) -> tuple[np.ndarray, np.ndarray]:
    """Crops (N, P, P, 3) around the false boxes of each frame and those boxes as crop fractions (N, 4)."""
    crops, given = [np.zeros((0, config.input_px, config.input_px, 3), np.uint8)], [np.zeros((0, 4))]
    for image, boxes in zip(images, false_boxes):
        if len(boxes):
            windows = [crop_window(b, config) for b in boxes]
            crops.append(_crops(image, windows, config.input_px))
            given.append(_fractions(np.asarray(boxes, float), np.array(windows, float)))
    return np.concatenate(crops), np.concatenate(given).astype(np.float32)



def load_refiner_net(weights: str | Path):
    """The torch refiner network (:class:`~chaser_bt.vision.detector.refine_net.BoxRefinerNet`) saved by
    :func:`train_refiner` at ``weights``, in eval mode, float32."""
    import torch

    from chaser_bt.vision.detector.refine_net import BoxRefinerNet

    blob = torch.load(Path(weights), map_location="cpu", weights_only=False)
    net = BoxRefinerNet(RefinerConfig.from_dict(blob["config"]))
    net.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in blob["state_dict"].items()})
    return net.eval()


def export_refiner_onnx(weights: str | Path, out_path: str | Path | None = None) -> Path:
    """Export the refiner at ``weights`` to ONNX (default: beside it, :func:`refiner_onnx_path`), inputs
    ``crops`` (B, 3, P, P) RGB in [0, 1] and ``boxes`` (B, 4), output ``refined`` (B, 4), with its crop
    geometry in the file's metadata so onnxruntime runs it without torch (needs torch and the onnx package)."""
    from chaser_bt.vision.detector.refine_net import export_network_onnx

    net = load_refiner_net(weights)
    out = Path(out_path) if out_path is not None else refiner_onnx_path(weights)
    export_network_onnx(net, out)
    write_metadata(out, {"refiner_config": net.config.to_dict()})
    return out
