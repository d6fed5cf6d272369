"""The detection experiments on a tiny synthetic data set: they run end to end, write JSON, CSV and
a chart, and a cancelled or killed experiment resumes without retraining finished runs and
without duplicated results."""
import csv
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from workbench.experiments.detection import PROFILES, run_experiment, summarise, t_interval
from workbench.jobs import CancelToken, JobCancelled

TINY = replace(PROFILES["quick"], name="tiny", image_hw=(48, 64), epochs={"isp": 1, "exposure_base": 1, "exposure": 1},
               crop_hw=None, batch_size=4)
ROOT = Path(__file__).resolve().parents[2]


def _project(evs=(-1.0, 0.0, 1.0)):
    from workbench.detect.synthetic import synthetic_project
    p = synthetic_project()
    return p.updated(experiment=p.experiment.updated(ev_biases=list(evs)))


def _drive(job, cancel=None, cancel_after=None):
    finished = 0
    while True:
        try:
            p = next(job)
        except StopIteration as stop:
            return stop.value
        if cancel_after is not None and p.done > 0 and "mAP" in p.message:
            finished += 1
            if finished >= cancel_after:
                cancel.cancel()


def _check_outputs(out: Path, kind: str, n_runs: int):
    doc = json.loads((out / "results.json").read_text())
    keys = [r["key"] for r in doc["runs"]]
    assert len(keys) == len(set(keys)) == n_runs
    rows = list(csv.DictReader((out / "runs.csv").open()))
    assert len({(r["key"], r["test_ev"]) for r in rows}) == len(rows)
    assert (out / f"{kind}.png").stat().st_size > 1000
    return doc


def test_isp_experiment_runs_end_to_end(synthetic_dir, tmp_path):
    t0 = time.perf_counter()
    job = run_experiment("isp", _project(), synthetic_dir, tmp_path, seeds=2,
                         profile_override=replace(TINY, image_hw=(96, 128)))
    assert "this data set is 64×48" in next(job).message        # the start says what the profile is sized for
    result = _drive(job)
    assert time.perf_counter() - t0 < 120
    doc = _check_outputs(tmp_path, "isp", 6)
    assert doc["complete"] and len(result.trained) == 6
    reps = [(s["representation"], s["n"]) for s in doc["summary"]]
    assert reps == [("raw", 2), ("linear", 2), ("srgb", 2)]
    assert all(s["ci95_low"] <= s["mean_map"] <= s["ci95_high"] for s in doc["summary"])


def test_cancelled_exposure_experiment_resumes_without_retraining(synthetic_dir, tmp_path):
    cancel = CancelToken()
    with pytest.raises(JobCancelled):
        _drive(run_experiment("exposure", _project(), synthetic_dir, tmp_path, seeds=1, profile_override=TINY,
                              cancel=cancel), cancel, cancel_after=2)
    first = json.loads((tmp_path / "results.json").read_text())
    assert len(first["runs"]) == 2 and not first["complete"]
    assert first["runs"][0]["role"]["condition"] == "start"              # the starting network comes first
    result = _drive(run_experiment("exposure", _project(), synthetic_dir, tmp_path, seeds=1, profile_override=TINY))
    assert len(result.reused) == 2 and len(result.trained) == 3          # start, ev0 | mix, EV−1, EV+1
    doc = _check_outputs(tmp_path, "exposure", 5)
    assert doc["runs"][:2] == first["runs"]                              # finished runs kept as they were
    start = doc["runs"][0]["key"]
    assert all(r["config"]["init"] == start for r in doc["runs"][1:])   # every condition is fine-tuned from it
    per_ev = sorted(s["test_ev"] for s in doc["summary"] if s["condition"] == "per_ev")
    assert per_ev == [-1.0, 0.0, 1.0]                                    # EV 0 comes from the EV-0 run


def test_killed_experiment_resumes_without_duplicates(synthetic_dir, tmp_path):
    code = ("import sys; from dataclasses import replace\n"
            "from workbench.experiments.detection import PROFILES, run_experiment\n"
            "from workbench.detect.synthetic import synthetic_project\n"
            "p = synthetic_project(); p = p.updated(experiment=p.experiment.updated(ev_biases=[-1.0, 0.0, 1.0]))\n"
            "prof = replace(PROFILES['quick'], name='tiny', image_hw=(48, 64),"
            " epochs={'isp': 1, 'exposure_base': 1, 'exposure': 1},"
            " crop_hw=None, batch_size=4)\n"
            f"for _ in run_experiment('isp', p, {str(synthetic_dir)!r}, {str(tmp_path)!r}, seeds=1,"
            " profile_override=prof): pass\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen([sys.executable, "-c", code], env=env)
    results = tmp_path / "results.json"
    deadline = time.time() + 120
    while time.time() < deadline:
        if results.exists() and len(json.loads(results.read_text())["runs"]) >= 1:
            break
        time.sleep(0.2)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done_before = {r["key"] for r in json.loads(results.read_text())["runs"]}
    assert 1 <= len(done_before) < 3
    result = _drive(run_experiment("isp", _project(), synthetic_dir, tmp_path, seeds=1, profile_override=TINY))
    assert set(result.reused) == done_before and len(result.trained) == 3 - len(done_before)
    _check_outputs(tmp_path, "isp", 3)


def test_results_of_another_experiment_are_not_mixed(synthetic_dir, tmp_path):
    from workbench.errors import OutputPathError
    _drive(run_experiment("isp", _project(), synthetic_dir, tmp_path, seeds=1,
                          profile_override=replace(TINY, nets=("mobile",))))
    with pytest.raises(OutputPathError, match="another experiment"):
        _drive(run_experiment("exposure", _project(), synthetic_dir, tmp_path, seeds=1, profile_override=TINY))


def test_t_interval_and_summary():
    mean, sd, lo, hi = t_interval([0.5, 0.6, 0.7])
    assert mean == pytest.approx(0.6) and sd == pytest.approx(0.1)
    assert hi - mean == pytest.approx(4.302653 * 0.1 / 3 ** 0.5, rel=1e-6)   # t(0.975, 2) = 4.3027
    assert t_interval([0.4])[1:] == (None, None, None)
    run = {"key": "a", "role": {"net": "mobile", "representation": "srgb", "condition": "ev0_trained", "seed": 0},
           "config": {"train_evs": [0.0]}, "classes": ["car"], "train": {"images": 1, "train_ms_per_image": 1.0,
                                                                        "step_ms_per_image": 1.0},
           "tests": [{"ev": -1.0, "map": 0.2, "ap": {"car": 0.2}}, {"ev": 0.0, "map": 0.5, "ap": {"car": 0.5}}]}
    rows = summarise("exposure", [run])
    assert [(r["condition"], r["test_ev"]) for r in rows] == [("ev0_trained", -1.0), ("ev0_trained", 0.0),
                                                              ("per_ev", 0.0)]


def test_command_line_names_a_missing_data_set(tmp_path):
    from workbench.cli import main
    assert main(["experiment", "isp", "city_detection_quick", "--data", str(tmp_path / "nothing"),
                 "--out", str(tmp_path / "out")]) == 2
