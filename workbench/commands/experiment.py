"""`workbench experiment isp|exposure PROJECT --data DIR`: the paper's detection experiments."""
from __future__ import annotations

import json
import logging
import sys

from workbench.commands.compute_options import add_compute_options, compute_spec


def register(sub) -> None:
    p = sub.add_parser("experiment", help="train and test detectors: ISP stage or exposure bias (resumable)")
    p.add_argument("kind", choices=("isp", "exposure"), help="isp: raw/linear/sRGB; exposure: EV bias sweep")
    p.add_argument("project", help="project file (or sample name) whose sensor, ISP and EV list are used")
    p.add_argument("--data", required=True, help="the project's rendered data set (`workbench dataset` folder)")
    p.add_argument("--profile", choices=("quick", "paper"), default="quick",
                   help="quick: 320x240, mobile net, 1 thread (CPU); paper: 640x480, both nets (GPU)")
    p.add_argument("--seeds", type=int, default=None, help="seeds per configuration (default: the profile's, 3)")
    p.add_argument("--out", default=None, help="output folder (default experiment-KIND-PROFILE); a rerun resumes")
    p.add_argument("--workers", type=int, default=0,
                   help="runs in parallel local processes (0 = in this process); with --backend ray and "
                        "no --address, the CPUs of the local Ray cluster started for the run")
    add_compute_options(p)
    p.set_defaults(func=cmd_experiment)


def cmd_experiment(args) -> int:
    from tqdm import tqdm

    from workbench.compute.local import JobFailed
    from workbench.errors import WorkbenchError
    from workbench.experiments.detection import run_experiment
    from workbench.jobs import CancelToken, JobCancelled
    from workbench.project import load_project

    handler = logging.StreamHandler(sys.stderr)       # training epochs on the terminal
    handler.setFormatter(logging.Formatter("  %(message)s"))
    logging.getLogger("workbench.detect").addHandler(handler)
    logging.getLogger("workbench.detect").setLevel(logging.INFO)
    project = load_project(args.project)
    out = args.out or f"experiment-{args.kind}-{args.profile}"
    cancel = CancelToken()
    compute = compute_spec(args, gpus_per_task=1.0 if args.profile == "paper" else 0.0)
    job = run_experiment(args.kind, project, args.data, out, profile=args.profile, seeds=args.seeds,
                         cancel=cancel, compute=compute)
    bar = None
    try:
        while True:
            try:
                p = next(job)
            except StopIteration as stop:
                result = stop.value
                break
            if bar is None:
                print(p.message, file=sys.stderr)
                bar = tqdm(total=int(p.total), initial=int(p.done), desc=args.kind, unit="run")
            else:
                bar.n = int(p.done)
                bar.set_postfix_str(p.message[-60:], refresh=False)
                bar.refresh()
    except (KeyboardInterrupt, JobCancelled):
        cancel.cancel()
        print(f"workbench experiment: stopped; finished runs are in {out} (rerun to resume)", file=sys.stderr)
        return 130
    except WorkbenchError as exc:
        print(f"workbench experiment: error: {exc}", file=sys.stderr)
        return 2
    except JobFailed as exc:
        print(f"workbench experiment: error: {exc} (finished runs are kept; rerun to resume)", file=sys.stderr)
        return 1
    finally:
        if bar is not None:
            bar.close()
    print(json.dumps({"out": str(result.out_dir), "results": str(result.results_path),
                      "trained": len(result.trained), "reused": len(result.reused),
                      "summary": result.summary}, indent=1, default=float))
    return 0
