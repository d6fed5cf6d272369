"""`workbench experiment isp|exposure PROJECT --data DIR`: the paper's detection experiments;
`workbench experiment claims --isp DIR --exposure DIR`: the paper's claims against their results;
`workbench dataset-noise DIR`: the render noise of a data set against the sensor's shot noise."""
from __future__ import annotations

import json
import logging
import sys

from workbench.commands.compute_options import add_compute_options, compute_spec
from workbench.files import json_text


def register(sub) -> None:
    from workbench.experiments.detection import PROFILES
    p = sub.add_parser("experiment", help="train and test detectors: ISP stage or exposure bias (resumable); "
                                          "or the paper's claims against two result folders")
    p.add_argument("kind", choices=("isp", "exposure", "budget", "claims"),
                   help="isp: raw/linear/sRGB; exposure: EV bias sweep; budget: is the profile's training budget "
                        "enough (B against 2B epochs, 2 seeds); claims: read --isp and --exposure results")
    p.add_argument("project", nargs="?", help="project file (or sample name) whose sensor, ISP and EV list are used")
    p.add_argument("--data", help="the project's rendered data set (`workbench dataset` folder)")
    p.add_argument("--profile", choices=tuple(PROFILES), default="standard",
                   help="; ".join(prof.note for prof in PROFILES.values()))
    p.add_argument("--seeds", type=int, default=None, help="seeds per configuration (default: the profile's)")
    p.add_argument("--out", default=None, help="output folder (default experiment-KIND-PROFILE); a rerun resumes; "
                                               "claims: the Markdown file to write (default: print)")
    p.add_argument("--checkpoints", default=None,
                   help="folder of training checkpoints (default OUT/checkpoints); give both experiments the "
                        "same one and they share the EV-0 sRGB runs")
    p.add_argument("--nets", nargs="+", default=None,
                   help="train only these of the profile's nets (another process may fill the same --out "
                        "with the others: the folder is merged under its lock after every run)")
    p.add_argument("--no-train", action="store_true",
                   help="train nothing: rewrite --out from the runs it holds and those --reuse lends (its "
                        "analysis, CSVs and chart by this version; after a budget grows, the runs it "
                        "supersedes move aside)")
    p.add_argument("--reuse", nargs="+", default=(), metavar="DIR",
                   help="result folders of the same data set whose finished runs of the same configuration are "
                        "taken instead of trained (the sRGB EV-0 runs are shared by isp, exposure and budget)")
    p.add_argument("--isp", help="claims: the isp experiment's result folder")
    p.add_argument("--exposure", help="claims: the exposure experiment's result folder")
    p.add_argument("--workers", type=int, default=0,
                   help="runs in parallel local processes (0 = in this process); with --backend ray and "
                        "no --address, the CPUs of the local Ray cluster started for the run")
    add_compute_options(p)
    p.set_defaults(func=cmd_experiment)

    q = sub.add_parser("dataset-noise", help="render noise of a data set's frames against the sensor's shot noise "
                                             "at the lowest EV its experiments test (writes render-noise.json)")
    q.add_argument("folder", help="a `workbench dataset` folder")
    q.add_argument("--frames", type=int, default=3, help="frames to measure (the first ones; default 3)")
    q.add_argument("--reference-spp", type=int, default=4096, help="samples per pixel of the reference renders")
    q.set_defaults(func=cmd_dataset_noise)


def _drive(job, desc: str, unit: str):
    """Run a long job with a progress bar; returns its result."""
    from tqdm import tqdm
    bar = None
    try:
        while True:
            try:
                p = next(job)
            except StopIteration as stop:
                return stop.value
            if bar is None:
                print(p.message, file=sys.stderr)
                bar = tqdm(total=float(p.total), initial=float(p.done), desc=desc, unit=unit)
            else:
                bar.n = round(float(p.done), 2)
                bar.set_postfix_str(p.message[-70:], refresh=False)
                bar.refresh()
    finally:
        if bar is not None:
            bar.close()


