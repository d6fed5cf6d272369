"""Design studies and A/B comparisons over camera_metrics.

    designs = design_grid(project, {"sensor.pixel_pitch_um": [1.5, 2, 3], "optics.f_number": [2, 4, 8]})
    result = run_job(run_study(project, vary, out_dir, compute=ComputeSpec(workers=2)))

A study is a grid of designs: every combination of the values given per field (dotted, as in the
project file). Each design's metrics are measured by a job of plain data (`measure_design`), so
the grid runs in this process, a process pool or on a Ray cluster (workbench.compute); the folder
keeps study.json (rewritten atomically after every design, so a rerun skips the finished ones),
study.csv, study.md and pareto.png of two chosen summary metrics.
"""
from __future__ import annotations

import csv
import hashlib
import io
import itertools
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Generator

from workbench.errors import OutputPathError, ParameterError
from workbench.jobs import Progress
from workbench.metrics.frame import LOW_LIGHT_SNR_KEY

STUDY_FORMAT = "camera-workbench-study"
MAX_DESIGNS = 200                  # a larger grid needs confirm_large (--confirm-large)
# CPU seconds of camera_metrics per sensor pixel (paper_camera, 640×480: 23 s on one core, measured); the
# estimate of a grid's time scales it by the starting design's pixels
SECONDS_PER_DESIGN_PIXEL = 23.0 / (640 * 480)
# summary metrics and whether more is better (for the Pareto front)
HIGHER_IS_BETTER = {"mtf50_cy_px": True, "mtf_nyquist": True, "mtf50_lp_mm": True, "snr_at_10pct_full_well_dB": True,
                    LOW_LIGHT_SNR_KEY: True, "noise_equivalent_exposure_lux_s": False,
                    "delta_e_mean": False, "delta_e_max": False, "read_noise_e": False, "full_well_e": True,
                    "dynamic_range_dB": True, "map": True}


def parse_vary(items: list[str]) -> dict[str, list]:
    """['sensor.pixel_pitch_um=1.5,2,3', …] → {'sensor.pixel_pitch_um': [1.5, 2.0, 3.0], …}; values
    are JSON (numbers, true/false, null) or else text. A field given twice, or a value given twice
    for a field (2 and 2.0 are one value), is refused: it would measure a design twice or drop one."""
    out = {}
    for item in items:
        field, sep, values = item.partition("=")
        field = field.strip()
        if not sep or "." not in field or not values:
            raise ParameterError("--vary", item, "SECTION.FIELD=V1,V2,… (e.g. sensor.pixel_pitch_um=1.5,2,3)")
        if field in out:
            raise ParameterError("--vary", field, "each field once: give all its values in one --vary "
                                                  f"{field}=V1,V2,…")
        parsed = []
        for text in values.split(","):
            try:
                value = json.loads(text)
            except json.JSONDecodeError:
                value = text
            if any(design_name({field: value}) == design_name({field: v}) for v in parsed):
                raise ParameterError(f"--vary {field}", text, "each value once (this one is given twice, or "
                                                              "names the same design as another)")
            parsed.append(value)
        out[field] = parsed
    if not out:
        raise ParameterError("--vary", items, "at least one SECTION.FIELD=V1,V2,…")
    return out


def with_fields(project, values: dict):
    """The project with dotted fields set (each section validated: a bad value names its field)."""
    from pydantic import ValidationError

    from workbench.project import parameter_error
    changes: dict[str, dict] = {}
    for field, value in values.items():
        section, _, name = field.partition(".")
        if not hasattr(project, section):
            raise ParameterError(field, value, f"a field of a project section; '{section}' is none")
        changes.setdefault(section, {})[name] = value
    try:
        return project.updated(**{sec: getattr(project, sec).updated(**vals) for sec, vals in changes.items()})
    except ValidationError as exc:
        raise parameter_error(exc) from None


def design_name(values: dict) -> str:
    return " ".join(f"{field.rsplit('.', 1)[-1]}={value:g}" if isinstance(value, (int, float))
                    and not isinstance(value, bool) else f"{field.rsplit('.', 1)[-1]}={value}"
                    for field, value in values.items())


def design_grid(project, vary: dict[str, list]) -> list[tuple[str, dict, object]]:
    """(name, field values, project) of every combination."""
    fields = list(vary)
    grid = []
    for combo in itertools.product(*(vary[f] for f in fields)):
        values = dict(zip(fields, combo))
        grid.append((design_name(values), values, with_fields(project, values)))
    return grid


