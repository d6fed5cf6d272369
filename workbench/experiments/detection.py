"""The paper's two detection experiments over a rendered data set, as resumable long jobs.

ISP stage ('isp'): each network is trained and tested on raw, linear and sRGB captures at EV 0
(the paper's Fig. 5), one run per (network, representation, seed).
Budget ('budget'): is the profile's training budget B enough? Per network, seeds 0 and 1 train
on sRGB at EV 0 for B and for 2B epochs; B is enough for a net when its test mAP@0.5 at EV 0
gains less than BUDGET_TOLERANCE from B to 2B (mean over the seeds), else the budget must grow
(the 2B runs are tested at every EV too, so they serve as the sRGB EV-0 runs of a budget of 2B).
Exposure bias ('exposure', on sRGB, the paper's Fig. 7): per (network, seed)
    ev0_trained   trained at EV 0, tested at every EV of the project's experiment.ev_biases;
    ev_mix        trained on the EV mix (each EV an equal share of every epoch), tested at every EV;
    per_ev        trained at one EV of the profile's per_ev_biases, tested at every EV.
The protocol is fair: every condition trains from the same random initialisation (the seed) for
the same budget (the profile's epochs for that net). None starts from another condition's weights
(the paper fine-tuned COCO weights, which a fresh install does not have; a start network trained
at EV 0 would favour EV 0). The per-EV curve is called an upper bound only where, for every seed,
it is at least the EV-0-trained and EV-mix curves at its EV (`per_ev_is_upper_bound`).

Seeds vary network initialisation, batch order, augmentation and training-capture noise; the
split and the test captures are the same for every run. Every sRGB run trained at EV 0 for the
budget B (one configuration, one key, in all three experiments) is tested at every EV of the
project, so its record serves each experiment: `reuse_from` folders lend finished records
to another experiment, and a run is never trained twice, in one sitting or the next. What the
runs say is read by paired
statistics (workbench.experiments.analysis): means with a seed t-interval and a test-set bootstrap
interval, paired contrasts, and the paper's claims with a verdict each.

Output folder: results.json (workbench.experiments.results' schema), runs.csv (one row per run and
test EV), summary.csv, contrasts.csv, bootstrap.npz (each run's test-set resamples), a chart
(isp.png, exposure.png or budget.png) and project.json (the project the runs read). Each run
records where it ran (CPU model, threads, wall and CPU seconds, code version). Checkpoints go to
--checkpoints (default OUT/checkpoints), one file per training configuration and data set; they
need not outlive a sitting: the folder is what is kept (a few MB), and a later sitting re-renders
the data set (same fingerprint), points the experiment at the folder and trains only what is
missing. After every finished run the folder is merged and rewritten atomically under its lock:
the records on disk and this process's, by key, so several processes (one per net, say) can fill
one folder, a killed experiment resumes without retraining finished runs, and no run is held
twice; a half-trained run resumes from its last epoch checkpoint while that exists. When the
profile's budget grows (plan.STANDARD_EPOCHS doubles), the old 2B runs are the new B runs and are
reused, not retrained; the budget folder keeps the old B runs in its runs as the ladder's lower
step (plan.budget_ladder_configs, read by budget.budget_analysis), while the ISP and exposure
folders, which read the current budget only, keep them under 'superseded_runs', outside the
analysis, as every folder does with any other record its profile no longer plans (`sort_records`).
"""
from __future__ import annotations

import csv
import io
import json
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from functools import partial
from pathlib import Path
from typing import Generator

import numpy as np

from workbench.compute import ComputeSpec
from workbench.errors import OutputPathError, ParameterError, StageError
from workbench.experiments.analysis import contrasts, summarise
from workbench.experiments.plan import (BUDGET_SEEDS, EXPERIMENTS, PROFILES, Profile, kept_roles,  # noqa: F401
                                        plan_configs, profile_of_settings)
from workbench.experiments.results import (BOOTSTRAP_FILE, RESULTS_FORMAT, RESULTS_SCHEMA_VERSION, read_bootstraps,
                                           read_results)
from workbench.jobs import CancelToken, Progress
from workbench.files import json_text

BUDGET_TOLERANCE = 0.01            # test mAP gain from B to 2B epochs below which budget B is enough
PROJECT_FILE = "project.json"