def cmd_experiment(args) -> int:
    from workbench.compute.local import JobFailed
    from workbench.errors import WorkbenchError
    from workbench.experiments.detection import run_experiment
    from workbench.jobs import CancelToken, JobCancelled
    from workbench.project import load_project

    if args.kind == "claims":
        return cmd_claims(args)
    missing = [f for f, v in (("PROJECT", args.project), ("--data", args.data)) if not v]
    if missing:
        print(f"workbench experiment {args.kind}: error: give {' and '.join(missing)}", file=sys.stderr)
        return 2
    handler = logging.StreamHandler(sys.stderr)       # training epochs on the terminal
    handler.setFormatter(logging.Formatter("  %(message)s"))
    logging.getLogger("workbench.detect").addHandler(handler)
    logging.getLogger("workbench.detect").setLevel(logging.INFO)
    if args.no_train and args.nets:
        print(f"workbench experiment {args.kind}: error: give --nets or --no-train, not both", file=sys.stderr)
        return 2
    out = args.out or f"experiment-{args.kind}-{args.profile}"
    cancel = CancelToken()
    try:
        project = load_project(args.project)
        compute = compute_spec(args, gpus_per_task=1.0 if args.profile == "paper" else 0.0)
        job = run_experiment(args.kind, project, args.data, out, profile=args.profile, seeds=args.seeds,
                             cancel=cancel, compute=compute, checkpoints=args.checkpoints,
                             nets=() if args.no_train else tuple(args.nets) if args.nets else None,
                             reuse_from=tuple(args.reuse))
        result = _drive(job, args.kind, "run")
    except (KeyboardInterrupt, JobCancelled):
        cancel.cancel()
        print(f"workbench experiment: stopped; finished runs are in {out} (rerun to resume)", file=sys.stderr)
        return 130
    except JobFailed as exc:              # before WorkbenchError: a failed run is one of those
        print(f"workbench experiment: error: {exc} (finished runs are kept; rerun to resume)", file=sys.stderr)
        return 1
    except WorkbenchError as exc:
        print(f"workbench experiment: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps({"out": str(result.out_dir), "results": str(result.results_path),
                      "trained": len(result.trained), "reused": len(result.reused)}, indent=1))
    return 0


def cmd_claims(args) -> int:
    from workbench.errors import OutputPathError, WorkbenchError
    from workbench.experiments.claims_report import claims_markdown
    if not (args.isp and args.exposure):
        print("workbench experiment claims: error: give --isp DIR and --exposure DIR (two result folders)",
              file=sys.stderr)
        return 2
    try:
        if args.out:
            from pathlib import Path

            from workbench.compute.folder_lock import hold_file_lock
            from workbench.files import atomic_write_text, prepare_output_folder
            if not args.out.strip():
                raise OutputPathError(args.out, "an empty file name; name the Markdown file (e.g. --out claims.md)")
            prepare_output_folder(Path(args.out).parent)
            with hold_file_lock(args.out, "workbench experiment claims"):
                text = claims_markdown(args.isp, args.exposure)
                atomic_write_text(args.out, text)
        else:
            text = claims_markdown(args.isp, args.exposure)
    except WorkbenchError as exc:
        print(f"workbench experiment claims: error: {exc}", file=sys.stderr)
        return 2
    print(text if not args.out else json.dumps({"claims": args.out}))
    return 0


def cmd_dataset_noise(args) -> int:
    from workbench.errors import WorkbenchError
    from workbench.experiments.render_noise import measure_render_noise
    from workbench.jobs import JobCancelled
    try:
        report = _drive(measure_render_noise(args.folder, args.frames, args.reference_spp), "dataset-noise", "frame")
    except (KeyboardInterrupt, JobCancelled):
        print("workbench dataset-noise: stopped; nothing written", file=sys.stderr)
        return 130
    except WorkbenchError as exc:
        print(f"workbench dataset-noise: error: {exc}", file=sys.stderr)
        return 2
    print(json_text(report))
    return 0
