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
from workbench.metrics.bounds import shown
from workbench.metrics.frame import LOW_LIGHT_SNR_KEY
from workbench.metrics.tolerance import (TOLERANCE_RULE, TOLERANCE_SIGMAS,  # noqa: F401
                                        difference_tolerance, epsilon_dominates)
from workbench.files import json_text

STUDY_FORMAT = "camera-workbench-study"
# what the measurements mean: 2 = e-SFR flat-fielded, raw planes at full resolution, MTF50's spread;
# 3 = ΔE fitted and held out on flat-fielded patch means, each metric's uncertainty over noise draws;
# 4 = MTF50 from a quadratic fitted about the 0.5 crossing (the first crossing read noisy curves low);
# 5 = an edge the exposure clips re-exposed unclipped, SNR measured at 10 % of the electrons at
# saturation, the dynamic range from them (analog gain counted), saturation_e in the summary;
# a resumed study re-measures the designs of another version instead of mixing them into one table
METRICS_VERSION = 5
DELTA_E_NOTE = ("ΔE2000: the Macbeth chart shot with its brightest pixels at 90 % of the swing, the ISP's XYZ of "
                "flat-fielded patch means (divided by the noise-free frame of a uniform white field through the same "
                "optics, so lens fall-off is not counted), exposure matched on neutral 5; delta_e_held_out: each "
                "patch through the colour matrix fitted to the other 23 (leave-one-out: colours the fit never saw); "
                "delta_e_mean/max: fitted (training) patches, the matrix fitted to all 24.")
MAX_DESIGNS = 200                  # a larger grid needs confirm_large (--confirm-large)
# CPU seconds of camera_metrics per sensor pixel (paper_camera, 640×480: 23 s on one core, measured); the
# estimate of a grid's time scales it by the starting design's pixels
SECONDS_PER_DESIGN_PIXEL = 23.0 / (640 * 480)
# summary metrics and whether more is better (for the Pareto front)
HIGHER_IS_BETTER = {"mtf50_cy_px": True, "mtf_nyquist": True, "mtf50_lp_mm": True, "snr_at_10pct_full_well_dB": True,
                    LOW_LIGHT_SNR_KEY: True, "noise_equivalent_exposure_lux_s": False,
                    "delta_e_held_out_mean": False, "delta_e_held_out_max": False,
                    "delta_e_mean": False, "delta_e_max": False, "read_noise_e": False, "full_well_e": True,
                    "saturation_e": True, "dynamic_range_dB": True, "map": True}


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
    sections = {}
    for sec, vals in changes.items():
        try:
            sections[sec] = getattr(project, sec).updated(**vals)
        except ValidationError as exc:                  # named with its section: 'sensor.read_noise_V'
            raise parameter_error(exc, prefix=sec) from None
    try:
        return project.updated(**sections)
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
        metrics["detection"] = design_map(project, job.detector, job.data, bootstrap=MAP_BOOTSTRAP)
        metrics["summary"]["map"] = metrics["detection"]["map"]
        metrics["uncertainty"]["map"] = metrics["detection"]["map_bootstrap_sd"]
    return {"design": job.name, "values": job.values, **metrics, "seconds": time.perf_counter() - t0}


def table_rows(designs: list[dict]) -> list[dict]:
    return [{"design": d["design"], **d["values"], **d["summary"], "seconds": round(d["seconds"], 2)}
            for d in designs]


def _markdown(rows: list[dict], reasons: list[dict] | None = None) -> str:
    """A Markdown table of rows; a None cell shows its reason (reasons[i][column]) or a dash."""
    if not rows:
        return "(no designs yet)\n"
    cols = list(rows[0])
    reasons = reasons or [{} for _ in rows]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(shown(r.get(c), why.get(c)) for c in cols) + " |" for r, why in zip(rows, reasons)]
    return "\n".join(lines) + "\n"


def study_sigma(designs: list[dict], x: str, y: str) -> dict[str, tuple]:
    """Design name → (σ_x, σ_y), the designs' measured uncertainties (None where not measured)."""
    return {d["design"]: tuple((d.get("uncertainty") or {}).get(m) for m in (x, y)) for d in designs}


