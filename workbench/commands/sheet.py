"""`workbench contact-sheet`: city frames of several scene types through the camera, tiled with
their label boxes and captions (datasets/contact_sheet.py) into one PNG and a JSON record."""
from __future__ import annotations

import json
import sys
from pathlib import Path

# The city scene types among the sample projects (the default list).
SCENE_TYPE_SAMPLES = ("city_day_clear_sky", "city_low_sun", "city_overcast", "city_night", "city_fog",
                      "city_tunnel", "city_tunnel_entrance", "city_detection_quick")


def register(sub) -> None:
    p = sub.add_parser("contact-sheet", help="render frames of city scene types through the camera and tile "
                                             "them with label boxes into one PNG (+ JSON)")
    p.add_argument("projects", nargs="*", default=list(SCENE_TYPE_SAMPLES),
                   help=f"city projects (files or sample names); default: {' '.join(SCENE_TYPE_SAMPLES)}")
    p.add_argument("--out", required=True, help="PNG to write; the JSON record goes beside it (same name, .json)")
    p.add_argument("--frames-per-scene", type=int, default=2, help="frames 0…N−1 of each project (default 2)")
    p.add_argument("--width", type=int, default=320, help="tile width in pixels (default 320)")
    p.add_argument("--height", type=int, default=240, help="tile height in pixels (default 240)")
    p.add_argument("--spp", type=int, default=32,
                   help="samples per pixel of every frame, fixed so night and fog cost no more (default 32)")
    p.add_argument("--columns", type=int, default=4, help="tiles per row of the sheet (default 4)")
    p.add_argument("--colours", type=int, default=None,
                   help="store the PNG with a palette of this many colours (7–256; box, text and background "
                        "colours exact) instead of RGB: about a third the size for noisy frames")
    p.add_argument("--sensor-noise", choices=("on", "off"), default="on",
                   help="'off': each sensor without its noise (gain, clipping and quantisation kept), so the grain "
                        "left is the renderer's (default on)")
    p.set_defaults(func=cmd_contact_sheet)


def cmd_contact_sheet(args) -> int:
    from workbench.detect.data import keep_box
    from workbench.errors import ParameterError
    from workbench.project import load_project
    from workbench.datasets.contact_sheet import write_contact_sheet

    from workbench.datasets.contact_sheet import MAX_FRAMES_PER_SCENE, MAX_TILE_PX
    for name, lo, hi in (("--frames-per-scene", 1, MAX_FRAMES_PER_SCENE), ("--width", 8, MAX_TILE_PX),
                         ("--height", 8, MAX_TILE_PX), ("--spp", 1, 1 << 16), ("--columns", 1, 64),
                         ("--colours", 7, 256)):
        value = getattr(args, name[2:].replace("-", "_"))
        if value is not None and not lo <= value <= (hi or value):
            raise ParameterError(name, value, f"must be an integer from {lo} to {hi}" if hi
                                 else f"must be an integer ≥ {lo}")
    projects = [load_project(p) for p in args.projects]
    not_city = [p.name for p in projects if p.scene.kind != "city"]
    if not_city:
        raise ParameterError("projects", ", ".join(not_city), "must be city projects (scene.kind 'city')")

    def report(k: int, total: int, tile) -> None:
        r = tile.record
        print(f"[{k}/{total}] {r['project']} #{r['frame']}: {r['render_s']:.1f} s render, "
              f"{sum(r['visible_objects_of_interest'].values())} road users", file=sys.stderr, flush=True)

    from workbench.compute.folder_lock import hold_file_lock
    from workbench.errors import OutputPathError
    from workbench.files import prepare_output_folder
    if not str(args.out).strip() or Path(args.out).suffix.lower() != ".png":
        raise OutputPathError(args.out, "must name a .png file")
    prepare_output_folder(Path(args.out).parent)
    with hold_file_lock(args.out, "workbench contact-sheet"):      # a second sheet into this file is refused
        png, record = write_contact_sheet(projects, args.frames_per_scene, args.out, width=args.width,
                                          height=args.height, spp=args.spp, columns=args.columns, keep=keep_box,
                                          colours=args.colours, sensor_noise=args.sensor_noise == "on",
                                          on_tile=report)
    print(json.dumps({"png": str(png), "json": str(record)}))
    return 0
