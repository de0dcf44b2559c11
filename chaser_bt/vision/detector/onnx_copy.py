"""Our ONNX copies of torch networks (the detector, its int8 copy, the box refiner): onnxruntime
sessions, whether a copy is current, and what a copy is (its metadata).

A copy keeps a JSON dict under :data:`METADATA_KEY` in its ``metadata_props`` (the detector's config
and ``obj_iou``, the refiner's crop geometry), so inference reads what the network is from the file
onnxruntime runs, without torch.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

__all__ = ["METADATA_KEY", "write_metadata", "read_metadata", "ort_session", "have_onnxruntime", "fresh"]

#: The ONNX metadata key (``metadata_props``) under which our copies keep a JSON dict of what they are.
METADATA_KEY = "chaser_bt"


def fresh(copy: Path, weights: Path) -> bool:
    """``copy`` exists and is not older than ``weights`` (1 s of slack for file systems and checkouts)."""
    return copy.exists() and weights.exists() and copy.stat().st_mtime >= weights.stat().st_mtime - 1.0


def write_metadata(onnx_path: str | Path, meta: dict) -> None:
    """Store ``meta`` (JSON) in the ONNX file's metadata under :data:`METADATA_KEY` (needs the onnx package)."""
    import onnx

    model = onnx.load(str(onnx_path))
    kept = [(p.key, p.value) for p in model.metadata_props if p.key != METADATA_KEY]
    del model.metadata_props[:]
    for key, value in kept + [(METADATA_KEY, json.dumps(meta, sort_keys=True))]:
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(model, str(onnx_path))


def read_metadata(session: Any) -> dict:
    """The dict :func:`write_metadata` stored in the model an onnxruntime ``session`` runs ({} if none)."""
    text = session.get_modelmeta().custom_metadata_map.get(METADATA_KEY)
    return json.loads(text) if text else {}


def ort_session(path: Path, threads: int):
    """An onnxruntime CPU session of ``path``; FileNotFoundError or ValueError naming the file when it cannot load."""
    import onnxruntime

    if not path.is_file():
        raise FileNotFoundError(f"ONNX model not found: {path}")
    opts = onnxruntime.SessionOptions()
    opts.intra_op_num_threads = threads
    opts.inter_op_num_threads = 1
    # Threads that spin while they wait for work take the core the simulator, the renderer or the
    # tick needs: measured at 320 int8, two threads 3.8 -> 2.2 ms a call spinning (4.3 ms of CPU), 2.4 ms
    # sleeping (3.7 ms of CPU, less than one thread's 3.8).
    opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    try:
        return onnxruntime.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own classes (InvalidProtobuf, Fail, ...)
        raise ValueError(f"{path}: onnxruntime cannot load it ({type(exc).__name__}: {str(exc).strip()[:200]})") from None


def have_onnxruntime() -> bool:
    try:
        import onnxruntime  # noqa: F401
    except ImportError:
        return False
    return True
