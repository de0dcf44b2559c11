"""Vision benchmark: detector quality and speed on a held-out rendered set, pipeline rate,
bearing error and range error in a follow sequence, renderer speed. Prints one JSON line.

Held-out: ``sitl.bench.camera_dataset`` split "heldout" (other ground seeds, wider lighting), seed 777;
the person detector (search and rescue) on a held-out person set, seed 778. Per domain: the
drone detector at 416 on held-out-split frames, half of them chase views, in the training camera-world
families (meadow, farmland, arid, winter, suburb; keys ``*_families``) and in the held-out families
(coast, moor; keys ``*_cross``), seed 779; the plain field is the first set; the person detector
likewise (keys ``*_person_416_families``, ``*_person_416_cross``), seed 779. Pipeline quality: the
share of labelled frames whose reported box is right (IoU >= 0.5), the bearing error p95 at the box
centre on those frames (the acceptance's wording) and on every frame with an estimate.
Speeds are single-threaded (torch and OpenCV), the setting measured fastest on the shared CPU.
Detector figures are the float network's (ONNX when its copy is current, else torch); where an int8
copy (``<stem>.int8.onnx``, ``chaser-bt quantize-detector``) sits beside the weights the same figures
for it follow under the same key with ``_int8`` appended, its frames/s taken right after the float
one's on the same frames (the ratio is what to read on a shared machine). The pipeline follows the
auto backend (int8 when current).
Photographs (``*_416_photo``): the drone detector at 416, class-agnostic, on 300 frames (120 with
``--quick``) of the ``photo`` family (``sitl.bench.photo_family``: drones drawn by their own code over
scikit-image's sample photographs, a source nothing trains on), seed 780; the person detector likewise
on 150 frames (30 with ``--quick``) of people drawn over the same photographs (``*_person_416_photo``), seed 780; null
without scikit-image.
Real footage (``*_real_heldout``): the drone detector at 416, class-agnostic, on the Halmstad
drone-detection dataset's held-out third (``V_DRONE_077``-``114``, ``V_BIRD_035``-``051``,
``V_AIRPLANE_040``-``059``, ``V_HELICOPTER_041``-``061``; every 10th frame; birds, airplanes and helicopters
as negatives), imported from ``--halmstad DIR`` (default ``$CHASER_BT_HALMSTAD``) the way
``chaser-bt import-footage`` does; the keys are null, and stderr says why, without it.
Usage: python benchmarks/bench_vision.py [--quick] [--weights W.pt] [--person-weights P.pt] [--halmstad DIR]
(default: the shipped detectors)
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time

import cv2
import numpy as np
import torch
from scipy.spatial.transform import Rotation

from chaser_bt.vision.camera import CameraModel
from chaser_bt.vision.detector.evaluate import evaluate_detections, frames_per_second, iou_matrix
from chaser_bt.vision.detector.inference import SHIPPED_WEIGHTS, Detector, int8_path
from chaser_bt.vision.frame_source import Frame
from chaser_bt.vision.pipeline import OwnshipPose, PipelineConfig, VisionPipeline
from chaser_bt.vision.projection import Projector
from chaser_bt.vision.range import TARGET_SPAN_M, range_from_box
from sitl.bench.camera_dataset import PERSON_CLASSES, DatasetRenderer, frame_boxes
from sitl.world.camera.renderer import Lighting, Renderer, TargetPose, attitude_from_velocity
from sitl.world.camera.scene import make_ground
from sitl.bench.camera_sequences import follow_sequence

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from record import Benchmark, add_record_flag, emit  # noqa: E402

BENCHMARK = Benchmark(
    "vision", __doc__,
    against="the built-in simulator's rendered held-out sets and follow sequence, drones and people drawn over "
            "scikit-image's photographs, and Halmstad real footage (with --halmstad; its keys null without it)",
    units={
        "ap50_*": "11-point interpolated AP@0.5 (VOC 2007), averaged over classes",
        "p_*": "precision at confidence 0.25", "r_*": "recall at confidence 0.25", "f1_*": "F1 at confidence 0.25",
        "iou_*": "mean IoU of true positives",
        "fps_*": "frames/s, single-threaded, at the input size in the key",
        "real_heldout_images": "images of the Halmstad held-out third (every 10th frame)",
        "pipeline_hz": "follow-sequence frames processed per wall s by the pipeline (detector every 3rd frame)",
        "bearing_err_deg_p95_correct_box": "deg, p95 bearing error at the box centre, frames with a right box (IoU >= 0.5)",
        "bearing_err_deg_p95": "deg, p95 bearing error at the box centre, every frame with an estimate",
        "correct_box_share": "share of labelled frames whose reported box is right (IoU >= 0.5)",
        "range_rel_err_median_bbox_only": "median |range from the box alone - truth| / truth, on detection frames",
        "range_rel_err_median": "median |estimated range - truth| / truth",
        "render_fps_640": "frames/s rendered at 640 x 480, one OpenCV thread",
    },
    headline=("ap50_416", "ap50_416_real_heldout", "ap50_416_cross", "fps_416", "pipeline_hz", "bearing_err_deg_p95_correct_box"),
)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.atan2(np.linalg.norm(np.cross(a, b)), float(np.dot(a, b))))


def variants(weights: str, **kwargs) -> dict[str, Detector]:
    """The float detector (key ""; ONNX when its copy is current, else torch) and, when its int8 copy is
    beside the weights, the int8 one (key "_int8")."""
    from pathlib import Path

    out = {"": Detector(weights, onnx_path=Path(weights).with_suffix(".onnx"), **kwargs)}  # an explicit float file: auto never picks int8
    if int8_path(weights).exists():
        out["_int8"] = Detector(weights, backend="onnx-int8", **kwargs)
    return out


def detector_metrics(n: int, seed: int, weights: str) -> dict:
    """{(size, variant): (metrics, frames/s)}; the variants' frames/s back to back on the same frames."""
    data = DatasetRenderer("heldout")
    rng = np.random.default_rng(seed)
    frames = [data.sample(rng) for _ in range(n)]
    out = {}
    for size in (416, 832):
        dets = variants(weights, image_size=size, conf_threshold=0.005, threads=1)
        metrics = {}
        for key, det in dets.items():
            preds = [[(d.box, d.score, d.class_id) for d in det(f.image)] for f in frames]
            metrics[key] = evaluate_detections(preds, [frame_boxes(f) for f in frames], len(det.class_names))
        for key, det in dets.items():
            det.conf_threshold = 0.25
            out[size, key] = (metrics[key], frames_per_second(det, [f.image for f in frames[: min(n, 100)]]))
    return out