def epsilon_note(sigma: dict[str, tuple], metrics: tuple[str, str]) -> str:
    """The ε-dominance rule of a study's front and the ε values its pairs of designs have."""
    parts = []
    for i, name in enumerate(metrics):
        eps = [difference_tolerance(a[i], b[i]) for a, b in itertools.combinations(sigma.values(), 2)]
        parts.append(f"{name} ε {min(eps):.3g}–{max(eps):.3g}" if eps else f"{name} ε —")
    return ("The front is by ε-dominance: a design is left off only when another is better by more than ε on one "
            "metric and worse by no more than ε on the other, ε = the compare tolerance of the pair, "
            f"{TOLERANCE_SIGMAS:g}·√(σ₁² + σ₂²) of their measured uncertainties (a design measured without "
            f"them counts σ = 0). Here: {'; '.join(parts)}.\n")


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
    sigma = study_sigma(doc["designs"], x, y)
    front = pareto_front(rows, x, y, HIGHER_IS_BETTER.get(x, True), HIGHER_IS_BETTER.get(y, True), sigma)
    md = (f"# Design study of {doc['project']}\n\n{len(rows)} of {doc['planned']} designs measured; machine "
          f"time {sum(d['seconds'] for d in doc['designs']):.1f} s.\n\n"
          + "".join(f"Note: {n}.\n\n" for n in doc.get("notes", []))
          + _markdown(rows, [d.get("null_reasons", {}) for d in doc["designs"]]) +
          f"\nPareto front of {x} and {y}: {', '.join(front) or '—'}\n\n" + epsilon_note(sigma, (x, y)))
    fig = Figure(figsize=(6.5, 5))
    draw_pareto(fig.add_subplot(), rows, x, y, HIGHER_IS_BETTER.get(x, True), HIGHER_IS_BETTER.get(y, True),
                fields=list(doc["vary"]), sigma=sigma)
    fig.tight_layout()
    png = io.BytesIO()
    fig.savefig(png, dpi=110, format="png")
    atomic_write_files({out / "pareto.png": png.getvalue(), out / "study.csv": buf.getvalue().encode(),
                        out / "study.md": md.encode(),
                        out / "study.json": (json_text(doc) + "\n").encode()})


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
           "planned": len(grid), "notes": notes, "metrics_version": METRICS_VERSION, "designs": []}
    with hold_folder_lock(out, "workbench study"):          # a second study on this folder is refused
        if (out / "study.json").exists():
            old = read_json_object(out / "study.json", "study file", "")
            if any(old.get(k) != doc[k] for k in ("format", "vary", "project", "detector")):
                raise OutputPathError(out, "holds another study (project, --vary or --detector differ); choose "
                                           "another --out")
            if old.get("metrics_version", 1) == METRICS_VERSION:
                doc["designs"] = checked_designs(out / "study.json", old.get("designs"), grid)
            else:
                notes.append(f"the designs measured by metrics version {old.get('metrics_version', 1)} are "
                             f"measured again (version {METRICS_VERSION}: flat-fielded e-SFR, held-out ΔE, "
                             "measured uncertainties, MTF50 fitted about its crossing, unclipped edges, SNR at "
                             "10 % of saturation)")
        done = {d["design"] for d in doc["designs"]}
        jobs = [DesignJob(name, values, p.model_dump_json(), detector, data) for name, values, p in grid
                if name not in done]
        yield Progress(len(done), len(grid), f"{len(grid)} designs, {len(done)} already measured"
                                             + "".join(f"; note: {n}" for n in notes))
        for job, result in run_jobs(measure_design, jobs, compute or ComputeSpec(workers=0), cancel):
            doc["designs"].append(seal_design(result))
            write_study(doc, out, x, y)
            yield Progress(len(doc["designs"]), len(grid), f"{job.name}: MTF50 {summary_value(result, 'mtf50_cy_px')}")
        write_study(doc, out, x, y)
    return doc


def summary_sigma(metrics: dict, key: str) -> float | None:
    """A summary metric's uncertainty (σ): over the noise draws when measured, else, for MTF50, the
    bootstrap standard deviation over the edge's rows."""
    sigma = metrics.get("uncertainty", {}).get(key)
    if sigma is None and key == "mtf50_cy_px":
        sigma = metrics["summary"].get("mtf50_sd_cy_px")
    return sigma


def summary_value(metrics: dict, key: str) -> str:
    """A summary metric as text, with ± its uncertainty (summary_sigma) when it has one."""
    v, sd = metrics["summary"].get(key), summary_sigma(metrics, key)
    text = f"{v:.4g}" if isinstance(v, float) else str(v)
    return text + (f" ± {sd:.2g}" if isinstance(v, float) and sd else "")