def plan_runs(kind: str, profile: Profile, seeds: int, dataset, checkpoints: Path):
    """The runs of an experiment as (role, DetectionJob) pairs. A run's key (and checkpoint file)
    names its training configuration, data set and split (which frames are test frames) only, so
    the same training is shared by every experiment that tests it."""
    from workbench.detect.job import DetectionJob
    evs = tuple(float(e) for e in dataset.project.experiment.ev_biases)
    return [(role, DetectionJob(key, str(dataset.folder), config, test_evs, str(checkpoints / f"{key}.pt"),
                                with_curves=kind == "isp"))
            for role, key, config, test_evs in plan_configs(kind, profile, seeds, evs, dataset.fingerprint,
                                                            dataset.split_digest)]


def sort_records(records: list[dict], kept: dict) -> tuple[list[dict], list[dict]]:
    """A folder's records as (runs, superseded_runs): a record of a key in kept ({key: role},
    plan.kept_roles) is a run in that role; any other was planned by an earlier profile."""
    return ([{**r, "role": kept[r["key"]]} for r in records if r["key"] in kept],
            [r for r in records if r["key"] not in kept])


def missing_runs(planned_keys, records: list[dict]) -> list[str]:
    """The planned keys (in plan order) that no record of the folder holds: the runs to train."""
    done = {r["key"] for r in records}
    return [key for key in planned_keys if key not in done]


def segments_text(segments: list[dict] | None) -> str | None:
    """A run's parts in one CSV cell: 'AMD EPYC 1–276 (4,199 s); …' (None when not recorded)."""
    if not segments:
        return None
    return "; ".join(f"{g['unit']} {g['first_epoch']}–{g['last_epoch']} ({g['seconds']:,.0f} s)" for g in segments)


def result_rows(runs: list[dict]) -> list[dict]:
    """One flat row per run and test EV (the CSV's rows)."""
    rows = []
    for run in runs:
        role, train, machine = run["role"], run["train"], run.get("machine", {})
        for test in run["tests"]:
            rows.append({**{k: role[k] for k in ("net", "representation", "condition", "seed")},
                         "train_evs": " ".join(f"{e:+g}" for e in run["config"]["train_evs"]),
                         "epochs": run["config"]["epochs"], "test_ev": test["ev"],
                         "map": test["map"], **{f"ap_{c}": test["ap"].get(c) for c in run["classes"]},
                         "coco_ap50": test.get("coco_ap50"), "train_map": train.get("train_map"),
                         "train_map_half": train.get("train_map_half"), "half_gain": train.get("half_gain"),
                         "converged": train.get("converged"), "autocast": train.get("autocast"),
                         "final_loss": train.get("final_loss"), "train_images": train["images"],
                         "train_ms_per_image": train["train_ms_per_image"],
                         "step_ms_per_image": train["step_ms_per_image"],
                         "train_sensor_isp_ms_per_image": train.get("sensor_isp_ms_per_image"),
                         "test_sensor_isp_ms_per_image": test.get("sensor_isp_ms_per_image"),
                         "infer_ms_per_image": test.get("infer_ms_per_image"), "cpu": machine.get("cpu"),
                         "trained_on": segments_text(train.get("segments")),
                         "run_wall_s": machine.get("wall_s"), "run_cpu_s": machine.get("cpu_s"), "key": run["key"]})
    return rows


def per_ev_is_upper_bound(runs: list[dict]) -> bool | None:
    """True when every per-EV run is, at its own EV, at least the EV-0-trained and EV-mix runs of
    its net and seed; None when there are no per-EV runs."""
    checks = []
    for run in runs:
        role = run["role"]
        if role["condition"] != "per_ev":
            continue
        ev = float(role["train_ev"])
        own = next(t["map"] for t in run["tests"] if t["ev"] == ev)
        for other in runs:
            r = other["role"]
            if r["net"] == role["net"] and r["seed"] == role["seed"] and r["condition"] in ("ev0_trained", "ev_mix"):
                theirs = next((t["map"] for t in other["tests"] if t["ev"] == ev), None)
                if own is not None and theirs is not None:
                    checks.append(own >= theirs)
    return all(checks) if checks else None


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

    from workbench.experiments.results import chart_size_in, draw_results
    from workbench.files import atomic_write_bytes
    fig = Figure(figsize=chart_size_in(doc))
    draw_results(fig, doc)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, dpi=110, format="png")
    atomic_write_bytes(path_png, buf.getvalue())


