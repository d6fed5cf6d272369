"""The paper's two detection experiments over a rendered data set, as resumable long jobs.

ISP stage ('isp'): each network is trained and tested on raw, linear and sRGB captures at EV 0
(the paper's Fig. 5), one run per (network, representation, seed).
Exposure bias ('exposure'): for every EV in the project's experiment.ev_biases, (a) the EV-0-trained
network tested at every EV, (b) a network trained on an EV mix (each EV an equal share of every
epoch, same number of training images) tested at every EV, (c) a network trained and tested at each
EV (the upper bound; at EV 0 it is run (a)): the paper's Fig. 7, on sRGB. As in the paper, where
every network was fine-tuned from COCO-trained weights (well-exposed sRGB photographs), each
condition fine-tunes one starting network per (net, seed) for the same number of epochs; here the
start is trained at EV 0 on sRGB on the training frames (epochs['exposure_base']), since no
COCO weights are used. The ISP experiment trains from random weights (the raw stem differs).

Seeds vary network initialisation, batch order, augmentation and training-capture noise; the
split and the test captures are the same for every run. Summaries: mean mAP over seeds with a
95 % Student-t confidence interval (none for one seed).

Output folder: results.json (the schema in workbench.experiments.results), runs.csv (one row per
run and test EV), summary.csv, a chart (isp.png or exposure.png) and checkpoints/ (one file per
run). Results are rewritten atomically after every finished run, so a killed experiment resumes
without retraining finished runs and never holds a run twice; a half-trained run resumes from its
last epoch checkpoint.
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
from dataclasses import asdict, dataclass, replace
from datetime import datetime, timezone
from functools import partial
from pathlib import Path
from typing import Generator

import numpy as np

from workbench.compute import ComputeSpec
from workbench.errors import OutputPathError, ParameterError
from workbench.experiments.results import RESULTS_FORMAT, RESULTS_SCHEMA_VERSION, read_results
from workbench.jobs import CancelToken, Progress

EXPERIMENTS = ("isp", "exposure")
REPRESENTATION_ORDER = ("raw", "linear", "srgb")
CONDITIONS = ("ev0_trained", "ev_mix", "per_ev")


@dataclass(frozen=True)
class Profile:
    """How big an experiment is. epochs: 'isp' per run; 'exposure_base' for the starting network
    and 'exposure' for each fine-tuned condition; crop_hw: training windows."""

    name: str
    image_hw: tuple[int, int]
    nets: tuple[str, ...]
    seeds: int
    epochs: dict
    batch_size: int
    crop_hw: tuple[int, int] | None
    lr: float
    threads: int | None
    device: str
    loader_workers: int
    cache_mb: float
    note: str


PROFILES = {
    "quick": Profile(
        name="quick", image_hw=(240, 320), nets=("mobile",), seeds=3,
        epochs={"isp": 12, "exposure_base": 8, "exposure": 2},
        batch_size=8, crop_hw=(128, 160), lr=3e-3, threads=1, device="cpu", loader_workers=0, cache_mb=1024.0,
        note="quick profile: 320×240 frames, the 'mobile' net, 1 thread, training on 160×128 windows; "
             "designed to finish each experiment in ≤ 20 min on one uncontended CPU core (≤ 30 min on a "
             "shared 2-core machine) from an already rendered data set of ~400 frames"),
    "paper": Profile(
        name="paper", image_hw=(480, 640), nets=("mobile", "resnet18"), seeds=3,
        epochs={"isp": 60, "exposure_base": 40, "exposure": 20},
        batch_size=16, crop_hw=None, lr=2e-3, threads=None, device="auto", loader_workers=12, cache_mb=4096.0,
        note="paper profile: 640×480 frames (~2,200 train / ~800 test), both nets, ≥ 3 seeds: meant for a "
             "GPU (CUDA with bf16 autocast when present); on a CPU it takes days"),
}


def _digest(*parts) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:10]


def plan_runs(kind: str, profile: Profile, seeds: int, dataset, out_dir: Path):
    """The runs of an experiment as DetectionJobs, each tagged with its role (net,
    representation, condition)."""
    from workbench.detect.train import DetectionJob, TrainConfig

    if kind not in EXPERIMENTS:
        raise ParameterError("experiment", kind, f"one of {', '.join(EXPERIMENTS)}")
    evs = tuple(float(e) for e in dataset.project.experiment.ev_biases)
    if kind == "exposure" and 0.0 not in evs:
        raise ParameterError("experiment.ev_biases", list(evs), "a list of EV biases that includes 0")
    base = TrainConfig(epochs=profile.epochs[kind], batch_size=profile.batch_size, lr=profile.lr,
                       crop_hw=profile.crop_hw, threads=profile.threads, device=profile.device,
                       loader_workers=profile.loader_workers, cache_mb=profile.cache_mb)
    jobs = []

    def add(role: dict, config, test_evs: tuple, tag: str = "") -> str:
        ev_tag = "mix" if len(config.train_evs) > 1 else f"ev{config.train_evs[0]:+g}"
        key = (f"{config.net}-{config.representation}-{tag}{ev_tag}-s{config.seed}-"
               f"{_digest(config.to_json(), test_evs, dataset.fingerprint)}")
        init = str(checkpoints / f"{config.init}.pt") if config.init else None
        jobs.append((role, DetectionJob(key, str(dataset.folder), config, test_evs, str(checkpoints / f"{key}.pt"),
                                        with_curves=kind == "isp", init_checkpoint=init)))
        return key

    checkpoints = out_dir / "checkpoints"
    for net in profile.nets:
        for seed in range(seeds):
            role = {"net": net, "seed": seed}
            if kind == "isp":
                for rep in REPRESENTATION_ORDER:
                    add({**role, "representation": rep, "condition": "ev0_trained"},
                        replace(base, net=net, representation=rep, seed=seed), (0.0,))
                continue
            start = add({**role, "representation": "srgb", "condition": "start"},
                        replace(base, net=net, seed=seed, epochs=profile.epochs["exposure_base"]), (), "start-")
            tuned = replace(base, net=net, seed=seed, init=start)
            add({**role, "representation": "srgb", "condition": "ev0_trained"}, tuned, evs)
            add({**role, "representation": "srgb", "condition": "ev_mix"}, replace(tuned, train_evs=evs), evs)
            for ev in evs:
                if ev != 0.0:
                    add({**role, "representation": "srgb", "condition": "per_ev"},
                        replace(tuned, train_evs=(ev,)), (ev,))
    return jobs


def t_interval(values) -> tuple[float, float | None, float | None, float | None]:
    """(mean, sd, low, high) of a 95 % Student-t interval for the mean; None where n < 2."""
    from scipy import stats
    v = np.asarray(values, dtype=np.float64)
    mean = float(v.mean())
    if v.size < 2:
        return mean, None, None, None
    sd = float(v.std(ddof=1))
    half = float(stats.t.ppf(0.975, v.size - 1) * sd / np.sqrt(v.size))
    return mean, sd, mean - half, mean + half


def result_rows(runs: list[dict]) -> list[dict]:
    """One flat row per run and test EV (the CSV's rows)."""
    rows = []
    for run in runs:
        role = run["role"]
        for test in run["tests"]:
            row = {**{k: role[k] for k in ("net", "representation", "condition", "seed")},
                   "train_evs": " ".join(f"{e:+g}" for e in run["config"]["train_evs"]), "test_ev": test["ev"],
                   "map": test["map"], **{f"ap_{c}": test["ap"].get(c) for c in run["classes"]},
                   "coco_ap50": test.get("coco_ap50"), "train_images": run["train"]["images"],
                   "train_ms_per_image": run["train"]["train_ms_per_image"],
                   "step_ms_per_image": run["train"]["step_ms_per_image"],
                   "train_sensor_isp_ms_per_image": run["train"].get("sensor_isp_ms_per_image"),
                   "test_sensor_isp_ms_per_image": test.get("sensor_isp_ms_per_image"),
                   "infer_ms_per_image": test.get("infer_ms_per_image"), "key": run["key"]}
            rows.append(row)
    return rows


def summarise(kind: str, runs: list[dict]) -> list[dict]:
    """Mean mAP and its 95 % interval over seeds per (net, representation, condition, test EV).
    Exposure: the per-EV upper bound at EV 0 is the EV-0-trained run's EV-0 test."""
    groups: dict[tuple, list[float]] = {}
    for row in result_rows(runs):
        conds = [row["condition"]]
        if kind == "exposure" and row["condition"] == "ev0_trained" and row["test_ev"] == 0.0:
            conds.append("per_ev")
        if row["map"] is None:            # no ground truth in the test frames: nothing to average
            continue
        for cond in conds:
            groups.setdefault((row["net"], row["representation"], cond, row["test_ev"]), []).append(row["map"])
    out = []
    for (net, rep, cond, ev), values in sorted(groups.items(), key=lambda kv: (
            kv[0][0], REPRESENTATION_ORDER.index(kv[0][1]), CONDITIONS.index(kv[0][2]), kv[0][3])):
        mean, sd, lo, hi = t_interval(values)
        out.append({"net": net, "representation": rep, "condition": cond, "test_ev": ev, "n": len(values),
                    "mean_map": mean, "sd": sd, "ci95_low": lo, "ci95_high": hi})
    return out


def _csv_text(rows: list[dict]) -> str:
    buf = io.StringIO()
    if rows:
        cols = list(rows[0])
        for r in rows[1:]:
            cols += [c for c in r if c not in cols]
        writer = csv.DictWriter(buf, fieldnames=cols)
        writer.writeheader()
        writer.writerows(rows)
    return buf.getvalue()


def plot_results(doc: dict, path_png: Path) -> None:
    """The chart of a results document (results.draw_results, as the GUI draws it) to a PNG,
    written atomically."""
    from matplotlib.figure import Figure

    from workbench.experiments.results import draw_results
    nets = len({s["net"] for s in doc["summary"]}) or 1
    fig = Figure(figsize=(6, 4) if doc["kind"] == "isp" else (5.5 * nets, 4))
    draw_results(fig, doc)
    fig.tight_layout()
    tmp = path_png.with_name(f".{path_png.stem}.tmp.png")
    fig.savefig(tmp, dpi=120)
    tmp.replace(path_png)


def write_outputs(doc: dict, out_dir: Path) -> None:
    """results.json, runs.csv, summary.csv and the chart, each written atomically."""
    from workbench.files import atomic_write_text
    atomic_write_text(out_dir / "results.json", json.dumps(doc, indent=1, default=float) + "\n")
    atomic_write_text(out_dir / "runs.csv", _csv_text(result_rows(doc["runs"])))
    atomic_write_text(out_dir / "summary.csv", _csv_text(doc["summary"]))
    plot_results(doc, out_dir / f"{doc['kind']}.png")


def _load_previous(path: Path, kind: str, fingerprint: str, profile: str) -> list[dict]:
    if not path.exists():
        return []
    doc = read_results(path)
    if doc["kind"] != kind or doc["dataset"]["fingerprint"] != fingerprint or doc["profile"] != profile:
        raise OutputPathError(path.parent, f"holds results of another experiment ({doc['kind']}, profile "
                                           f"{doc['profile']}, another data set or project); choose another --out")
    return doc["runs"]


@dataclass
class ExperimentResult:
    out_dir: Path
    results_path: Path
    trained: list[str]
    reused: list[str]
    summary: list[dict]


def run_experiment(kind: str, project, data_dir: str | Path, out_dir: str | Path, *, profile: str = "quick",
                   seeds: int | None = None, workers: int = 0, cancel: CancelToken | None = None,
                   profile_override: Profile | None = None,
                   compute: ComputeSpec | None = None) -> Generator[Progress, None, ExperimentResult]:
    """Run (or resume) experiment `kind` ('isp' | 'exposure') of `project` on the data set in
    data_dir (rendered from the same project's scene, city, pose, optics and render settings; its
    sensor, ISP and experiment settings are the project's). A long job: yields Progress, returns
    an ExperimentResult. workers: 0 = runs in this process (cancellable inside a run), ≥ 1 =
    that many processes (cancellable between runs); compute, when given, says where instead (e.g.
    one Ray task per training run, each with its CPUs as thread budget and, for the paper
    profile, a GPU). profile_override replaces the named profile (tests use tiny ones)."""
    from workbench.compute import run_jobs
    from workbench.detect.data import DetectionDataset
    from workbench.detect.train import run_detection_job
    from workbench.render.dataset import code_version

    if profile_override is None and profile not in PROFILES:
        raise ParameterError("profile", profile, f"one of {', '.join(PROFILES)}")
    prof = profile_override or PROFILES[profile]
    seeds = prof.seeds if seeds is None else seeds
    if not isinstance(seeds, int) or seeds < 1:
        raise ParameterError("seeds", seeds, "an integer ≥ 1")
    dataset = DetectionDataset(data_dir, project=project)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise OutputPathError(out, "is a file; --out needs a folder")
    out.mkdir(parents=True, exist_ok=True)
    jobs = plan_runs(kind, prof, seeds, dataset, out)
    runs = _load_previous(out / "results.json", kind, dataset.fingerprint, prof.name)
    done = {r["key"] for r in runs}
    todo = [(role, job) for role, job in jobs if job.key not in done]
    reused = [job.key for _, job in jobs if job.key in done]
    doc = {"format": RESULTS_FORMAT, "schema_version": RESULTS_SCHEMA_VERSION, "kind": kind, "profile": prof.name,
           "project": project.name, "dataset": {"folder": str(dataset.folder), "fingerprint": dataset.fingerprint,
                                                "stats": dataset.stats()},
           "classes": list(dataset.class_names), "ev_biases": [float(e) for e in project.experiment.ev_biases],
           "settings": {**asdict(prof), "seeds": seeds}, "code_version": code_version(),
           "runs": runs, "summary": summarise(kind, runs), "complete": not todo,
           "written_utc": datetime.now(timezone.utc).isoformat()}
    write_outputs(doc, out)
    h, w = dataset.image_hw
    size_note = "" if (h, w) == tuple(prof.image_hw) else (
        f" (this data set is {w}×{h}, the profile is sized for {prof.image_hw[1]}×{prof.image_hw[0]}: "
        f"expect about {h * w / (prof.image_hw[0] * prof.image_hw[1]):.1f}× the time)")
    yield Progress(len(reused), len(jobs), f"{prof.note}{size_note}; {len(jobs)} runs, {len(reused)} already done")
    role_of = {job.key: role for role, job in jobs}
    compute = compute or ComputeSpec(workers=workers)
    in_process = compute.backend == "local" and compute.workers == 0
    fn = partial(run_detection_job, cancel=cancel) if in_process else run_detection_job
    trained = []
    phases = [[job for _, job in todo if not job.config.init], [job for _, job in todo if job.config.init]]
    for job, result in (pair for phase in phases for pair in run_jobs(fn, phase, compute, cancel)):
        result["role"] = role_of[job.key]
        runs = [r for r in runs if r["key"] != job.key] + [result]
        trained.append(job.key)
        doc.update(runs=runs, summary=summarise(kind, runs), complete=len(trained) == len(todo),
                   written_utc=datetime.now(timezone.utc).isoformat())
        write_outputs(doc, out)
        maps = ", ".join(f"EV{t['ev']:+g} {t['map']:.3f}" if t["map"] is not None else f"EV{t['ev']:+g} -"
                         for t in result["tests"]) or "starting weights"
        yield Progress(len(reused) + len(trained), len(jobs), f"{job.key}: mAP {maps}")
    return ExperimentResult(out, out / "results.json", trained, reused, doc["summary"])
