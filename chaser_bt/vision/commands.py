"""``chaser-bt train-detector``, ``train-refiner``, ``eval-detector`` and ``quantize-detector`` (wired into
chaser_bt/cli.py by add_command).

Data folders are in YOLO layout (images/*.jpg, labels/*.txt, classes.txt); render them with
``python -m sitl.bench.camera_dataset OUT --split train|heldout``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

from chaser_bt.cli_args import (non_negative_float, non_negative_int, output_dir, output_file, positive_float,
                                positive_int, seed)

__all__ = ["add_command", "evaluate_folder"]


def evaluate_folder(data_dir: str | Path, weights: str | Path, image_size: int, threads: int = 1, limit: int = 0,
                    backend: str = "auto", class_agnostic: bool = False, failures: str | Path | None = None) -> dict:
    """Metrics (model card) and frames/s of the detector on a YOLO folder at ``image_size``;
    ``class_agnostic`` scores every box as one class (footage labelled ``drone`` against a detector
    that tells drone designs apart), else the folder's classes must be the detector's; ``failures``
    names a PNG to draw the worst false boxes and misses at 0.25 into."""
    from chaser_bt.vision.detector.evaluate import (
        evaluate_detections,
        frames_per_second,
    )
    from chaser_bt.vision.detector.inference import Detector

    root = Path(data_dir)
    paths = sorted((root / "images").glob("*.jpg"))
    if limit:
        paths = paths[:limit]
    if not paths:
        raise ValueError(f"{root / 'images'}: no .jpg images")
    det = Detector(weights, image_size=image_size, conf_threshold=0.005, threads=threads, backend=backend)
    names = det.class_names
    listed = root / "classes.txt"
    folder_names = tuple(x.strip() for x in listed.read_text().splitlines() if x.strip()) if listed.exists() else names
    if not class_agnostic and folder_names != tuple(names):
        raise ValueError(f"{listed}: classes {list(folder_names)} are not the detector's {list(names)} "
                         "(--class-agnostic scores every box as one class)")
    if class_agnostic:
        names = ("any",)
    preds, gts, frames = [], [], []
    for p in paths:
        img = cv2.imread(str(p), cv2.IMREAD_COLOR)
        h, w = img.shape[:2]
        frames.append(img)
        preds.append([(d.box, d.score, 0 if class_agnostic else d.class_id) for d in det(img)])
        rows = []
        lab = root / "labels" / (p.stem + ".txt")
        for line in lab.read_text().splitlines() if lab.exists() else []:
            if line.strip():
                c, cx, cy, bw, bh = line.split()
                cx, cy, bw, bh = float(cx) * w, float(cy) * h, float(bw) * w, float(bh) * h
                rows.append([0 if class_agnostic else int(c), cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2])
        gts.append(np.array(rows, float).reshape(-1, 5))
    m = evaluate_detections(preds, gts, len(names))
    if failures is not None:
        from chaser_bt.vision.detector.failures import failure_sheet, find_failures

        if not cv2.imwrite(str(failures), failure_sheet(find_failures(preds, gts, 0.25), paths)):
            raise ValueError(f"--failures {failures}: could not be written (a .png path in an existing folder)")
    det.conf_threshold = 0.25
    fps = frames_per_second(det, frames[:60])
    return {"images": len(paths), "image_size": image_size, "backend": det.backend, "ap50": m.ap50, "ap50_per_class": {names[k]: v for k, v in m.ap50_per_class.items()},
            "iou": m.iou, "precision": m.precision, "recall": m.recall, "f1": m.f1, "fps": fps}


def probability(text: str) -> float:
    """A share in [0, 1]."""
    value = non_negative_float(text)
    if value > 1.0:
        raise argparse.ArgumentTypeError(f"expected a share in [0, 1], got {value}")
    return value


def image_size(text: str) -> int:
    """A detector input size: a positive multiple of 32 px."""
    value = positive_int(text)
    if value % 32:
        raise argparse.ArgumentTypeError(f"expected a multiple of 32 px, got {value}")
    return value


def stage_widths(text: str) -> tuple[int, ...]:
    """Five comma-separated positive channel counts, one per detector stage."""
    parts = text.split(",")
    if len(parts) != 5:
        raise argparse.ArgumentTypeError(f"expected five comma-separated widths, got {text!r}")
    return tuple(positive_int(p.strip()) for p in parts)


def _train(args: argparse.Namespace) -> int:
    from chaser_bt.vision.detector.train import TrainConfig, TrainingInterrupted, train_detector

    if not (Path(args.data) / "images").is_dir():
        print(f"chaser-bt: --data {args.data}: no images/ folder (YOLO layout expected)", file=sys.stderr)
        return 2
    try:
        if args.init:  # before training starts: a wrong --init file is bad input, not a traceback
            _check_weights(args.init, "--init")
        out = train_detector(TrainConfig(args.data, args.out, steps=args.steps, batch=args.batch, seed=args.seed, threads=args.threads,
                                         lr=args.lr, init_weights=args.init or "", widths=args.widths, small_box_px=args.small_box_px,
                                         small_weight=args.small_weight, obj_iou=args.obj_iou, mixup=args.mixup,
                                         mixup_beta=args.mixup_beta, blur=args.blur), resume=not args.fresh)
    except (ValueError, FileNotFoundError) as e:
        print(f"chaser-bt: {e}", file=sys.stderr)
        return 2
    except TrainingInterrupted as e:
        print(f"\nchaser-bt: train-detector: interrupted at step {e.step}; checkpoint {e.checkpoint}: run the same "
              "command again to resume", file=sys.stderr)
        return 130
    print(f"weights written to {out}")
    try:
        from chaser_bt.vision.detector.inference import export_onnx

        print(f"ONNX copy written to {export_onnx(out, out.with_suffix('.onnx'))}")
    except ImportError:
        print("onnx is not installed: no ONNX copy (inference uses torch)")
    from chaser_bt.vision.detector.inference import int8_path

    if int8_path(out).exists():
        print(f"{int8_path(out)} is now older than the weights (not used): run chaser-bt quantize-detector --weights {out} "
              "--calib DIR to renew it")
    return 0


def _train_refiner(args: argparse.Namespace) -> int:
    import torch

    from chaser_bt.vision.detector.refine import (
        RefinerConfig,
        false_detections,
        make_negative_set,
        make_refiner_set,
        train_refiner,
    )
    from chaser_bt.vision.detector.train import iter_yolo_folder

    torch.set_num_threads(args.threads)
    config = RefinerConfig(scores=args.negatives_from is not None)
    rng = np.random.default_rng(args.seed)
    sets, negatives = [], []
    try:
        detect = None
        if args.negatives_from is not None:
            from chaser_bt.vision.detector.inference import Detector

            _check_weights(args.negatives_from, "--negatives-from")
            detect = Detector(args.negatives_from, conf_threshold=args.negative_conf, threads=args.threads, refiner=None)
        for folder in args.data:
            if not (Path(folder) / "images").is_dir():
                raise ValueError(f"--data {folder}: no images/ folder (YOLO layout expected)")
            crops_before, negatives_before = sum(len(x[0]) for x in sets), sum(len(x[0]) for x in negatives)
            # 640 x 480 frames stay at full resolution; a chunk of them is held at a time, only the crops kept.
            for images, boxes in iter_yolo_folder(folder, 640):
                sets.append(make_refiner_set(images, boxes, config, args.per_label, rng))
                if detect is not None:
                    negatives.append(make_negative_set(images, false_detections(detect, images, boxes), config))
            crops = sum(len(x[0]) for x in sets) - crops_before
            if crops == 0:
                raise ValueError(f"--data {folder}: no labelled targets in its frames")
            false = sum(len(x[0]) for x in negatives) - negatives_before
            print(f"{folder}: {crops} crops" + (f", {false} of false boxes" if detect is not None else ""), file=sys.stderr)
    except (ValueError, FileNotFoundError) as e:
        print(f"chaser-bt: {e}", file=sys.stderr)
        return 2
    crops, given, targets = (np.concatenate(parts) for parts in zip(*sets))
    negative_set = tuple(np.concatenate(parts) for parts in zip(*negatives)) if negatives else None
    if negative_set is not None and len(negative_set[0]) == 0:
        print(f"chaser-bt: --negatives-from {args.negatives_from}: the detector made no false boxes on --data", file=sys.stderr)
        return 2
    out = train_refiner(crops, given, targets, args.out, config, steps=args.steps, seed=args.seed, negatives=negative_set)
    print(f"refiner written to {out}")
    try:  # the copy the detector runs in onnxruntime, without torch
        from chaser_bt.vision.detector.refine import export_refiner_onnx

        print(f"ONNX copy written to {export_refiner_onnx(out)}")
    except ImportError:
        print("onnx is not installed: no ONNX copy (the refiner runs in torch)")
    return 0


def _eval(args: argparse.Namespace) -> int:
    from chaser_bt.vision.detector.inference import DEFAULT_WEIGHTS

    if not (Path(args.data) / "images").is_dir():
        print(f"chaser-bt: --data {args.data}: no images/ folder (YOLO layout expected)", file=sys.stderr)
        return 2
    try:
        _check_weights(args.weights or DEFAULT_WEIGHTS)
        results = [evaluate_folder(args.data, args.weights or DEFAULT_WEIGHTS, s, args.threads, args.limit, args.backend,
                                   args.class_agnostic, args.failures if k == 0 else None) for k, s in enumerate(args.sizes)]
    except (ValueError, FileNotFoundError) as e:
        print(f"chaser-bt: {e}", file=sys.stderr)
        return 2
    for r in results:
        print(json.dumps(r))
    return 0


def _quantize(args: argparse.Namespace) -> int:
    """``chaser-bt quantize-detector``: the int8 ONNX copy beside the weights, calibrated on training frames."""
    from chaser_bt.vision.detector.inference import DEFAULT_WEIGHTS, int8_path
    from chaser_bt.vision.detector.quantize import DEFAULT_EXCLUDE, quantize_detector, read_frames

    weights = Path(args.weights or DEFAULT_WEIGHTS)
    onnx_in = weights.with_suffix(".onnx")
    out = Path(args.out) if args.out else int8_path(weights)
    try:
        _check_weights(weights)
        if not onnx_in.is_file():
            raise ValueError(f"{onnx_in}: no float ONNX copy beside the weights (train-detector writes one)")
        try:
            frames = read_frames(args.calib, args.frames)
        except ValueError as e:
            raise ValueError(f"--calib {e}") from None
        keep_float = () if args.all_layers else tuple(args.keep_float or DEFAULT_EXCLUDE)
        quantize_detector(onnx_in, out, frames, image_size=args.size, exclude=keep_float,
                          per_channel=not args.per_tensor, method=args.method)
    except (ValueError, FileNotFoundError) as e:
        print(f"chaser-bt: {e}", file=sys.stderr)
        return 2
    print(f"int8 copy written to {out} (calibrated on {len(frames)} frames)")
    return 0


def _import_footage(args: argparse.Namespace) -> int:
    """``chaser-bt import-footage``: a CVAT export or the Halmstad dataset into YOLO folders."""
    from chaser_bt.vision.footage import import_footage
    from chaser_bt.vision.footage.halmstad import import_halmstad, is_halmstad

    rename = {}
    for pair in args.rename or []:
        old, sep, new = pair.partition("=")
        if not sep or not old or not new:
            print(f"chaser-bt: --rename {pair!r}: expected LABEL=CLASS", file=sys.stderr)
            return 2
        rename[old] = new
    halmstad = args.format == "halmstad" or (args.format == "auto" and is_halmstad(args.export))
    cvat_only = {"--video": args.video, "--video-start": args.video_start, "--video-step": args.video_step,
                 "--chunk": args.chunk, "--prefix": args.prefix or None}
    misplaced = [flag for flag, value in (cvat_only.items() if halmstad else
                                          {"--every": args.every, "--parts": args.parts}.items()) if value is not None]
    if misplaced:
        print(f"chaser-bt: {' '.join(misplaced)}: not for {'the Halmstad dataset' if halmstad else 'a CVAT export'}",
              file=sys.stderr)
        return 2
    try:
        if halmstad:
            summary = import_halmstad(args.export, args.out, classes=args.classes or ("drone",), rename=rename,
                                      every=args.every or 10, val_frac=args.val_frac, seed=args.seed,
                                      parts=args.parts or ("train", "val", "test"), min_box_px=args.min_box_px,
                                      preview=args.preview, progress=_video_progress)
        else:
            summary = import_footage(args.export, args.out, video=args.video, chunk=args.chunk or 150,
                                     val_frac=args.val_frac, seed=args.seed, classes=args.classes, rename=rename,
                                     video_start=args.video_start or 0, video_step=args.video_step or 1,
                                     min_box_px=args.min_box_px, prefix=args.prefix, preview=args.preview)
    except (ValueError, FileNotFoundError) as e:
        print(f"chaser-bt: {e}", file=sys.stderr)
        return 2
    for name, why in summary.skipped:
        print(f"skipped {name}: {why}", file=sys.stderr)
    if halmstad and summary.skipped:
        print(f"skipped {len(summary.skipped)} videos (named above)", file=sys.stderr)
    print(json.dumps(summary.to_dict()))
    return 0


def _video_progress(done: int, total: int, name: str) -> None:
    """One progress line a video, on stderr (the JSON summary keeps stdout)."""
    sys.stderr.write(f"\r[{'#' * int(30 * done / total):<30}] {done}/{total} videos ({name})")
    if done == total:
        sys.stderr.write("\n")
    sys.stderr.flush()


def _check_weights(path: str | Path, flag: str = "--weights") -> None:
    """Raises ValueError, naming ``flag``, unless ``path`` loads as detector weights (a file ``train-detector`` wrote)."""
    import pickle
    import zipfile

    from chaser_bt.vision.detector.inference import load_model

    if not Path(path).is_file():
        raise ValueError(f"{flag} {path}: {'is a folder, not a file' if Path(path).is_dir() else 'no such file'}")
    if Path(path).stat().st_size == 0:
        raise ValueError(f"{flag} {path}: empty file, not detector weights (expected a .pt file train-detector wrote)")
    try:
        load_model(path)
    except (pickle.UnpicklingError, zipfile.BadZipFile, EOFError, KeyError, TypeError, RuntimeError, AttributeError) as exc:
        raise ValueError(f"{flag} {path}: not detector weights (expected a .pt file train-detector wrote; {type(exc).__name__})") from None


def add_command(subparsers) -> None:
    """Add ``train-detector``, ``train-refiner``, ``eval-detector``, ``quantize-detector`` and ``import-footage`` to the CLI's subparsers."""
    help_ = "train the vision detector on a YOLO folder (seeded, resumable; Ctrl-C writes a checkpoint)"
    t = subparsers.add_parser("train-detector", help=help_, description=help_)
    t.add_argument("--data", required=True, metavar="DIR", help="YOLO folder (python -m sitl.bench.camera_dataset writes one; required)")
    t.add_argument("--out", default="detector.pt", type=output_file, metavar="FILE.pt",
                   help="weights file to write; a .ckpt beside it makes it resumable (default detector.pt)")
    t.add_argument("--steps", type=positive_int, default=1500, metavar="N", help="optimiser steps in all, counting resumed ones (default 1500)")
    t.add_argument("--batch", type=positive_int, default=24, metavar="N", help="images per step (default 24)")
    t.add_argument("--seed", type=seed, default=1, metavar="N", help="seed of the batches and initial weights (default 1)")
    t.add_argument("--threads", type=positive_int, default=1, metavar="N", help="torch threads (default 1)")
    t.add_argument("--fresh", action="store_true", help="ignore an existing checkpoint (default: resume from it)")
    t.add_argument("--lr", default=2e-3, type=positive_float, metavar="RATE", help="peak learning rate (default 2e-3; lower when fine-tuning)")
    t.add_argument("--init", default=None, metavar="FILE.pt",
                   help="fine-tune from these weights (same classes) instead of from scratch (default: from scratch)")
    t.add_argument("--widths", default=None, type=stage_widths, metavar="W,W,W,W,W",
                   help="the five stage widths; with --init, the trained net is first widened to them without changing its "
                        "output (default: the --init weights' widths, or 16,32,48,96,128)")
    t.add_argument("--small-box-px", default=0.0, type=non_negative_float, metavar="PX",
                   help="over-sample images with a box narrower than this, px at 416 scale (default 0: no over-sampling)")
    t.add_argument("--small-weight", type=positive_float, default=3.0, metavar="X", help="how many times more often such images are drawn (default 3)")
    t.add_argument("--obj-iou", type=non_negative_float, default=0.0, metavar="G",
                   help="objectness target 1 - G + G * IoU of the predicted box (YOLOv5's gr; default 0)")
    t.add_argument("--mixup", type=probability, default=0.1, metavar="FRAC",
                   help="share of mosaics blended with a second one, boxes of both (YOLOv4/v5's mixup; default 0.1)")
    t.add_argument("--mixup-beta", type=positive_float, default=32.0, metavar="A",
                   help="mixup weight drawn from Beta(A, A); 32 keeps it near 0.5 (default 32)")
    t.add_argument("--blur", type=probability, default=0.3, metavar="FRAC",
                   help="share of mosaics blurred, half by motion (3-9 px, any direction), half Gaussian (sigma 0.5-1.5 px) (default 0.3)")
    t.set_defaults(handler=_train)
    help_ = "train the box refiner (second stage) on YOLO folders of full-size frames"
    r = subparsers.add_parser("train-refiner", help=help_, description=help_)
    r.add_argument("--data", required=True, nargs="+", metavar="DIR", help="YOLO folders (python -m sitl.bench.camera_dataset writes them; required)")
    r.add_argument("--out", required=True, type=output_file, metavar="FILE.pt",
                   help="weights file; ship it beside the detector as <detector>_refiner.pt (required)")
    r.add_argument("--per-label", type=positive_int, default=6, metavar="N", help="jittered crops per labelled target (default 6)")
    r.add_argument("--steps", type=positive_int, default=4000, metavar="N", help="optimiser steps (default 4000)")
    r.add_argument("--seed", type=seed, default=1, metavar="N", help="seed of the crops and initial weights (default 1)")
    r.add_argument("--threads", type=positive_int, default=2, metavar="N", help="torch threads (default 2)")
    r.add_argument("--negatives-from", default=None, metavar="FILE.pt",
                   help="detector weights: train a scoring refiner, its negatives this detector's false boxes on --data "
                        "(default: none, a refiner that only re-places boxes and does not score them)")
    r.add_argument("--negative-conf", type=probability, default=0.05, metavar="SCORE",
                   help="lowest score of the false boxes mined with --negatives-from (default 0.05)")
    r.set_defaults(handler=_train_refiner)
    help_ = "11-point AP@0.5, IoU, P/R/F1 at 0.25 and frames/s of the detector on a YOLO folder"
    e = subparsers.add_parser("eval-detector", help=help_, description=help_)
    e.add_argument("--data", required=True, metavar="DIR", help="YOLO folder (required)")
    e.add_argument("--weights", default=None, metavar="FILE.pt", help="detector weights (default: the shipped weights)")
    e.add_argument("--sizes", type=image_size, nargs="+", default=[416, 832], metavar="PX",
                   help="input sizes to evaluate at, px, multiples of 32 (default 416 832)")
    e.add_argument("--threads", type=positive_int, default=1, metavar="N", help="torch threads (default 1)")
    e.add_argument("--class-agnostic", action="store_true",
                   help="score every box as one class (footage labelled 'drone'; default: the folder's classes must be the detector's)")
    e.add_argument("--failures", default=None, type=output_file, metavar="FILE.png",
                   help="draw the highest-scoring false boxes and the largest misses at 0.25, at the first size, into this "
                        "picture (default: none)")
    e.add_argument("--limit", type=non_negative_int, default=0, metavar="N", help="use the first N images only (default 0: all)")
    e.add_argument("--backend", choices=["auto", "torch", "onnx", "onnx-int8"], default="auto",
                   help="auto: the int8 ONNX copy when a current .int8.onnx file is beside the weights, else the "
                        "float one when a current .onnx file is, else torch (default auto)")
    e.set_defaults(handler=_eval)
    help_ = ("write the detector's int8 ONNX copy (<weights>.int8.onnx, what the auto backend runs when it is current) "
             "with onnxruntime's static quantization, calibrated on training frames")
    q = subparsers.add_parser("quantize-detector", help=help_, description=help_)
    q.add_argument("--weights", default=None, metavar="FILE.pt",
                   help="detector weights with their float .onnx copy beside them (default: the shipped weights)")
    q.add_argument("--calib", required=True, nargs="+", metavar="DIR",
                   help="folders of training frames (YOLO folders or plain folders of .jpg/.png), never the evaluation sets (required)")
    q.add_argument("--frames", type=non_negative_int, default=240, metavar="N",
                   help="calibration frames in all, taken evenly across the folders (default 240; 0: every one)")
    q.add_argument("--out", default=None, type=output_file, metavar="FILE.onnx",
                   help="file to write (default: beside the weights, <stem>.int8.onnx)")
    q.add_argument("--size", type=image_size, default=416, metavar="PX", help="input size of the calibration frames, px (default 416)")
    q.add_argument("--method", choices=["percentile", "minmax", "entropy"], default="percentile",
                   help="activation range calibration: percentile = the 99.999th of the calibration frames (default percentile)")
    q.add_argument("--per-tensor", action="store_true", help="one weight scale per layer instead of per output channel (default: per channel)")
    q.add_argument("--all-layers", action="store_true",
                   help="quantize the stem and the head too (default: both stay float)")
    q.add_argument("--keep-float", nargs="+", metavar="PREFIX",
                   help="node-name prefixes of the layers left float (default: /stem/ /head/)")
    q.set_defaults(handler=_quantize)
    help_ = ("import labelled footage into YOLO folders: a CVAT export (YOLO 1.1 or COCO 1.0, zip or folder) of your "
             "footage into train/ and val/, split by contiguous chunks; or the Halmstad drone-detection dataset "
             "into train/, val/ and its fixed held-out test/, split by video")
    f = subparsers.add_parser("import-footage", help=help_, description=help_)
    f.add_argument("export", metavar="EXPORT", help="CVAT export (zip or unpacked folder), or the Halmstad dataset's folder")
    f.add_argument("--format", choices=["auto", "cvat", "halmstad"], default="auto",
                   help="what the export is (default auto: halmstad when the folder holds V_*_LABELS.mat files)")
    f.add_argument("--out", required=True, type=output_dir, metavar="DIR",
                   help="folder to write train/, val/ (test/) and import.json into (required)")
    f.add_argument("--every", type=positive_int, default=None, metavar="N",
                   help="Halmstad: write every N-th frame of each video (default 10)")
    f.add_argument("--parts", nargs="+", choices=["train", "val", "test"], default=None, metavar="PART",
                   help="Halmstad: which parts to write, of train, val and test (default: all three)")
    f.add_argument("--prefix", default="", metavar="TEXT", help="start of every written file's name, one per flight sharing --out (default: none)")
    f.add_argument("--video", default=None, metavar="FILE",
                   help="take the frames from this video: export frame_NNNNNN = video frame N (default: the export's images)")
    f.add_argument("--video-start", type=non_negative_int, default=None, metavar="N",
                   help="video frame of the export's frame 0, the task's start frame (default 0)")
    f.add_argument("--video-step", type=positive_int, default=None, metavar="N",
                   help="video frames per export frame, the task's frame step (default 1)")
    f.add_argument("--chunk", type=positive_int, default=None, metavar="N",
                   help="consecutive frames per chunk of the split (default 150: 5 s at 30 frames/s)")
    f.add_argument("--val-frac", type=non_negative_float, default=0.2, metavar="FRAC",
                   help="share of chunks (Halmstad: of each kind's videos) held out for validation, 0..1 (default 0.2)")
    f.add_argument("--seed", type=seed, default=1, metavar="N",
                   help="which chunks (Halmstad: which videos) are held out (default 1)")
    f.add_argument("--classes", nargs="+", default=None, metavar="CLASS",
                   help="output classes in id order, the detector's, e.g. s1000 phantom (default: the export's labels; "
                        "Halmstad: drone, the other kinds written as hard negatives)")
    f.add_argument("--rename", nargs="+", default=None, metavar="LABEL=CLASS",
                   help="export label to class, e.g. drone=s1000 (default: none)")
    f.add_argument("--min-box-px", type=non_negative_float, default=1.0, metavar="PX",
                   help="drop boxes narrower or lower than this once clipped, pixels (default 1)")
    f.add_argument("--preview", type=non_negative_int, default=0, metavar="N",
                   help="write the first N frames with their boxes drawn to OUT/preview/ (default 0: none)")
    f.set_defaults(handler=_import_footage)