def write_outputs(doc: dict, boots: dict, out_dir: Path, project=None) -> None:
    """results.json, runs.csv, summary.csv, contrasts.csv, bootstrap.npz, the chart and (given
    the project) project.json, each written atomically."""
    from workbench.files import atomic_write_bytes, atomic_write_text
    if project is not None:
        atomic_write_text(out_dir / PROJECT_FILE, project.model_dump_json(indent=1) + "\n")
    from workbench.experiments.records import seal_document
    atomic_write_text(out_dir / "results.json", json_text(seal_document(doc)) + "\n")
    atomic_write_text(out_dir / "runs.csv", _csv_text(result_rows(doc["runs"])))
    atomic_write_text(out_dir / "summary.csv", _csv_text(doc["summary"]))
    atomic_write_text(out_dir / "contrasts.csv", _csv_text(doc["contrasts"]))
    buf = io.BytesIO()
    np.savez_compressed(buf, **{f"{key}|{ev:+g}": np.asarray(v, np.float16) for key, by_ev in boots.items()
                                for ev, v in by_ev.items()})
    atomic_write_bytes(out_dir / BOOTSTRAP_FILE, buf.getvalue())
    plot_results(doc, out_dir / f"{doc['kind']}.png")


def _load_previous(out: Path, kind: str, fingerprint: str, profile: str) -> tuple[list[dict], dict]:
    if not (out / "results.json").exists():
        return [], {}
    doc = read_results(out)
    if doc["kind"] != kind or (doc.get("dataset") or {}).get("fingerprint") != fingerprint \
            or doc.get("profile") != profile:
        raise OutputPathError(out, f"holds results of another experiment ({doc['kind']}, profile "
                                   f"{str(doc.get('profile'))[:40]}, another data set or project); choose another "
                                   "--out")
    return doc["runs"] + doc.get("superseded_runs", []), read_bootstraps(out)


def borrowed_runs(folders, jobs, fingerprint: str) -> tuple[list[dict], dict]:
    """Finished records of `jobs` in other result folders (same data set; a record serves a job
    of the same key whose test EVs it covers), with their bootstrap resamples, each cut to the
    job's test EVs; the role is set by the caller."""
    wanted = {job.key: set(job.test_evs) for _, job in jobs}
    runs, boots = [], {}
    for folder in folders:
        doc = read_results(folder)
        their_fingerprint = str((doc.get("dataset") or {}).get("fingerprint"))
        if their_fingerprint != fingerprint:
            raise OutputPathError(folder, f"holds results of another data set (fingerprint {their_fingerprint[:12]}… "
                                          f"≠ {fingerprint[:12]}…)")
        theirs = read_bootstraps(folder)
        for run in doc["runs"]:
            evs = wanted.get(run["key"])
            if evs is None or run["key"] in boots or not evs <= {float(t["ev"]) for t in run["tests"]}:
                continue
            runs.append({**run, "tests": [t for t in run["tests"] if float(t["ev"]) in evs]})
            boots[run["key"]] = {ev: v for ev, v in theirs.get(run["key"], {}).items() if ev in evs}
    return runs, boots


def _split_bootstrap(result: dict) -> dict:
    """Take the bootstrap resamples out of a run result: {test EV: float array (NaN for None)}."""
    boots = {}
    for test in result["tests"]:
        values = test.pop("bootstrap_map", None)
        if values is not None:
            boots[float(test["ev"])] = np.array([np.nan if v is None else v for v in values], np.float64)
    return boots


@dataclass
class ExperimentResult:
    out_dir: Path
    results_path: Path
    trained: list[str]
    reused: list[str]
    summary: list[dict]


def _analysis(kind: str, runs: list[dict], boots: dict, evs, epochs: dict | None = None) -> dict:
    """Summary and contrasts of the runs; the ISP and budget experiments read EV 0 only (their
    sRGB runs carry every EV for the exposure experiment); epochs: the profile's budget per net
    (default: that of the budget runs in budget_factor 1)."""
    if kind == "budget":
        from workbench.experiments.budget import budget_analysis
        return budget_analysis(runs, boots, BUDGET_TOLERANCE, epochs)
    if kind == "isp":
        runs = [{**r, "tests": [t for t in r["tests"] if float(t["ev"]) == 0.0]} for r in runs]
    summary = summarise(kind, runs, boots)
    for row in summary:                    # how many of the runs behind a mean converged
        behind = [r for r in runs if all(r["role"].get(k) == row[k] for k in ("net", "representation", "condition"))
                  and (row["condition"] != "per_ev" or r["role"].get("train_ev") == row["test_ev"])]
        row["converged"] = f"{sum(r['train'].get('converged') is True for r in behind)}/{len(behind)}"
    return {"summary": summary, "contrasts": contrasts(kind, runs, boots, evs),
            "per_ev_is_upper_bound": per_ev_is_upper_bound(runs) if kind == "exposure" else None,
            "not_converged": [{"key": r["key"], "convergence": r["train"].get("convergence")} for r in runs
                              if r["train"].get("converged") is not True]}



