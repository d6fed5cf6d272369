"""Run records of the detection experiments: trusted only if they are what the plan made.

A record (one entry of a results.json's 'runs' or 'superseded_runs') names its run by a key that
ends in a digest of its training configuration, the data set's fingerprint and the split it was
trained and tested on (`run_key`; the record's 'split_digest', absent in records made before runs
named their split, when a city's poses could fall in both splits), so a record whose config, data
set, split or key was changed no longer matches. A record this code writes is
also sealed (`seal_record`): 'digest' (the full SHA-256 of config and fingerprint) and 'checksum'
(SHA-256 of the record less its role and tests; each test carries its own, so a record lent to
another experiment may keep a subset of its tests); the document as a whole carries a checksum
too (`seal_document`), so its analysis cannot be edited unseen either. Records written before sealing (no 'checksum')
are checked for all but an edit of their numbers within range. `check_runs` refuses a document
whose records are not unique, not in the plan its settings make (or its budget ladder), not the config they name, or
hold a metric outside its range (AP, mAP in 0…1, losses finite): the file and the run are named.
Refused rather than dropped and retrained: a run costs 10–20 CPU-minutes, and a record that
changed after it was written says something went wrong that the user should see; the message
says how to retrain it (remove the record).
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

from workbench.errors import InputFileError, WorkbenchError
from workbench.experiments.plan import (config_digest, kept_roles, plan_configs, profile_of_settings,  # noqa: F401
                                        run_key)

FIX = "remove that record from the file to train the run again, or choose another --out"


def _checksum(node) -> str:
    """SHA-256 of a JSON node (NaN allowed: a PR curve of a class with no ground truth holds some)."""
    return hashlib.sha256(json.dumps(node, sort_keys=True).encode()).hexdigest()


def _body(run: dict) -> dict:
    return {k: v for k, v in run.items() if k not in ("role", "tests", "checksum")}


def seal_document(doc: dict) -> dict:
    """A results document as results.json stores it (plain JSON) with a checksum of the rest, so an
    edit of its analysis (summary, contrasts, verdicts) is seen too."""
    plain = json.loads(json.dumps(doc, default=float))
    plain.pop("checksum", None)
    return {**plain, "checksum": _checksum(plain)}


def document_problem(doc: dict) -> str | None:
    """Why a sealed results document is not what was written, or None (an unsealed one: None)."""
    if "checksum" in doc and doc["checksum"] != _checksum({k: v for k, v in doc.items() if k != "checksum"}):
        return ("it was changed after it was written (its checksum does not match); restore it, or remove "
                "'checksum' to take the edit as yours")
    return None


def seal_record(run: dict, fingerprint: str) -> dict:
    """The record as results.json stores it (plain JSON), with its digest and checksums."""
    run = json.loads(json.dumps(run, default=float))
    tests = [{**t, "checksum": _checksum({k: v for k, v in t.items() if k != "checksum"})} for t in run["tests"]]
    body = {**_body(run), "digest": config_digest(run["config"], fingerprint, run.get("split_digest"))}
    return {**body, "checksum": _checksum(body), "role": run.get("role"), "tests": tests}


def _fraction(value) -> bool:
    """None, or a finite number in 0…1 (an AP or mAP)."""
    return value is None or _number(value) and 0.0 <= value <= 1.0


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _count(value, low: int = 0) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= low


def _config_problem(config) -> str | None:
    if not isinstance(config, dict):
        return "its 'config' is not an object"
    evs = config.get("train_evs")
    if not (isinstance(config.get("net"), str) and isinstance(config.get("representation"), str)
            and isinstance(evs, list) and evs and all(_number(e) for e in evs)
            and _count(config.get("seed")) and _count(config.get("epochs"), 1)):
        return "its 'config' lacks a net, representation, training EVs, seed or epochs of the right type"
    return None


def _time(value) -> bool:
    """None, or a finite duration or rate ≥ 0."""
    return value is None or _number(value) and value >= 0


def _segments(value) -> bool:
    """A run's parts (engine.training_segments): machine in words, epochs in order, seconds ≥ 0."""
    return isinstance(value, list) and all(
        isinstance(g, dict) and isinstance(g.get("unit"), str) and _count(g.get("first_epoch"), 1)
        and _count(g.get("last_epoch"), g["first_epoch"]) and _number(g.get("seconds")) and g["seconds"] >= 0
        for g in value)