def check_grid_size(project, vary: dict[str, list], confirm_large: bool) -> int:
    """The number of designs of the grid; ParameterError, with an estimate of the machine time,
    when it exceeds MAX_DESIGNS and confirm_large is not set (before any design is built)."""
    designs = math.prod(len(v) for v in vary.values())
    if designs > MAX_DESIGNS and not confirm_large:
        per_design_s = max(1.0, SECONDS_PER_DESIGN_PIXEL * project.sensor.rows * project.sensor.cols)
        raise ParameterError("--vary", f"{designs:,} designs", f"at most {MAX_DESIGNS} designs unless confirmed "
                             f"(--confirm-large); this grid would take about {designs * per_design_s / 3600:,.1f} h "
                             f"of CPU time (~{per_design_s:.0f} s a design at {project.sensor.cols}×"
                             f"{project.sensor.rows} px)")
    return designs


def _checksum(node) -> str:
    """SHA-256 of a JSON node (NaN allowed: the measurements' curves may hold some)."""
    return hashlib.sha256(json.dumps(node, sort_keys=True).encode()).hexdigest()


def seal_design(result: dict) -> dict:
    """A design's measurements as study.json stores them (plain JSON) with a checksum of the rest."""
    plain = json.loads(json.dumps(result, default=float))
    return {**plain, "checksum": _checksum(plain)}


def _design_problem(entry, grid_values: dict) -> str | None:
    if not isinstance(entry, dict) or not isinstance(entry.get("design"), str):
        return "not a design's measurements"
    name = entry["design"]
    if name not in grid_values:
        return "not a design of this grid"
    if entry.get("values") != grid_values[name]:
        return "its values are not the grid's for that name"
    summary, seconds = entry.get("summary"), entry.get("seconds")
    if not isinstance(summary, dict) or not all(v is None or isinstance(v, (int, float)) and not isinstance(v, bool)
                                                and math.isfinite(v) for v in summary.values()):
        return "its summary is not a set of finite numbers"
    if not (isinstance(seconds, (int, float)) and not isinstance(seconds, bool) and 0 <= seconds < math.inf):
        return "its 'seconds' is not a time ≥ 0"
    if "checksum" in entry and entry["checksum"] != _checksum({k: v for k, v in entry.items() if k != "checksum"}):
        return "it was changed after it was measured (its checksum does not match)"
    return None


def checked_designs(path: Path, designs, grid) -> list[dict]:
    """The measured designs of a study.json, each a design of `grid` given once with finite
    measurements; InputFileError naming the file and the design otherwise (a design measured
    twice or not in the grid would be counted: progress "[3/2]")."""
    from workbench.errors import InputFileError
    if designs is None:
        return []
    if not isinstance(designs, list):
        raise InputFileError(path, "'designs' must be a list; delete the file to measure the study again")
    grid_values = {name: json.loads(json.dumps(values)) for name, values, _ in grid}
    seen = set()
    for entry in designs:
        problem = _design_problem(entry, grid_values)
        if problem is None and entry["design"] in seen:
            problem = "it is listed twice"
        if problem is not None:
            name = entry.get("design") if isinstance(entry, dict) else None
            raise InputFileError(path, f"design {str(name)[:80]!r}: {problem}; remove that entry to measure it "
                                       "again, or choose another --out")
        seen.add(entry["design"])
    return designs


@dataclass(frozen=True)
class DesignJob:
    """One design of a study as plain data (runs anywhere compute.run_jobs runs jobs)."""

    name: str
    values: dict
    project_json: str
    detector: str | None = None
    data: str | None = None

    def __repr__(self) -> str:
        return f"DesignJob({self.name})"


def measure_design(job: DesignJob) -> dict:
    """camera_metrics of a design (and the detector's test mAP when the job names one), with the
    seconds it took."""
    from workbench.metrics.frame import camera_metrics
    from workbench.project import project_from_dict
    t0 = time.perf_counter()
    project = project_from_dict(json.loads(job.project_json))
    metrics = camera_metrics(project)
    if job.detector is not None:
        from workbench.metrics.detection import design_map
        metrics["detection"] = design_map(project, job.detector, job.data)
        metrics["summary"]["map"] = metrics["detection"]["map"]
    return {"design": job.name, "values": job.values, **metrics, "seconds": time.perf_counter() - t0}


def table_rows(designs: list[dict]) -> list[dict]:
    return [{"design": d["design"], **d["values"], **d["summary"], "seconds": round(d["seconds"], 2)}
            for d in designs]