def colour_lines(metrics: dict) -> list[str]:
    """ΔE2000 of a design in words: held out beside fitted (training) patches, and the sRGB output."""
    colour = metrics.get("colour")
    if not colour:
        return []
    out = colour["srgb_output"]
    lines = []
    if colour.get("held_out") is not None:
        held, fitted = colour["held_out"], colour["fitted"]
        lines += [f"ΔE2000 held-out patches (leave-one-out fits): mean {held['mean']:.2f}, max {held['max']:.2f} "
                  f"({held['worst']})",
                  f"ΔE2000 fitted (training) patches: mean {fitted['mean']:.2f}, max {fitted['max']:.2f} "
                  f"({fitted['worst']})"]
    lines.append(f"ΔE2000 of the sRGB output as rendered (fitted matrix, lens fall-off and gamut clipping "
                 f"included): mean {out['mean']:.2f}, max {out['max']:.2f}")
    return lines


def metrics_markdown(metrics: dict) -> str:
    """metrics.md: each summary metric with its measured uncertainty, the colour error in words, then
    MTF50 (± its bootstrap standard deviation over the edge's rows), MTF(0.25) and MTF(0.5) of every
    plane, with the closed form optics × pixel beside the raw planes."""
    fmt = (lambda v: "—" if v is None else f"{v:.4g}")
    rows = [{"metric": k, "value": v, "± σ": summary_sigma(metrics, k)} for k, v in metrics["summary"].items()
            if k != "mtf50_sd_cy_px"]
    lines = [f"# Camera metrics of {metrics['project']}", "", _markdown(rows).rstrip("\n"), "",
             f"σ: the standard deviation over {metrics.get('noise_draws')} noise draws of the charts (for the "
             "noise-equivalent exposure and the low-light SNR at least the standard error of the sensitivity); "
             "design parameters are exact.", ""]
    lines += [f"- {line}" for line in colour_lines(metrics)] + ["", DELTA_E_NOTE]
    lines += ["", "## MTF (ISO 12233 e-SFR, flat-fielded; cycles per sensor pixel)", "",
              "| plane | MTF50 | ± 1σ | MTF(0.25) | MTF(0.5) | plane Nyquist | trusted up to | closed-form MTF50 |",
              "|---|---|---|---|---|---|---|---|"]
    for r in metrics["mtf"]:
        lines.append(f"| {r['plane']} | {fmt(r['mtf50_cy_px'])} | {fmt(r.get('mtf50_sd_cy_px'))} | "
                     f"{fmt(r.get('mtf_0.25'))} | {fmt(r['mtf_nyquist'])} | {fmt(r.get('nyquist_cy_px'))} | "
                     f"{fmt(r.get('reliable_up_to_cy_px'))} | {fmt(r.get('model_mtf50_cy_px'))} |")
    notes = [f"{r['plane']}: {r['note']}" for r in metrics["mtf"] if r.get("note")]
    lines += ["", "± 1σ: standard deviation of MTF50 over a bootstrap of the edge region's rows. Raw planes: "
              "each channel's own sites at their full-grid positions; closed form = the optics' model × the "
              "pixel aperture, weighted by the channel's spectrum. " + "; ".join(notes) + "."]
    return "\n".join(lines) + "\n"


def write_metrics(metrics: dict, out_dir) -> dict:
    """metrics.json, metrics.md (metrics_markdown) and metrics.png (MTF, SNR and ΔE charts) of one
    design; returns their paths."""
    from matplotlib.figure import Figure

    from workbench.files import atomic_write_files
    from workbench.metrics.charts import draw_metrics
    out = _output_folder(out_dir)
    fig = Figure(figsize=(11, 8), layout="constrained")     # room for the legends beside the axes
    draw_metrics(fig, [metrics])
    png = io.BytesIO()
    fig.savefig(png, dpi=110, format="png")
    paths = {"json": out / "metrics.json", "md": out / "metrics.md", "png": out / "metrics.png"}
    atomic_write_files({paths["png"]: png.getvalue(), paths["md"]: metrics_markdown(metrics).encode(),
                        paths["json"]: (json_text(metrics) + "\n").encode()})
    return paths


def _output_folder(out_dir) -> Path:
    from workbench.files import prepare_output_folder
    return prepare_output_folder(out_dir)