def _is_count(value, low: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= low


def _check_arguments(kind, profile, seeds, workers, profile_override, compute, checkpoints, nets, reuse_from):
    """ParameterError for an argument of run_experiment of the wrong type or value (seeds=True
    would run one seed; a folder name given as reuse_from would be read letter by letter)."""
    if not isinstance(kind, str) or kind not in EXPERIMENTS:
        raise ParameterError("experiment", kind, f"one of {', '.join(EXPERIMENTS)}")
    if profile_override is None and (not isinstance(profile, str) or profile not in PROFILES):
        raise ParameterError("profile", profile, f"one of {', '.join(PROFILES)}")
    if profile_override is not None and not isinstance(profile_override, Profile):
        raise ParameterError("profile_override", profile_override, "a Profile or None")
    if seeds is not None and not _is_count(seeds, 1):
        raise ParameterError("seeds", seeds, "an integer ≥ 1 (or None: the profile's)")
    if not _is_count(workers, 0):
        raise ParameterError("workers", workers, "an integer ≥ 0 (0: in this process)")
    if compute is not None and not isinstance(compute, ComputeSpec):
        raise ParameterError("compute", compute, "a ComputeSpec or None")
    if checkpoints is not None and (not isinstance(checkpoints, (str, Path)) or not str(checkpoints).strip()):
        raise ParameterError("checkpoints", checkpoints, "a folder name (an empty one would mean the current "
                                                         "folder), or None for OUT/checkpoints")
    for name, value in (("nets", nets), ("reuse_from", reuse_from)):
        if value is not None and (isinstance(value, (str, bytes, Path)) or not isinstance(value, (tuple, list))
                                  or not all(isinstance(v, (str, Path)) and str(v).strip() for v in value)):
            raise ParameterError(name, value, "a tuple of names" if name == "nets" else "a tuple of result folders")


def run_experiment(kind: str, project, data_dir: str | Path, out_dir: str | Path, *, profile: str = "quick",
                   seeds: int | None = None, workers: int = 0, cancel: CancelToken | None = None,
                   profile_override: Profile | None = None, compute: ComputeSpec | None = None,
                   checkpoints: str | Path | None = None, nets: tuple[str, ...] | None = None,
                   reuse_from: tuple[str | Path, ...] = ()) -> Generator[Progress, None, ExperimentResult]:
    """Run (or resume) experiment `kind` ('isp' | 'exposure' | 'budget') of `project` on the data
    set in data_dir (rendered from the same project's scene, city, pose, optics and render
    settings; its sensor, ISP and experiment settings are the project's). A long job: yields
    Progress, returns an ExperimentResult. workers: 0 = runs in this process (cancellable inside a
    run), ≥ 1 = that many processes (cancellable between runs); compute, when given, says where
    instead (e.g. one Ray task per training run, each with its CPUs as thread budget and, for the
    paper profile, a GPU). checkpoints: the folder of training checkpoints (default
    OUT/checkpoints). nets: train only these of the profile's nets (another process may fill the
    same folder with the others). reuse_from: result folders of the same data set whose finished
    runs of the same key are taken instead of trained. profile_override replaces the named
    profile (tests use tiny ones)."""
    from workbench.compute import run_jobs
    from workbench.compute.folder_lock import hold_folder_lock
    from workbench.compute.job_claims import claim, release
    from workbench.detect.data import DetectionDataset
    from workbench.detect.job import loaded_code_version, run_detection_job
    from workbench.experiments.records import record_problem, seal_record
    from workbench.files import prepare_output_folder

    _check_arguments(kind, profile, seeds, workers, profile_override, compute, checkpoints, nets, reuse_from)
    prof = profile_override or PROFILES[profile]
    seeds = prof.seeds if seeds is None else seeds
    unknown = [n for n in (nets or ()) if n not in prof.nets]
    if unknown:
        raise ParameterError("nets", list(nets), f"nets of the profile ({', '.join(prof.nets)})")
    dataset = DetectionDataset(data_dir, project=project)
    dataset.test_indices()                              # refused before any training: a set with no test city
    out = prepare_output_folder(out_dir)
    ckpt_dir = prepare_output_folder(checkpoints) if checkpoints is not None else out / "checkpoints"
    ckpt_dir.mkdir(parents=True, exist_ok=True)
    jobs = plan_runs(kind, prof, seeds, dataset, ckpt_dir)
    role_of = {job.key: role for role, job in jobs}
    kept = kept_roles(kind, prof, seeds, tuple(float(e) for e in project.experiment.ev_biases), dataset.fingerprint,
                      dataset.split_digest)
    evs = [float(e) for e in project.experiment.ev_biases]
    base = {"format": RESULTS_FORMAT, "schema_version": RESULTS_SCHEMA_VERSION, "kind": kind, "profile": prof.name,
            "project": project.name, "dataset": {"folder": dataset.folder.name, "fingerprint": dataset.fingerprint,
                                                 "split_digest": dataset.split_digest,
                                                 "frames": len(dataset.frames), "stats": dataset.stats()},
            "classes": list(dataset.class_names), "ev_biases": evs, "settings": {**asdict(prof), "seeds": seeds}}
    mine: list[dict] = []
    my_boots: dict = {}
    version = loaded_code_version()              # the code this process runs, not the tree's state later

    def merge_and_write() -> dict:
        """The folder's records merged with this process's (by key; role as planned), rewritten."""
        with hold_folder_lock(out, f"workbench experiment {kind}", wait=True):
            runs, boots = _load_previous(out, kind, dataset.fingerprint, prof.name)
            keys = {r["key"] for r in mine}
            runs, superseded = sort_records([r for r in runs if r["key"] not in keys] + mine, kept)
            boots = {**boots, **my_boots}
            doc = {**base, "code_version": version, "runs": runs, **_analysis(kind, runs, boots, evs, prof.epochs),
                   "complete": not missing_runs(role_of, runs),
                   "superseded_runs": superseded, "written_utc": datetime.now(timezone.utc).isoformat()}
            write_outputs(doc, boots, out, project)
        return doc

    with hold_folder_lock(out, f"workbench experiment {kind}", wait=True):
        previous = _load_previous(out, kind, dataset.fingerprint, prof.name)[0]
    missing = missing_runs([job.key for _, job in jobs], previous)
    lent, lent_boots = borrowed_runs(reuse_from, [(r, j) for r, j in jobs if j.key in missing], dataset.fingerprint)
    mine += lent
    my_boots.update(lent_boots)
    missing = missing_runs(missing, lent)
    reused = sorted(set(role_of) - set(missing))
    ladder = sum(r["key"] in kept and r["key"] not in role_of for r in previous)
    todo = [job for _, job in jobs if job.key in missing and (nets is None or job.config.net in nets)]
    doc = merge_and_write()

    def claimed():
        """The todo runs, each claimed (job_claims, in the checkpoint folder) as it is drawn and
        released once its record is written (a claim left by a process that died is stale); runs
        another live process holds, or that the folder gained meanwhile, are skipped."""
        for job in todo:
            with hold_folder_lock(out, f"workbench experiment {kind}", wait=True):
                finished = {r["key"] for r in _load_previous(out, kind, dataset.fingerprint, prof.name)[0]}
            if job.key not in finished and claim(ckpt_dir, job.key):
                yield job

    h, w = dataset.image_hw
    size_note = "" if (h, w) == tuple(prof.image_hw) else (
        f" (this data set is {w}×{h}, the profile is sized for {prof.image_hw[1]}×{prof.image_hw[0]}: "
        f"expect about {h * w / (prof.image_hw[0] * prof.image_hw[1]):.1f}× the time)")
    yield Progress(len(reused), len(jobs), f"{prof.note}{size_note}; {len(jobs)} runs, {len(reused)} already done"
                                           f"{f' ({len(lent)} from other folders)' if lent else ''}, "
                                           f"{len(todo)} to train here"
                                           f"{f'; {ladder} runs of earlier budgets kept as the ladder' * bool(ladder)}")
    compute = compute or ComputeSpec(workers=workers)
    in_process = compute.backend == "local" and compute.workers == 0
    fn = partial(run_detection_job, cancel=cancel) if in_process else run_detection_job
    trained = []
    for job, result in run_jobs(fn, claimed(), compute, cancel):
        result["role"] = role_of[job.key]
        my_boots[job.key] = _split_bootstrap(result)
        result = seal_record(result, dataset.fingerprint)
        problem = record_problem(result, dataset.fingerprint, set(evs), list(dataset.class_names))
        if problem is not None:                    # never a NaN or out-of-range number in a results.json
            raise StageError("experiment", f"run {job.key}: {problem}; its record is not written")
        mine = [r for r in mine if r["key"] != job.key] + [result]
        trained.append(job.key)
        doc = merge_and_write()
        release(ckpt_dir, job.key)
        maps = ", ".join(f"EV{t['ev']:+g} {t['map']:.3f}" if t["map"] is not None else f"EV{t['ev']:+g} -"
                         for t in result["tests"])
        yield Progress(len(reused) + len(trained), len(jobs),
                       f"{job.key}: train mAP {result['train']['train_map'] or 0:.3f} "
                       f"({result['train'].get('convergence', '')}); test mAP {maps}")
    return ExperimentResult(out, out / "results.json", trained, reused, doc["summary"])
