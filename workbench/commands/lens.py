"""`workbench lens info LENS` and `workbench lens plot LENS --out DIR`."""
from __future__ import annotations

import argparse
import math

from workbench.errors import ParameterError
from workbench.files import json_text


def register(sub) -> None:
    p = sub.add_parser("lens", help="lens prescriptions: paraxial data, aberrations, plots")
    lsub = p.add_subparsers(dest="lens_command", required=True)
    for name, helptext in (("info", "paraxial data and an aberration summary"),
                           ("plot", "PNG figures: layout, spots, ray fans, PSF, MTF, distortion, illumination")):
        q = lsub.add_parser(name, help=helptext)
        q.add_argument("lens", help="a lens file (.json/.dat/.zmx) or a name in resources/lenses/")
        q.add_argument("--max-field-deg", type=float, default=None,
                       help="largest field angle to analyse (default: largest traceable)")
        q.add_argument("--focus-m", type=float, default=None,
                       help="focus on an object this far in front of the lens (default: as stored)")
        if name == "info":
            q.add_argument("--json", action="store_true", help="print JSON")
            q.add_argument("--sensor-mm", type=float, nargs=2, metavar=("WIDTH", "HEIGHT"), default=None,
                           help="sensor size: adds the fields of view and analyses up to its corner")
            q.set_defaults(func=cmd_info)
        else:
            q.add_argument("--out", required=True, help="output folder for the PNGs")
            q.set_defaults(func=cmd_plot)


def _lens(args):
    from workbench.optics.lens import focus, load_lens
    if args.max_field_deg is not None and not 0 < args.max_field_deg < 90:
        raise ParameterError("--max-field-deg", args.max_field_deg, "must be a number in (0, 90) degrees")
    if args.focus_m is not None and not (math.isfinite(args.focus_m) and args.focus_m > 0):
        raise ParameterError("--focus-m", args.focus_m, "must be a finite distance > 0 (m)")
    lens = load_lens(args.lens)
    return focus(lens, args.focus_m) if args.focus_m is not None else lens


def cmd_info(args: argparse.Namespace) -> int:
    from workbench.optics.lens.report import format_summary, lens_summary
    if args.sensor_mm is not None and not all(math.isfinite(v) and 0 < v <= 1000 for v in args.sensor_mm):
        raise ParameterError("--sensor-mm", tuple(args.sensor_mm), "width and height must be finite numbers "
                                                                   "in (0, 1000] mm")
    s = lens_summary(_lens(args), args.max_field_deg, None if args.sensor_mm is None else tuple(args.sensor_mm))
    print(json_text(s, indent=2) if args.json else format_summary(s))
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    from workbench.compute.folder_lock import hold_folder_lock
    from workbench.files import prepare_output_folder
    from workbench.optics.lens.report import write_plots
    lens = _lens(args)
    out = prepare_output_folder(args.out)
    with hold_folder_lock(out, "workbench lens plot"):
        written = write_plots(lens, out, args.max_field_deg)
    for p in written:
        print(p)
    return 0
