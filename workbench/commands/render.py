"""`workbench render` (one labelled city frame), `workbench dataset` (a resumable set of them) and the
folder commands `dataset-stats` and `dataset-verify`."""
from __future__ import annotations

import json
import sys
from dataclasses import asdict

import numpy as np

from workbench.commands.compute_options import add_compute_options, compute_spec
from workbench.files import json_text

# Box colours per class id (RGB), cycling for ids beyond the list.
CLASS_COLOURS = ((230, 25, 75), (60, 180, 75), (255, 225, 25), (0, 130, 200), (245, 130, 48),
                 (145, 30, 180), (70, 240, 240), (240, 50, 230), (210, 245, 60), (250, 190, 212),
                 (0, 128, 128), (220, 190, 255), (170, 110, 40))
OVERLAY_CLASSES = ("car", "pedestrian", "bus", "truck", "tree", "lamp", "bench", "mailbox")


def register(sub) -> None:
    p = sub.add_parser("render", help="render one labelled frame of a city project")
    p.add_argument("project", help="project file (or the name of a sample project)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--frame", type=int, default=0, help="frame index: picks the seeds (default 0)")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("dataset", help="render a resumable labelled data set (COCO JSON + manifest)")
    p.add_argument("project", help="project file (or the name of a sample project)")
    p.add_argument("--frames", type=int, required=True, help="number of frames")
    p.add_argument("--out", required=True, help="output folder (a rerun resumes it)")
    p.add_argument("--workers", type=int, default=1,
                   help="local worker processes (0 = in this process); with --backend ray and no "
                        "--address, the CPUs of the local Ray cluster started for the run")
    p.add_argument("--float32", action="store_true",
                   help="store irradiance as float32 (default float16 with scale, ≤ 0.05 %% error)")
    p.add_argument("--confirm-large", action="store_true",
                   help="render more than 2,000 frames (refused without it, with an estimate of the time)")
    add_compute_options(p)
    p.set_defaults(func=cmd_dataset)

    p = sub.add_parser("dataset-stats", help="write statistics.json and statistics.png of a data-set folder")
    p.add_argument("folder", help="data-set folder (made by `workbench dataset`)")
    p.set_defaults(func=cmd_dataset_stats)

    p = sub.add_parser("dataset-verify", help="check every file of a data-set folder (frames against the "
                                              "manifest's hashes, labels against the frames) and list all problems")
    p.add_argument("folder", help="data-set folder (made by `workbench dataset`)")
    p.set_defaults(func=cmd_dataset_verify)


def label_overlay(rgb01: np.ndarray, labels, classes=OVERLAY_CLASSES):
    """PIL image of an sRGB preview with the visible boxes and class names of `classes` drawn."""
    from PIL import Image, ImageDraw
    img = Image.fromarray(np.round(np.clip(rgb01, 0, 1) * 255).astype(np.uint8))
    draw = ImageDraw.Draw(img)
    for obj in labels.objects:
        if obj.visible_px == 0 or obj.class_name not in classes:
            continue
        x, y, w, h = obj.bbox_xywh
        colour = CLASS_COLOURS[(obj.class_id - 1) % len(CLASS_COLOURS)]
        draw.rectangle([x, y, x + w - 1, y + h - 1], outline=colour)
        draw.text((x + 1, max(0, y - 11)), obj.class_name, fill=colour)
    return img