# how far apart two designs' measurements of a metric must be to call one better: this many standard
# deviations of their difference, √(σ_A² + σ_B²), σ each design's measured uncertainty (≈ 95 %)
MAP_BOOTSTRAP = 200                    # test-set resamples for the uncertainty of a design's mAP
def compare_verdict(metric: str, a: float | None, b: float | None, sigma_a: float | None = None,
                    sigma_b: float | None = None, why_a: str | None = None, why_b: str | None = None) -> str:
    """'A better', 'B better', 'same within ±x' (difference_tolerance of the two uncertainties);
    'not comparable: …' when one has no finite value and a reason (why_a, why_b: an unbounded SNR
    is no number to compare), else '' when one is missing."""
    if a is None or b is None:
        whys = [f"{name} {why}" for name, value, why in (("A", a, why_a), ("B", b, why_b)) if value is None and why]
        return "not comparable: " + ", ".join(whys) if whys else ""
    x = difference_tolerance(sigma_a, sigma_b)
    if abs(b - a) <= x:
        return f"same within ±{x:.2g}"
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
    from workbench.project import difference_labels, project_differences
    changed = [{"field": f, "A": va, "B": vb} for f, va, vb in project_differences(a, b)]
    rows, reasons = [], []
    for key, better in HIGHER_IS_BETTER.items():
        va, vb = ma["summary"].get(key), mb["summary"].get(key)
        why = {"A": ma.get("null_reasons", {}).get(key), "B": mb.get("null_reasons", {}).get(key)}
        if va is None and vb is None and not any(why.values()):
            continue
        sa, sb = ma.get("uncertainty", {}).get(key), mb.get("uncertainty", {}).get(key)
        rows.append({"metric": key, "A": va, "B": vb, "B − A": None if va is None or vb is None else vb - va,
                     "±": difference_tolerance(sa, sb),
                     "": compare_verdict(key, va, vb, sa, sb, why["A"], why["B"])})
        why = {k: v for k, v in why.items() if v and rows[-1][k] is None}
        if why:
            rows[-1]["null_reasons"] = why
        reasons.append(why)
    what = ("Changed from A to B: " + "; ".join(f"{c['field']} {c['A']} → {c['B']}" for c in changed)
            if changed else "A and B are the same design (no parameter differs).")

    def boot(m: dict) -> str:
        v, sd = m["summary"].get("mtf50_cy_px"), m["summary"].get("mtf50_sd_cy_px")
        return "—" if v is None else f"{v:.4g}" + ("" if sd is None else f" ± {sd:.2g}")
    spread = f"\nMTF50 ± 1σ (bootstrap over the edge's rows): A {boot(ma)}, B {boot(mb)} cy/px.\n"
    table = [{k: v for k, v in r.items() if k != "null_reasons"} for r in rows]
    md = (f"# {ma['project']} (A) against {mb['project']} (B)\n\n{what}\n\n" + _markdown(table, reasons) + spread +
          f"\nVerdict: {TOLERANCE_RULE}; noise draws per design: A {ma.get('noise_draws')}, B {mb.get('noise_draws')}.\n\n"
          "MTF: sRGB luminance by the ISO 12233 slanted edge (cy/px; lp/mm on the sensor). SNR: the uniform "
          "field, measured, at 10 % of the electrons at saturation (each channel exposed to put its mean there; the "
          "full well at analog gain 1, less at higher gain) and for a 10 cd/m² surface exposed 10 ms through the "
          "optics (green channel). Noise-equivalent exposure: sensor-plane lux·s where SNR = 1. " + DELTA_E_NOTE +
          " Dynamic range: the electrons at saturation over the read noise (with none, over the ADC's quantisation "
          "noise). MTF: where the design's exposure clips the slanted edge, the edge is re-exposed unclipped "
          "(ISO 12233), and the MTF rows say so.\n")
    label_a, label_b = difference_labels(a, b)
    fig = Figure(figsize=(11, 8), layout="constrained")
    draw_metrics(fig, [{**ma, "label": label_a}, {**mb, "label": label_b}])
    png = io.BytesIO()
    fig.savefig(png, dpi=110, format="png")
    doc = {"A": ma, "B": mb, "changed": changed, "table": rows}
    atomic_write_files({out / "compare.png": png.getvalue(), out / "compare.md": md.encode(),
                        out / "compare.json": (json_text(doc) + "\n").encode()})
    return doc