# the other fields of a record and what each must be where present (what the CSV and charts print)
FIELD_RULES = {
    "train": {"steps": _count, "images": _count, "seconds": _time, "sensor_isp_ms_per_image": _time,
              "train_map_ev": _number, "converged": lambda v: v is None or isinstance(v, bool),
              "convergence": lambda v: isinstance(v, str), "autocast": lambda v: isinstance(v, str),
              "segments": _segments},
    "test": {"images": _count, "seconds": _time, "infer_ms_per_image": _time, "sensor_isp_ms_per_image": _time,
             "n_ground_truth": lambda v: isinstance(v, dict) and all(_count(n) for n in v.values())},
    "machine": {"cpu": lambda v: isinstance(v, str), "bf16_native": lambda v: isinstance(v, bool),
                "threads": lambda v: _count(v, 1), "wall_s": _time, "cpu_s": _time,
                "code_version": lambda v: isinstance(v, str)},
}


def _fields_problem(part: str, node: dict) -> str | None:
    bad = [name for name, ok in FIELD_RULES[part].items() if name in node and not ok(node[name])]
    return f"{part}.{bad[0]} {str(node[bad[0]])[:40]!r} is not of its kind" if bad else None


def _train_problem(train, epochs: int) -> str | None:
    if not isinstance(train, dict):
        return "its 'train' is not an object"
    problem = _fields_problem("train", train)
    if problem:
        return problem
    for name in ("train_map", "train_map_half", "train_map_end"):
        if not _fraction(train.get(name)):
            return f"train.{name} {train.get(name)!r} is not a mAP in 0…1"
    history, curve = train.get("history"), train.get("curve")
    if not isinstance(history, list) or len(history) != epochs or not all(
            isinstance(h, dict) and h.get("epoch") == k and _number(h.get("loss"))
            and all(_time(v) for name, v in h.items() if name != "epoch") for k, h in enumerate(history, 1)):
        return f"its loss history is not one set of finite losses ≥ 0 per epoch of its {epochs}"
    if not isinstance(curve, list) or not all(isinstance(c, dict) and _count(c.get("epoch"), 1)
                                              and c["epoch"] <= epochs and _fraction(c.get("train_map"))
                                              for c in curve):
        return "its train-mAP curve is not a list of epochs of the run with mAPs in 0…1"
    if not _number(train.get("final_loss")) or train.get("epochs") != epochs or not _count(train.get("images")):
        return f"it does not record a finished run of {epochs} epochs with a finite final loss"
    for name in ("train_ms_per_image", "step_ms_per_image"):
        if not (_number(train.get(name)) and train[name] >= 0):
            return f"train.{name} {train.get(name)!r} is not a time ≥ 0"
    if train.get("half_gain") is not None and not (_number(train["half_gain"]) and abs(train["half_gain"]) <= 1):
        return f"train.half_gain {train['half_gain']!r} is not a difference of mAPs"
    return None


def _tests_problem(tests, classes: list, evs: set) -> str | None:
    if not isinstance(tests, list) or not tests or not all(isinstance(t, dict) for t in tests):
        return "its 'tests' is not a list of test results"
    seen = set()
    for t in tests:
        ev = t.get("ev")
        if not _number(ev) or float(ev) not in evs or float(ev) in seen:
            return f"test EV {ev!r} is not one of the experiment's EV biases, or is listed twice"
        seen.add(float(ev))
        problem = _fields_problem("test", t)
        if problem:
            return problem
        if not _fraction(t.get("map")) or not _fraction(t.get("coco_ap50")):
            return f"its test mAP at EV {ev:+g} ({t.get('map')!r}) is not in 0…1"
        ap = t.get("ap")
        if not isinstance(ap, dict) or not set(ap) <= set(classes) or not all(_fraction(v) for v in ap.values()):
            return f"its AP per class at EV {ev:+g} is not an AP in 0…1 for each of its classes"
    return None


def _seal_problem(run: dict, fingerprint: str) -> str | None:
    if "digest" in run and run["digest"] != config_digest(run["config"], fingerprint, run.get("split_digest")):
        return "its digest does not match its config and the data set"
    if "checksum" not in run:
        return None                         # written before records were sealed
    if run["checksum"] != _checksum(_body(run)):
        return "it was changed after it was written (its checksum does not match)"
    if not all(t.get("checksum") == _checksum({k: v for k, v in t.items() if k != "checksum"}) for t in run["tests"]):
        return "a test result was changed after it was written (its checksum does not match)"
    return None


