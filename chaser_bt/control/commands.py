"""``chaser-bt chase-geometry``: the recommended follow position for a camera and a target.

Wired into the CLI by ``add_command(subparsers)``. Prints the slant range and elevation (and the
ground range / relative height set-points they become) with what they buy: pixels on target and
the reaction times to a vertical and a horizontal dash; ``--plot`` writes the trade-off figure
(the paper's figure 4), ``--json`` prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from chaser_bt.cli_args import output_file
from chaser_bt.control.chase_geometry import ChaseInputs, recommend, trade_off_figure

__all__ = ["add_command"]


def add_command(subparsers: argparse._SubParsersAction) -> None:
    d = ChaseInputs()
    help_ = "recommend the follow position (slant range, elevation) for a camera and a target; draw the trade-off"
    p = subparsers.add_parser("chase-geometry", help=help_, description=help_)
    p.add_argument("--hfov-deg", type=float, default=math.degrees(d.hfov_rad), metavar="DEG", help="camera horizontal FOV, deg, in (0, 180) (default %(default).4g)")
    p.add_argument("--vfov-deg", type=float, default=math.degrees(d.vfov_rad), metavar="DEG", help="camera vertical FOV, deg, in (0, 180) (default %(default).4g)")
    p.add_argument("--width-px", type=int, default=d.width_px, metavar="PX", help="image width, px (default %(default)s)")
    p.add_argument("--height-px", type=int, default=d.height_px, metavar="PX", help="image height, px (default %(default)s)")
    p.add_argument("--target-size-m", type=float, nargs=3, metavar=("WIDTH", "DEPTH", "HEIGHT"),
                   default=[d.target_width_m, d.target_depth_m, d.target_height_m], help=f"target box, m, each > 0 (default {d.target_width_m:g} {d.target_depth_m:g} {d.target_height_m:g})")
    p.add_argument("--speed-h", type=float, default=d.speed_h_mps, metavar="M/S", help="target horizontal dash speed, m/s (default %(default)s)")
    p.add_argument("--speed-up", type=float, default=d.speed_up_mps, metavar="M/S", help="target climb speed, m/s (default %(default)s)")
    p.add_argument("--speed-down", type=float, default=d.speed_down_mps, metavar="M/S", help="target descent speed, m/s (default %(default)s)")
    p.add_argument("--min-pixels", type=float, default=d.min_pixels, metavar="PX", help="pixels on target the detector needs, px (default %(default)s)")
    p.add_argument("--plot", type=output_file, metavar="FILE.png", help="write the trade-off figure here (default: none)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=run)


def _positive(v: float) -> bool:
    return math.isfinite(v) and v > 0


def _inputs(args: argparse.Namespace) -> ChaseInputs:
    """The inputs; every value out of range is named with what its own field expects."""
    positive = _positive
    checks = {"--hfov-deg": (0 < args.hfov_deg < 180, "a field of view in (0, 180) deg"),
              "--vfov-deg": (0 < args.vfov_deg < 180, "a field of view in (0, 180) deg"),
              "--width-px": (args.width_px > 0, "a width >= 1 px"), "--height-px": (args.height_px > 0, "a height >= 1 px"),
              "--target-size-m": (all(positive(x) for x in args.target_size_m), "three sizes > 0 m"),
              "--speed-h": (positive(args.speed_h), "a speed > 0 m/s"), "--speed-up": (positive(args.speed_up), "a speed > 0 m/s"),
              "--speed-down": (positive(args.speed_down), "a speed > 0 m/s"),
              "--min-pixels": (positive(args.min_pixels), "a pixel count > 0")}
    bad = [f"{k}: expected {what}" for k, (ok, what) in checks.items() if not ok]
    if bad:
        raise ValueError("; ".join(bad))
    w, dpt, h = args.target_size_m
    return ChaseInputs(hfov_rad=math.radians(args.hfov_deg), vfov_rad=math.radians(args.vfov_deg),
                       width_px=args.width_px, height_px=args.height_px, target_width_m=w, target_depth_m=dpt,
                       target_height_m=h, speed_h_mps=args.speed_h, speed_up_mps=args.speed_up,
                       speed_down_mps=args.speed_down, min_pixels=args.min_pixels)


def run(args: argparse.Namespace) -> int:
    try:
        inputs = _inputs(args)
        rec = recommend(inputs)
    except ValueError as e:
        print(f"chaser-bt: {e}", file=sys.stderr)
        return 2
    if args.plot:
        trade_off_figure(inputs, args.plot)
    d = rec.as_dict()
    if args.json:
        print(json.dumps(d))
    else:
        print(f"follow from {d['slant_range_m']:g} m slant range at {d['elevation_deg']:g} deg elevation "
              f"(ground range {d['ground_range_m']:g} m, {d['rel_height_m']:g} m above the target)")
        print(f"  pixels on target {d['pixels_on_target']:g}; time to react: vertical dash {d['t_vertical_dash_s']:g} s, "
              f"horizontal dash {d['t_horizontal_dash_s']:g} s")
        if args.plot:
            print(f"  trade-off figure: {args.plot}")
    return 0
