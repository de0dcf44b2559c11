"""``chaser-bt calibrate FILE``: fit the radar's pose from a recorded calibration flight (appendix A).

Prints the radar's position (geodetic), yaw/pitch/roll and the 1-sigma ENU residuals; ``--json``
prints one JSON object instead. Bad input (missing file, malformed line) exits 2 naming the file,
line and field; a flight that cannot be fitted exits 1.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from chaser_bt.radar.calibration import CalibrationError
from chaser_bt.radar.recording import METHODS, RecordingError, calibrate_recording, load_recording

__all__ = ["add_command", "run_calibrate"]


def add_command(subparsers) -> None:
    """Add ``calibrate`` to the ``chaser-bt`` sub-commands."""
    p = subparsers.add_parser("calibrate", help="fit the ground radar's pose from a recorded calibration flight",
                              description="Fit the ground radar's pose from a recorded calibration flight (docs/radar.md).")
    p.add_argument("file", metavar="FILE", help="calibration flight, JSON lines (docs/radar.md)")
    p.add_argument("--method", choices=METHODS, default="six",
                   help="six: orientation and position (default); longest: the paper's 3-parameter fit on the "
                        "longest track; best: 3-parameter fit on the best track")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=run_calibrate)


def run_calibrate(args: argparse.Namespace) -> int:
    try:
        rec = load_recording(args.file)
    except RecordingError as e:
        print(f"chaser-bt: {e}", file=sys.stderr)
        return 2
    try:
        res, where = calibrate_recording(rec, args.method)
    except CalibrationError as e:
        print(f"chaser-bt: {args.file}: cannot calibrate: {e}", file=sys.stderr)
        return 1
    y, p, r = (math.degrees(a) for a in res.yaw_pitch_roll)
    out = {"method": res.method, "lat_deg": where.lat_deg, "lon_deg": where.lon_deg, "alt_m": where.alt_m,
           "yaw_deg": y, "pitch_deg": p, "roll_deg": r,
           "residual_std_enu_m": [round(float(v), 3) for v in res.residual_std_enu],
           "residual_rms_m": round(res.residual_rms_m, 3), "tracks": list(res.track_ids), "bins": res.n_bins}
    if args.json:
        print(json.dumps(out))
    else:
        e, n, u = out["residual_std_enu_m"]
        print(f"radar pose ({res.method}, {len(res.track_ids)} track(s), {res.n_bins} bins)\n"
              f"  position  lat {where.lat_deg:.7f} deg  lon {where.lon_deg:.7f} deg  alt {where.alt_m:.2f} m\n"
              f"  attitude  yaw {y:.2f} deg  pitch {p:.2f} deg  roll {r:.2f} deg\n"
              f"  residual 1-sigma  E {e:.2f} m  N {n:.2f} m  U {u:.2f} m")
    return 0