def _markdown(rows: list[dict]) -> str:
    if not rows:
        return "(no designs yet)\n"
    cols = list(rows[0])
    fmt = (lambda v: f"{v:.4g}" if isinstance(v, float) else str(v))
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(fmt(r.get(c)) for c in cols) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def write_study(doc: dict, out: Path, x: str, y: str) -> None:
    """study.json, study.csv, study.md and pareto.png of a study document, atomically."""
    from matplotlib.figure import Figure

    from workbench.files import atomic_write_files
    from workbench.metrics.charts import draw_pareto, pareto_front
    rows = table_rows(doc["designs"])
    buf = io.StringIO()
    if rows:
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    front = pareto_front(rows, x, y, HIGHER_IS_BETTER.get(x, True), HIGHER_IS_BETTER.get(y, True))
    md = (f"# Design study of {doc['project']}\n\n{len(rows)} of {doc['planned']} designs measured; machine "
          f"time {sum(d['seconds'] for d in doc['designs']):.1f} s.\n\n"
          + "".join(f"Note: {n}.\n\n" for n in doc.get("notes", [])) + _markdown(rows) +
          f"\nPareto front of {x} and {y}: {', '.join(front) or '—'}\n")
    fig = Figure(figsize=(6.5, 5))
    draw_pareto(fig.add_subplot(), rows, x, y, HIGHER_IS_BETTER.get(x, True), HIGHER_IS_BETTER.get(y, True),
                fields=list(doc["vary"]))
    fig.tight_layout()
    png = io.BytesIO()
    fig.savefig(png, dpi=110, format="png")
    atomic_write_files({out / "pareto.png": png.getvalue(), out / "study.csv": buf.getvalue().encode(),
                        out / "study.md": md.encode(),
                        out / "study.json": (json.dumps(doc, indent=1, default=float) + "\n").encode()})


def run_study(project, vary: dict[str, list], out_dir, *, x: str = "mtf50_cy_px",
              y: str = "snr_at_10pct_full_well_dB", compute=None, cancel=None, detector=None,
              data=None, confirm_large: bool = False) -> Generator[Progress, None, dict]:
    """Measure every design of the grid (resuming a folder that holds this study); with a detector
    checkpoint and its data set, each design's test mAP too (summary 'map'). A field no design's
    optics level reads is refused, one read in part is noted (metrics.grid_checks: the document's
    'notes', the first Progress). A grid of more than MAX_DESIGNS designs needs confirm_large. The
    folder is locked while the study runs; designs it already holds are checked (checked_designs).
    Yields Progress, returns the study document."""
    from workbench.compute import ComputeSpec, run_jobs
    from workbench.compute.folder_lock import hold_folder_lock
    from workbench.datasets.files import read_json_object
    for name in (x, y):
        if name not in HIGHER_IS_BETTER:
            raise ParameterError("--x/--y", name, "one of " + ", ".join(HIGHER_IS_BETTER))
    check_grid_size(project, vary, confirm_large)
    from workbench.metrics.grid_checks import check_grid
    notes = check_grid(project, vary)
    grid = design_grid(project, vary)
    if (detector is None) != (data is None):
        raise ParameterError("detector/data", detector or data, "give both a checkpoint and its data set, or neither")
    if detector is not None:                      # refuse before any work: the checkpoint, and each design's frames
        from workbench.detect.data import DetectionDataset
        from workbench.metrics.detection import read_trained
        read_trained(detector)
        for _, _, p in grid:
            DetectionDataset(data, project=p)
        detector, data = str(Path(detector).resolve()), str(Path(data).resolve())
    if "map" in (x, y) and detector is None:
        raise ParameterError("--x/--y", "map", "needs --detector and --data")
    out = _output_folder(out_dir)
    doc = {"format": STUDY_FORMAT, "project": project.name, "vary": vary, "detector": detector,
           "planned": len(grid), "notes": notes, "designs": []}
    with hold_folder_lock(out, "workbench study"):          # a second study on this folder is refused
        if (out / "study.json").exists():
            old = read_json_object(out / "study.json", "study file", "")
            if any(old.get(k) != doc[k] for k in ("format", "vary", "project", "detector")):
                raise OutputPathError(out, "holds another study (project, --vary or --detector differ); choose "
                                           "another --out")
            doc["designs"] = checked_designs(out / "study.json", old.get("designs"), grid)
        done = {d["design"] for d in doc["designs"]}
        jobs = [DesignJob(name, values, p.model_dump_json(), detector, data) for name, values, p in grid
                if name not in done]
        yield Progress(len(done), len(grid), f"{len(grid)} designs, {len(done)} already measured"
                                             + "".join(f"; note: {n}" for n in notes))
        for job, result in run_jobs(measure_design, jobs, compute or ComputeSpec(workers=0), cancel):
            doc["designs"].append(seal_design(result))
            write_study(doc, out, x, y)
            yield Progress(len(doc["designs"]), len(grid), f"{job.name}: MTF50 {result['summary']['mtf50_cy_px']}")
        write_study(doc, out, x, y)
    return doc