TRAINING_FAMILIES = ("meadow", "farmland", "arid", "winter", "suburb")
HELDOUT_FAMILIES = ("coast", "moor")


def domain_metrics(n: int, seed: int, weights: str) -> dict:
    """AP@0.5, precision and recall at 0.25 of the drone detector at 416 in the training and the held-out
    camera-world families (held-out split, half the frames chase views)."""
    out = {}
    dets = variants(weights, image_size=416, conf_threshold=0.005, threads=1)
    for key, families in (("families", TRAINING_FAMILIES), ("cross", HELDOUT_FAMILIES)):
        frames = _render(DatasetRenderer("heldout", follow_share=0.5, families=families), n, seed)
        out.update(_scores(dets, frames, f"_416_{key}"))
    return out


def _render(data: DatasetRenderer, n: int, seed: int) -> list:
    rng = np.random.default_rng(seed)
    return [data.sample(rng) for _ in range(n)]


def _scores(dets: dict[str, Detector], frames: list, infix: str, classes: tuple[str, ...] | None = None) -> dict:
    """``ap50{infix}{variant}``, ``p``, ``r`` and ``iou`` of each detector variant on ``frames``."""
    out = {}
    for v, det in dets.items():
        preds = [[(d.box, d.score, d.class_id) for d in det(f.image)] for f in frames]
        truth = [frame_boxes(f) if classes is None else frame_boxes(f, classes) for f in frames]
        m = evaluate_detections(preds, truth, len(det.class_names))
        out.update({f"ap50{infix}{v}": round(m.ap50, 4), f"p{infix}{v}": round(m.precision, 4),
                    f"r{infix}{v}": round(m.recall, 4), f"iou{infix}{v}": round(m.iou, 4)})
    return out