def record_problem(run, fingerprint: str, evs: set, doc_classes: list | None = None) -> str | None:
    """What makes `run` not a record of a finished run on the data set of `fingerprint` (classes
    doc_classes, when given) tested at some of `evs`, or None."""
    if not isinstance(run, dict) or not isinstance(run.get("key"), str):
        return "not a run record with a key"
    problem = _config_problem(run.get("config"))
    split = run.get("split_digest")
    if problem is None and split is not None and not isinstance(split, str):
        problem = "its 'split_digest' is not a digest"
    if problem is None and run["key"] != run_key(run["config"], fingerprint, split):
        problem = (f"its key does not name its config on this data set and split (expected "
                   f"{run_key(run['config'], fingerprint, split)})")
    classes, machine = run.get("classes"), run.get("machine", {})
    if problem is None and not (isinstance(classes, list) and classes == list(doc_classes or classes)
                                and len(set(map(str, classes))) == len(classes)
                                and all(isinstance(c, str) for c in classes)):
        problem = "its 'classes' is not the document's list of class names"
    if problem is None:
        problem = _fields_problem("machine", machine) if isinstance(machine, dict) else "its 'machine' is not an object"
    return (problem or _train_problem(run.get("train"), run["config"]["epochs"])
            or _tests_problem(run.get("tests"), classes, evs) or _seal_problem(run, fingerprint))


def _planned_roles(path: Path, doc: dict, evs: tuple) -> dict:
    """{key: role} of the records the document's kind and settings keep in its runs (kept_roles:
    the plan and, for the budget study, its ladder of earlier budgets)."""
    settings = doc.get("settings")
    try:
        return kept_roles(doc["kind"], profile_of_settings(settings), settings["seeds"], evs,
                          doc["dataset"]["fingerprint"], doc["dataset"].get("split_digest"))
    except (WorkbenchError, TypeError, ValueError, KeyError, AttributeError) as exc:
        raise InputFileError(path, f"its 'settings' do not make an experiment plan ({exc.__class__.__name__}: "
                                   f"{str(exc)[:120]}); rerun the experiment into a new folder") from None


def check_runs(path: str | Path, doc: dict) -> None:
    """InputFileError naming the file and the run when the document's records are not unique, a
    run of 'runs' is not in its plan (with the plan's role), or a record fails record_problem."""
    runs, superseded = doc["runs"], doc.get("superseded_runs", [])
    if not isinstance(superseded, list):
        raise InputFileError(path, "'superseded_runs' must be a list")
    dataset, ev_list = doc.get("dataset"), doc.get("ev_biases")
    if (runs or superseded or dataset is not None) and not (isinstance(dataset, dict)
                                                           and isinstance(dataset.get("fingerprint"), str)):
        raise InputFileError(path, "'dataset' must name the data set's fingerprint")
    if (runs or superseded) and not (isinstance(ev_list, list) and all(_number(e) for e in ev_list)):
        raise InputFileError(path, "'ev_biases' must be a list of EV biases")
    if not (runs or superseded):
        return
    fingerprint, evs = dataset["fingerprint"], tuple(float(e) for e in ev_list)
    classes = doc.get("classes")
    if not (classes is None or isinstance(classes, list) and classes and all(isinstance(c, str) for c in classes)):
        raise InputFileError(path, "'classes' must be the list of class names")
    seen = set()
    for run in runs + superseded:
        problem = record_problem(run, fingerprint, set(evs), classes)
        key = run.get("key") if isinstance(run, dict) else None
        if problem is None and key in seen:
            problem = "it is listed twice"
        if problem is not None:
            raise InputFileError(path, f"run {str(key)[:80]!r}: {problem}; {FIX}")
        seen.add(key)
    plan = _planned_roles(path, doc, evs) if runs else {}
    for run in runs:
        if run["key"] not in plan or run.get("role") != plan[run["key"]]:
            raise InputFileError(path, f"run {run['key']!r}: not a run of this experiment's plan (or not in its "
                                       f"role); {FIX}")