def write_metrics(metrics: dict, out_dir) -> dict:
    """metrics.json and metrics.png (MTF, SNR and ΔE charts) of one design; returns their paths."""
    from matplotlib.figure import Figure

    from workbench.files import atomic_write_files
    from workbench.metrics.charts import draw_metrics
    out = _output_folder(out_dir)
    fig = Figure(figsize=(11, 8))
    draw_metrics(fig, [metrics])
    fig.tight_layout()
    png = io.BytesIO()
    fig.savefig(png, dpi=110, format="png")
    paths = {"json": out / "metrics.json", "png": out / "metrics.png"}
    atomic_write_files({paths["png"]: png.getvalue(),
                        paths["json"]: (json.dumps(metrics, indent=1, default=float) + "\n").encode()})
    return paths


def _output_folder(out_dir) -> Path:
    from workbench.files import prepare_output_folder
    return prepare_output_folder(out_dir)


# how far apart two measurements of a metric must be to call one design better: below this they
# read "same within ±tolerance" (the measurement's repeatability on the test charts is about this
# size: MTF50 by the slanted edge ±0.002 cy/px, SNR ±0.1 dB; an exposure 1 %; ΔE ±0.05)
COMPARE_TOLERANCE = {"mtf50_cy_px": ("abs", 0.002), "mtf_nyquist": ("abs", 0.005), "mtf50_lp_mm": ("rel", 0.01),
                     "snr_at_10pct_full_well_dB": ("abs", 0.1), LOW_LIGHT_SNR_KEY: ("abs", 0.1),
                     "noise_equivalent_exposure_lux_s": ("rel", 0.01), "delta_e_mean": ("abs", 0.05),
                     "delta_e_max": ("abs", 0.05), "read_noise_e": ("rel", 0.01), "full_well_e": ("rel", 0.01),
                     "dynamic_range_dB": ("abs", 0.1), "map": ("abs", 0.01)}


def compare_verdict(metric: str, a: float | None, b: float | None) -> str:
    """'A better', 'B better', 'same within ±x' (COMPARE_TOLERANCE) or '' when one is missing."""
    if a is None or b is None:
        return ""
    kind, tol = COMPARE_TOLERANCE.get(metric, ("rel", 0.01))
    width = tol * max(abs(a), abs(b)) if kind == "rel" else tol
    if abs(b - a) <= width:
        return f"same within ±{tol:g}" + (" (relative)" if kind == "rel" else "")
    return "B better" if (b > a) == HIGHER_IS_BETTER.get(metric, True) else "A better"


def compare_designs(a, b, out_dir) -> dict:
    """camera_metrics of two projects, written as compare.json, compare.md (the parameters that
    differ, then a table with the change and a verdict: better only beyond the metric's
    tolerance) and compare.png (MTF, SNR and ΔE of both); returns the comparison."""
    from matplotlib.figure import Figure

    from workbench.files import atomic_write_files
    from workbench.metrics.charts import draw_metrics
    from workbench.metrics.frame import camera_metrics
    out = _output_folder(out_dir)
    ma, mb = camera_metrics(a), camera_metrics(b)
    if ma["project"] == mb["project"]:
        ma["project"], mb["project"] = f"A: {a.name}", f"B: {b.name}"
    from workbench.project import project_differences
    changed = [{"field": f, "A": va, "B": vb} for f, va, vb in project_differences(a, b)]
    rows = []
    for key, better in HIGHER_IS_BETTER.items():
        va, vb = ma["summary"].get(key), mb["summary"].get(key)
        if va is None and vb is None:
            continue
        rows.append({"metric": key, "A": va, "B": vb, "B − A": None if va is None or vb is None else vb - va,
                     "": compare_verdict(key, va, vb)})
    what = ("Changed from A to B: " + "; ".join(f"{c['field']} {c['A']} → {c['B']}" for c in changed)
            if changed else "A and B are the same design (no parameter differs).")
    md = (f"# {ma['project']} (A) against {mb['project']} (B)\n\n{what}\n\n" + _markdown(rows) +
          "\nMTF: sRGB luminance by the ISO 12233 slanted edge (cy/px; lp/mm on the sensor). SNR: the uniform "
          "field, measured, at 10 % of full well and for a 10 cd/m² surface exposed 10 ms through the optics "
          "(green channel). Noise-equivalent exposure: sensor-plane lux·s where SNR = 1. ΔE2000: the Macbeth "
          "chart shot with its brightest pixels at 90 % of the swing, exposure matched on neutral 5; it "
          "includes the optics' fall-off over the chart. Dynamic range: full well over read noise.\n")
    fig = Figure(figsize=(11, 8))
    draw_metrics(fig, [ma, mb])
    fig.tight_layout()
    png = io.BytesIO()
    fig.savefig(png, dpi=110, format="png")
    doc = {"A": ma, "B": mb, "changed": changed, "table": rows}
    atomic_write_files({out / "compare.png": png.getvalue(), out / "compare.md": md.encode(),
                        out / "compare.json": (json.dumps(doc, indent=1, default=float) + "\n").encode()})
    return doc