def person_metrics(n: int, seed: int, weights: str) -> dict:
    """AP@0.5 etc. of the person detector at 416 on held-out person frames: the plain field (seed ``seed``;
    keys ``*_person_416``) and, on ``n // 2`` frames each, the training and the held-out camera-world
    families (seed ``seed + 1``; keys ``*_person_416_families``, ``*_person_416_cross``), and people drawn over
    photographs (the ``photo`` family, seed ``seed + 2``; keys ``*_person_416_photo``); {} without weights."""
    from pathlib import Path

    if not Path(weights).exists():
        return {}
    dets = variants(weights, image_size=416, conf_threshold=0.005, threads=1)
    plain = _render(DatasetRenderer("heldout", kinds=PERSON_CLASSES), n, seed)
    out = _scores(dets, plain, "_person_416", PERSON_CLASSES)
    for key, families in (("families", TRAINING_FAMILIES), ("cross", HELDOUT_FAMILIES)):
        frames = _render(DatasetRenderer("heldout", kinds=PERSON_CLASSES, families=families), n // 2, seed + 1)
        out.update(_scores(dets, frames, f"_person_416_{key}", PERSON_CLASSES))
    out.update(photo_metrics(n // 2, seed + 2, weights, kind="person"))
    for v, det in dets.items():
        det.conf_threshold = 0.25
        out[f"fps_person_416{v}"] = round(frames_per_second(det, [f.image for f in plain[: min(n, 100)]]), 1)
    return out


def follow_metrics(n: int, seed: int, weights: str) -> dict:
    cam = CameraModel(width_px=640, height_px=480)
    views = list(follow_sequence(cam, n, seed))
    det = Detector(weights, image_size=416, threads=1)
    pipe = VisionPipeline(cam, det, PipelineConfig(detect_every=3))
    proj = Projector(cam)
    fx = cam.focal_px[0]
    est_err, box_err, bearing_err, bearing_err_correct, correct = [], [], [], [], 0
    t0 = time.perf_counter()
    results = []
    for k, v in enumerate(views):
        est = pipe.process(Frame(v.t, v.image, k), OwnshipPose(v.t, v.position_enu, v.velocity_enu, v.attitude_measured))
        results.append((est, pipe.track.box if pipe.track is not None and est is not None else None, pipe.track, pipe.smoother.attitude))
    elapsed = time.perf_counter() - t0
    projection_err = []
    for v, (est, box, track, smoothed) in zip(views, results):
        if v.label is None:
            continue
        true_range = float(np.linalg.norm(v.target_enu - cam.position_enu(v.position_enu, v.attitude_true)))
        right = box is not None and iou_matrix(np.array([box]), np.array([v.label.box]))[0, 0] >= 0.5
        correct += right
        if est is not None:
            est_err.append(abs(est.range_m - true_range) / true_range)
            # Bearing at the box centre vs the true ray through the true box centre.
            lb = v.label.box
            true_ray = proj.bearing_enu(np.array([[(lb[0] + lb[2]) / 2, (lb[1] + lb[3]) / 2]]), v.attitude_true)[0]
            bearing_err.append(_angle_deg(est.bearing_enu, true_ray))
            if right:
                bearing_err_correct.append(bearing_err[-1])
            # Projection alone: the true box centre through the smoothed, IMU-noisy attitude.
            lb_c = np.array([[(lb[0] + lb[2]) / 2, (lb[1] + lb[3]) / 2]])
            projection_err.append(_angle_deg(proj.bearing_enu(lb_c, smoothed)[0], true_ray))
        if track is not None and track.t_detected == v.t and box is not None:
            box_err.append(abs(range_from_box(box, TARGET_SPAN_M[track.class_name], 320.0, fx) - true_range) / true_range)
    labelled = sum(v.label is not None for v in views)
    return {"pipeline_hz": len(views) / elapsed, "correct_box_share": correct / max(labelled, 1),
            "bearing_err_deg_p95": float(np.percentile(bearing_err, 95)) if bearing_err else float("nan"),
            "bearing_err_deg_p95_correct_box": float(np.percentile(bearing_err_correct, 95)) if bearing_err_correct else float("nan"),
            "range_rel_err_median": float(np.median(est_err)) if est_err else float("nan"),
            "range_rel_err_median_bbox_only": float(np.median(box_err)) if box_err else float("nan"),
            "estimate_share": len(est_err) / max(labelled, 1),
            "projection_only_bearing_err_deg_p95": float(np.percentile(projection_err, 95)) if projection_err else float("nan")}


def render_fps(n: int) -> float:
    cam = CameraModel(width_px=640, height_px=480)
    r = Renderer(cam, make_ground(1004))
    rng = np.random.default_rng(3)
    att = [Rotation.from_euler("ZYX", [0.01 * k, 0.05, 0.02]) for k in range(n)]
    tg = [TargetPose("s1000", np.array([15.0, 3.0, 28.0]), attitude_from_velocity(np.array([3.0, 1.0, 0.0])))]
    t0 = time.perf_counter()
    for k in range(n):
        r.render(np.array([0.0, 0.0, 30.0]), att[k], tg, Lighting(), rng, blur_px=3.0)
    return n / (time.perf_counter() - t0)


def photo_metrics(n: int, seed: int, weights: str, kind: str = "drone") -> dict:
    """AP@0.5, precision, recall and IoU (keys ``*_416_photo``, ``*_person_416_photo`` for people, and their
    ``_int8``) of the drone or person detector, class-agnostic, on ``n`` frames of the ``photo`` family of
    ``kind``; nulls without scikit-image."""
    infix = "_416_photo" if kind == "drone" else "_person_416_photo"
    try:
        from sitl.bench.photo_family import PhotoFamily

        family = PhotoFamily(kind=kind)
    except ImportError:
        print(f"bench_vision: no scikit-image (pip install scikit-image): *{infix} are null", file=sys.stderr)
        return dict.fromkeys(f"{m}{infix}{v}" for v in ("", "_int8") for m in ("ap50", "p", "r", "iou"))
    rng = np.random.default_rng(seed)
    frames = [family.sample(rng) for _ in range(n)]
    out = {}
    for v, det in variants(weights, image_size=416, conf_threshold=0.005, threads=1).items():
        preds = [[(d.box, d.score, 0) for d in det(f.image)] for f in frames]
        m = evaluate_detections(preds, [f.boxes for f in frames], 1)
        out.update({f"ap50{infix}{v}": round(m.ap50, 4), f"p{infix}{v}": round(m.precision, 4),
                    f"r{infix}{v}": round(m.recall, 4), f"iou{infix}{v}": round(m.iou, 4)})
    return out


def real_heldout_metrics(root: str, weights: str) -> dict:
    """AP@0.5, precision and recall at 0.25 (keys ``*_416_real_heldout`` and their ``_int8``) of the drone
    detector, class-agnostic, on the Halmstad held-out third; nulls without the dataset."""
    from pathlib import Path

    from chaser_bt.vision.commands import evaluate_folder
    from chaser_bt.vision.footage.halmstad import import_halmstad

    keys = [f"{m}_416_real_heldout{v}" for v in ("", "_int8") for m in ("ap50", "p", "r")]
    if not root:
        print("bench_vision: no Halmstad dataset (--halmstad DIR or $CHASER_BT_HALMSTAD): *_real_heldout are null",
              file=sys.stderr)
        return dict.fromkeys(keys)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        import_halmstad(root, tmp, parts=("test",), every=10)
        backends = {"": "onnx", "_int8": "onnx-int8"} if int8_path(weights).exists() else {"": "onnx"}
        for v, backend in backends.items():
            m = evaluate_folder(Path(tmp) / "test", weights, 416, backend=backend, class_agnostic=True)
            out.update({f"ap50_416_real_heldout{v}": round(m["ap50"], 4), f"p_416_real_heldout{v}": round(m["precision"], 4),
                        f"r_416_real_heldout{v}": round(m["recall"], 4)})
            out["real_heldout_images"] = m["images"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--weights", default=str(SHIPPED_WEIGHTS["tiny_yolo"]), help="drone detector weights (default: the shipped ones)")
    ap.add_argument("--person-weights", default=str(SHIPPED_WEIGHTS["person_yolo"]),
                    help="person detector weights (default: the shipped ones)")
    ap.add_argument("--halmstad", default=os.environ.get("CHASER_BT_HALMSTAD", ""), metavar="DIR",
                    help="the Halmstad drone-detection dataset's folder, for the *_real_heldout keys (default $CHASER_BT_HALMSTAD)")
    add_record_flag(ap)
    args = ap.parse_args()
    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    n_det, n_follow, n_render = (120, 240, 60) if args.quick else (600, 900, 300)
    det = detector_metrics(n_det, 777, args.weights)
    domains = domain_metrics(n_det // 4 if args.quick else n_det // 2, 779, args.weights)
    person = person_metrics(n_det // 2, 778, args.person_weights)
    fol = follow_metrics(n_follow, 5, args.weights)
    real = real_heldout_metrics(args.halmstad, args.weights)
    photo = photo_metrics(n_det // 2, 780, args.weights)
    det_backend = Detector(args.weights).backend
    figures = {}
    for v in sorted({v for _, v in det}):
        m416, fps416 = det[416, v]
        m832, fps832 = det[832, v]
        figures.update({f"ap50_416{v}": round(m416.ap50, 4), f"ap50_832{v}": round(m832.ap50, 4), f"iou_416{v}": round(m416.iou, 4),
                        f"p_416{v}": round(m416.precision, 4), f"r_416{v}": round(m416.recall, 4), f"f1_416{v}": round(m416.f1, 4),
                        f"fps_416{v}": round(fps416, 1), f"fps_832{v}": round(fps832, 1)})
    emit({
        "name": "vision",
        **figures,
        **domains,
        **real,
        **photo,
        "pipeline_hz": round(fol["pipeline_hz"], 1),
        "bearing_err_deg_p95": round(fol["bearing_err_deg_p95"], 3),
        "correct_box_share": round(fol["correct_box_share"], 4),
        "bearing_err_deg_p95_correct_box": round(fol["bearing_err_deg_p95_correct_box"], 3),
        "range_rel_err_median": round(fol["range_rel_err_median"], 4),
        "range_rel_err_median_bbox_only": round(fol["range_rel_err_median_bbox_only"], 4),
        "render_fps_640": round(render_fps(n_render), 1),
        **person,
    }, BENCHMARK, args.record)
    # Diagnostics beside the figures, on stderr.
    print(json.dumps({"estimate_share": round(fol["estimate_share"], 4),
                      "projection_only_bearing_err_deg_p95": round(fol["projection_only_bearing_err_deg_p95"], 3),
                      "detector_backend": det_backend}), file=sys.stderr)


if __name__ == "__main__":
    main()
