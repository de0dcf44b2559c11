"""An int8 copy of the detector's ONNX network, made with onnxruntime's own quantization tooling.

Why: in a camera-on rehearsal the detector runs on every frame and is the largest single cost; on
a CPU with AVX512-VNNI (and AMX-INT8) onnxruntime's int8 convolutions are faster than its fp32
ones. What: static quantization (:func:`onnxruntime.quantization.quantize_static`) in QDQ form,
weights int8 per output channel (symmetric), activations uint8 with ranges calibrated on frames
put through the detector's own letterbox (the network's real inputs); onnxruntime fuses the
QuantizeLinear/DequantizeLinear pairs around each Conv into an integer convolution when it loads
the model. Activation ranges are the 99.999th percentile of what the calibration frames produce
(min-max and entropy were measured too). The stem (the two stride-2 convolutions that read the RGB
input) and the head (the raw logits that decode reads as box sizes and scores) stay float by default:
keeping the stem's second convolution float too cost 8 % of the int8 copy's speed and won back the
drone detector's held-out AP (docs/vision.md has the figures with and without each). Calibration
frames must come from training data only (here: the plain field and the training camera-world
families), never from the held-out sets the result is scored on.

Nothing here is hand-written quantization: the calibration reader only feeds frames.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from chaser_bt.vision.detector.augment import letterbox
from chaser_bt.vision.detector.inference import int8_path, network_input
from chaser_bt.vision.detector.onnx_copy import METADATA_KEY, write_metadata

__all__ = ["DEFAULT_EXCLUDE", "CALIBRATION_METHODS", "FrameReader", "int8_path", "quantize_detector", "read_frames"]

#: Node-name prefixes of the layers kept float by default: the stem (input side) and the head (output).
DEFAULT_EXCLUDE: tuple[str, ...] = ("/stem/", "/head/")
CALIBRATION_METHODS = ("minmax", "percentile", "entropy")


def read_frames(folders: Iterable[str | Path], limit: int = 0) -> list[np.ndarray]:
    """BGR frames (``.jpg``/``.png``) from each folder or its ``images/`` subfolder (YOLO layout), sorted by name;
    at most ``limit`` in all (0: every one), taken evenly across the folders."""
    import cv2

    lists = []
    for folder in folders:
        root = Path(folder)
        src = root / "images" if (root / "images").is_dir() else root
        paths = sorted(p for p in src.glob("*") if p.suffix.lower() in (".jpg", ".jpeg", ".png"))
        if not paths:
            raise ValueError(f"{src}: no .jpg or .png images")
        lists.append(paths)
    if limit:
        per = max(1, limit // len(lists))
        lists = [paths[:: max(1, len(paths) // per)][:per] for paths in lists]
    frames = []
    for p in (p for paths in lists for p in paths):
        img = cv2.imread(str(p), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"{p}: not a readable image")
        frames.append(img)
    return frames


class FrameReader:
    """onnxruntime's calibration data reader over BGR frames, each letterboxed and scaled as :class:`Detector` does."""

    def __init__(self, frames: Sequence[np.ndarray], image_size: int = 416, input_name: str = "images") -> None:
        self._inputs = [network_input(letterbox(f, image_size)[0]) for f in frames]
        self._name = input_name
        self._next, self._end = 0, len(self._inputs)

    def __len__(self) -> int:
        return len(self._inputs)

    def get_next(self) -> dict | None:
        if self._next >= self._end:
            return None
        self._next += 1
        return {self._name: self._inputs[self._next - 1]}

    def rewind(self) -> None:
        self._next, self._end = 0, len(self._inputs)

    def set_range(self, start_index: int, end_index: int) -> None:
        """Read frames ``start_index`` to ``end_index`` next (onnxruntime's strided calibration: bounded memory)."""
        self._next, self._end = start_index, min(end_index, len(self._inputs))


def quantize_detector(onnx_in: str | Path, out: str | Path, frames: Sequence[np.ndarray], image_size: int = 416,
                      exclude: Sequence[str] = DEFAULT_EXCLUDE, per_channel: bool = True, method: str = "percentile",
                      percentile: float = 99.999) -> Path:
    """Write the int8 (QDQ) copy of the float network ``onnx_in`` to ``out``, calibrated on ``frames`` (BGR).

    Args:
        exclude: node-name prefixes of layers left float (default: the stem and the head).
        per_channel: one weight scale per output channel (else per tensor).
        method: activation range calibration, "percentile" (at ``percentile``; measured best here), "minmax"
            or "entropy" (onnxruntime's defaults, 128 bins, come out the same as min-max for this network).

    Calibration runs in chunks of at most 40 frames (onnxruntime's ``CalibStridedMinMax``, which merges
    the ranges or histograms), so memory stays bounded (~2 GB peak for 240 frames at 416).
    """
    import onnx
    from onnxruntime.quantization import CalibrationDataReader, CalibrationMethod, QuantFormat, QuantType, quantize_static
    from onnxruntime.quantization.shape_inference import quant_pre_process

    if method not in CALIBRATION_METHODS:
        raise ValueError(f"method must be one of {CALIBRATION_METHODS}, got {method!r}")
    if not frames:
        raise ValueError("no calibration frames")
    model = onnx.load(str(onnx_in))
    input_name = model.graph.input[0].name
    keep_float = [n.name for n in model.graph.node if any(n.name.startswith(e) for e in exclude)]

    class _Reader(FrameReader, CalibrationDataReader):
        pass

    reader = _Reader(frames, image_size, input_name)
    calibrate = {"minmax": CalibrationMethod.MinMax, "percentile": CalibrationMethod.Percentile,
                 "entropy": CalibrationMethod.Entropy}[method]
    extra = {"CalibPercentile": percentile} if method == "percentile" else {}
    extra["CalibStridedMinMax"] = max(d for d in range(1, 41) if len(frames) % d == 0)  # must divide the frame count
    with tempfile.TemporaryDirectory() as tmp:
        pre = Path(tmp) / "pre.onnx"
        quant_pre_process(str(onnx_in), str(pre), skip_symbolic_shape=True)  # shape inference and graph clean-up
        quantize_static(str(pre), str(out), reader, quant_format=QuantFormat.QDQ, activation_type=QuantType.QUInt8,
                        weight_type=QuantType.QInt8, per_channel=per_channel, calibrate_method=calibrate,
                        nodes_to_exclude=keep_float, extra_options=extra)
    meta = {p.key: p.value for p in model.metadata_props}.get(METADATA_KEY)
    if meta is not None:  # what the network is travels with the copy (inference reads it without torch)
        write_metadata(out, json.loads(meta))
    return Path(out)