def cmd_render(args) -> int:
    from workbench.jobs import tqdm_progress
    from workbench.previews import irradiance_preview, save_image, save_png
    from workbench.project import load_project
    from workbench.render.city_frame import project_frame_seeds, render_city_frame
    from workbench.datasets.dataset import FRAME_FORMAT, FRAME_VERSION, write_frame
    from workbench.render.labels import labels_to_coco

    from workbench.errors import ParameterError
    from workbench.files import atomic_write_text, prepare_output_folder
    from workbench.render.city_frame import long_render_note
    project = load_project(args.project)
    if args.frame < 0:
        raise ParameterError("--frame", args.frame, "must be an integer ≥ 0")
    out = prepare_output_folder(args.out)
    from workbench.compute.folder_lock import hold_folder_lock
    with hold_folder_lock(out, "workbench render"):      # a second render into this folder is refused
        if long_render_note(project):
            print(long_render_note(project), file=sys.stderr, flush=True)
        seeds = project_frame_seeds(project, args.frame)
        progress = tqdm_progress(f"render frame {args.frame}")
        try:
            frame = render_city_frame(project, seeds, on_progress=progress)
        finally:
            progress.close()
        stem = f"frame_{args.frame:06d}"
        rgb = irradiance_preview(frame.irradiance_photons, frame.wavelengths_nm, frame.meta.get("render"))
        save_png(out / f"{stem}_irradiance.png", rgb)
        save_image(out / f"{stem}_labels.png", label_overlay(rgb, frame.labels))
        write_frame(out / f"{stem}.npz", frame,
                    {"format": FRAME_FORMAT, "version": FRAME_VERSION, "index": args.frame,
                     "seeds": asdict(seeds), "project": project.name}, "float32")
        coco = labels_to_coco([(f"{stem}.npz", frame.labels)])
        atomic_write_text(out / f"{stem}_coco.json", json_text(coco))
        counts: dict[str, int] = {}
        for o in frame.labels.objects:
            if o.visible_px:
                counts[o.class_name] = counts.get(o.class_name, 0) + 1
        print(json.dumps({"frame": args.frame, "out": str(out), "shape": list(frame.labels.shape),
                          "visible_objects": counts, **{k: frame.meta[k] for k in ("variant", "spp")
                                                        if k in frame.meta}}, indent=1))
    return 0


def cmd_dataset(args) -> int:
    from tqdm import tqdm

    from workbench.compute import JobFailed
    from workbench.errors import WorkbenchError
    from workbench.project import load_project
    from workbench.datasets.dataset import run_dataset

    try:
        project = load_project(args.project)
        from workbench.datasets.size_limit import check_dataset_size
        check_dataset_size(project, args.frames, max(args.workers, 1), args.confirm_large)
        job = run_dataset(project, args.frames, args.out, compute=compute_spec(args, max_tasks_per_child=16),
                          irradiance_dtype="float32" if args.float32 else "float16")
        steps = iter(())
        try:
            steps = iter([next(job)])       # checks the folder and the spec before a bar is drawn
        except StopIteration as stop:
            result = stop.value
        with tqdm(total=args.frames, desc="dataset", unit="frame") as bar:
            while True:
                try:
                    p = next(steps, None) or next(job)
                except StopIteration as stop:
                    result = stop.value
                    break
                bar.n = round(p.done, 2)            # frames in flight count by their progress
                bar.set_postfix_str(p.message, refresh=False)
                bar.refresh()
    except JobFailed as exc:
        print(f"workbench dataset: error: {exc} (finished frames are kept; rerun to resume)",
              file=sys.stderr)
        return 1
    except WorkbenchError as exc:
        print(f"workbench dataset: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps({"out": str(result.out_dir), "frames": result.frames,
                      "rendered": len(result.rendered), "reused": len(result.reused),
                      "coco": str(result.coco_path), "manifest": str(result.manifest_path)}, indent=1))
    return 0


def cmd_dataset_stats(args) -> int:
    from workbench.errors import WorkbenchError
    from workbench.datasets.dataset import write_folder_statistics

    try:
        json_path, png_path = write_folder_statistics(args.folder)
    except WorkbenchError as exc:
        print(f"workbench dataset-stats: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps({"statistics": str(json_path), "plot": str(png_path)}))
    return 0


def cmd_dataset_verify(args) -> int:
    """Print every problem of a data-set folder, one a line; exit 2 when there is any."""
    from tqdm import tqdm

    from workbench.datasets.integrity import verify_dataset

    with tqdm(desc="dataset-verify", unit="frame", leave=False) as bar:
        def on_frame(done, total):
            bar.total = total
            bar.update(done - bar.n)
        problems = verify_dataset(args.folder, on_frame)
        frames = bar.total
    for problem in problems:
        print(problem)
    if problems:
        print(f"workbench dataset-verify: error: {len(problems)} problem{'s' if len(problems) > 1 else ''} in "
              f"{args.folder} (listed above)", file=sys.stderr)
        return 2
    print(json.dumps({"folder": str(args.folder), "valid": True, "frames": frames}))
    return 0
