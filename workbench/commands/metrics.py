"""`workbench metrics`, `workbench compare` and `workbench study`: a camera design's measurements
(system MTF, SNR against signal, ΔE2000), two designs side by side, and a grid of designs with a
Pareto chart (workbench/metrics)."""
from __future__ import annotations

import json
import sys

from workbench.commands.compute_options import add_compute_options, compute_spec


def register(sub) -> None:
    m = sub.add_parser("metrics", help="measure a camera design on test charts: system MTF (ISO 12233 "
                                       "slanted edge), SNR against signal, ΔE2000 of the Macbeth chart")
    m.add_argument("project", help="project file or sample name")
    m.add_argument("--out", default=None, help="folder for metrics.json, metrics.md and metrics.png (default: "
                                               "print only)")
    m.set_defaults(func=cmd_metrics)

    c = sub.add_parser("compare", help="two camera designs side by side: a report (Markdown table with the "
                                       "change, PNG charts, JSON) of their measurements")
    c.add_argument("a", help="design A: project file or sample name")
    c.add_argument("b", help="design B: project file or sample name")
    c.add_argument("--out", required=True, help="folder for compare.md, compare.png and compare.json")
    c.set_defaults(func=cmd_compare)

    from workbench.metrics.study import HIGHER_IS_BETTER
    s = sub.add_parser("study", help="a grid of camera designs (every combination of --vary values): the "
                                     "measurements of each, a table and a Pareto chart; resumable")
    s.add_argument("project", help="the design the grid starts from: project file or sample name")
    s.add_argument("--vary", action="append", required=True, metavar="SECTION.FIELD=V1,V2,…",
                   help="a field and its values, e.g. sensor.pixel_pitch_um=1.5,2,3 (repeat for a grid)")
    s.add_argument("--out", required=True, help="folder for study.json/.csv/.md and pareto.png; rerun to resume")
    s.add_argument("--x", default="mtf50_cy_px", choices=sorted(HIGHER_IS_BETTER),
                   help="metric on the Pareto chart's x axis (default mtf50_cy_px)")
    s.add_argument("--y", default="snr_at_10pct_full_well_dB", choices=sorted(HIGHER_IS_BETTER),
                   help="metric on its y axis (default snr_at_10pct_full_well_dB)")
    s.add_argument("--workers", type=int, default=0,
                   help="local worker processes (default 0: in this process)")
    s.add_argument("--detector", default=None, metavar="CHECKPOINT",
                   help="a trained detector checkpoint: also report test mAP@0.5 per design on --data")
    s.add_argument("--data", default=None, help="the rendered data set for --detector (workbench dataset)")
    s.add_argument("--confirm-large", action="store_true",
                   help="measure a grid of more than 200 designs (refused without it, with an estimate of the time)")
    add_compute_options(s)
    s.set_defaults(func=cmd_study)


def _summary_lines(metrics: dict) -> str:
    """Each summary metric with ± its measured uncertainty (σ), or the reason it has no value; then
    the colour error in words."""
    from workbench.metrics.study import colour_lines, summary_value
    why = metrics.get("null_reasons", {})
    return "\n".join([f"  {k:32s} {summary_value(metrics, k) if v is not None else why.get(k) or '—'}"
                      for k, v in metrics["summary"].items() if k != "mtf50_sd_cy_px"] +
                     ([f"  (±: σ over {metrics['noise_draws']} noise draws)"] if metrics.get("noise_draws") else []) +
                     [f"  {text}" for text in colour_lines(metrics)])


def cmd_metrics(args) -> int:
    from workbench.metrics.frame import camera_metrics
    from workbench.metrics.study import write_metrics
    from workbench.project import load_project
    project = load_project(args.project)
    with _out_lock(args.out, "workbench metrics"):
        metrics = camera_metrics(project)
        paths = write_metrics(metrics, args.out) if args.out is not None else None   # saved before anything is
    print(f"{project.name}:\n{_summary_lines(metrics)}")                           # printed: a closed pipe loses none
    if paths is not None:
        print(json.dumps({k: str(v) for k, v in paths.items()}))
    return 0


def _out_lock(out: str | None, what: str):
    """The lock of the --out folder (prepared first), so a second command on it is refused before it
    measures anything; nothing to hold without --out."""
    from contextlib import nullcontext

    from workbench.compute.folder_lock import hold_folder_lock
    from workbench.files import prepare_output_folder
    return nullcontext() if out is None else hold_folder_lock(prepare_output_folder(out), what)


def cmd_compare(args) -> int:
    from workbench.metrics.study import compare_designs
    from workbench.project import load_project
    a, b = load_project(args.a), load_project(args.b)
    with _out_lock(args.out, "workbench compare"):
        doc = compare_designs(a, b, args.out)
    from workbench.metrics.bounds import shown
    for row in doc["table"]:
        why = row.get("null_reasons", {})
        print(f"{row['metric']:32s} A {shown(row['A'], why.get('A')):>10s}  B {shown(row['B'], why.get('B')):>10s}  "
              f"{row['']}")
    print(f"report: {args.out}/compare.md")
    return 0


def cmd_study(args) -> int:
    from workbench.errors import ParameterError
    from workbench.jobs import run_job
    from workbench.metrics.study import parse_vary, run_study
    from workbench.project import load_project
    if (args.detector is None) != (args.data is None):
        raise ParameterError("--detector/--data", args.detector or args.data, "give both or neither")
    if args.workers < 0:
        raise ParameterError("--workers", args.workers, "must be 0 (this process) or more")
    project = load_project(args.project)

    def report(p) -> None:
        print(f"[{p.done}/{p.total}] {p.message}", file=sys.stderr, flush=True)
    doc = run_job(run_study(project, parse_vary(args.vary), args.out, x=args.x, y=args.y,
                            compute=compute_spec(args), detector=args.detector, data=args.data,
                            confirm_large=args.confirm_large), report)
    print(f"{len(doc['designs'])} designs; machine time {sum(d['seconds'] for d in doc['designs']):.1f} s; "
          f"table {args.out}/study.md, chart {args.out}/pareto.png")
    return 0
