"""The detection experiments on a tiny synthetic data set: they run end to end, write JSON, CSV,
bootstrap resamples and a chart; the exposure protocol gives every condition the same start and
budget; a cancelled or killed experiment resumes without retraining finished runs and without
duplicated results; two experiments sharing a checkpoint folder train the EV-0 sRGB runs once."""
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

from workbench.experiments.detection import PROFILES, plan_runs, run_experiment
from workbench.experiments.results import read_bootstraps
from workbench.jobs import CancelToken, JobCancelled

TINY = replace(PROFILES["quick"], name="tiny", image_hw=(48, 64), epochs={"mobile": 1, "resnet18": 1},
               crop_hw=None, batch_size=4, per_ev_biases=(1.0,), curve_points=1)
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


def _scores(run: dict) -> list:
    """A run's test scores (not its timings): EV, mAP and AP per class."""
    return [(t["ev"], t["map"], t["ap"]) for t in run["tests"]]


def _check_outputs(out: Path, kind: str, n_runs: int):
    doc = json.loads((out / "results.json").read_text())
    keys = [r["key"] for r in doc["runs"]]
    assert len(keys) == len(set(keys)) == n_runs
    rows = list(csv.DictReader((out / "runs.csv").open()))
    assert len({(r["key"], r["test_ev"]) for r in rows}) == len(rows)
    assert (out / f"{kind}.png").stat().st_size > 1000
    return doc


def test_isp_experiment_runs_end_to_end(synthetic_dir, tmp_path):
    job = run_experiment("isp", _project(), synthetic_dir, tmp_path, seeds=2,
                         profile_override=replace(TINY, image_hw=(96, 128)))
    assert "this data set is 64×48" in next(job).message        # the start says what the profile is sized for
    result = _drive(job)
    doc = _check_outputs(tmp_path, "isp", 6)
    assert doc["complete"] and len(result.trained) == 6
    reps = [(s["representation"], s["n"], s["test_ev"]) for s in doc["summary"]]
    assert reps == [("raw", 2, 0.0), ("linear", 2, 0.0), ("srgb", 2, 0.0)]     # sRGB runs carry every EV
    by_key = {r["key"]: r for r in doc["runs"]}
    for s in doc["summary"]:
        maps = [next(t["map"] for t in r["tests"] if t["ev"] == 0.0) for r in doc["runs"]
                if r["role"]["representation"] == s["representation"]]
        assert s["mean_map"] == pytest.approx(sum(maps) / 2)
    assert sorted(r["contrast"] for r in doc["contrasts"]) == ["linear − srgb", "raw − srgb"]
    boots = read_bootstraps(tmp_path)
    assert set(boots) == set(by_key) and all(len(b[0.0]) == 1000 for b in boots.values())
    for run in doc["runs"]:
        assert "bootstrap_map" not in run["tests"][0]                # resamples live in bootstrap.npz
        assert 0.0 <= run["train"]["train_map"] <= 1.0 and run["train"]["curve"]
        assert run["machine"]["cpu"] and run["machine"]["wall_s"] > 0 and run["machine"]["threads"] >= 1
        assert run["train"]["convergence"]
    assert json.loads((tmp_path / "project.json").read_text())["name"] == _project().name
    assert doc["dataset"]["folder"] == synthetic_dir.name and doc["code_version"]
    assert (tmp_path / "contrasts.csv").read_text().startswith("contrast,")


def test_every_exposure_condition_starts_alike_and_trains_as_long():
    from workbench.detect.data import DetectionDataset  # noqa: F401  (the planner needs only the project)

    class _Set:
        project, fingerprint, folder, split_digest = _project((-1.0, 0.0, 1.0)), "f", "/set", "s"
    jobs = plan_runs("exposure", replace(TINY, nets=("mobile", "resnet18"), epochs={"mobile": 3, "resnet18": 2}),
                     2, _Set(), Path("/ckpt"))
    assert len(jobs) == 2 * 2 * 3                                   # nets × seeds × (EV 0, mix, EV +1)
    for net in ("mobile", "resnet18"):
        for seed in range(2):
            configs = [job.config for role, job in jobs if role["net"] == net and role["seed"] == seed]
            plain = {json.dumps({**json.loads(c.to_json()), "train_evs": None}) for c in configs}
            assert len(plain) == 1                                  # only the training EVs differ
            assert sorted(c.train_evs for c in configs) == [(-1.0, 0.0, 1.0), (0.0,), (1.0,)]
    assert all(job.test_evs == (-1.0, 0.0, 1.0) for _, job in jobs)


def test_cancelled_exposure_experiment_resumes_without_retraining(synthetic_dir, tmp_path):
    cancel = CancelToken()
    with pytest.raises(JobCancelled):
        _drive(run_experiment("exposure", _project(), synthetic_dir, tmp_path, seeds=1, profile_override=TINY,
                              cancel=cancel), cancel, cancel_after=2)
    first = json.loads((tmp_path / "results.json").read_text())
    assert len(first["runs"]) == 2 and not first["complete"]
    result = _drive(run_experiment("exposure", _project(), synthetic_dir, tmp_path, seeds=1, profile_override=TINY))
    assert len(result.reused) == 2 and len(result.trained) == 1          # ev0, mix | EV +1
    doc = _check_outputs(tmp_path, "exposure", 3)
    assert doc["runs"][:2] == first["runs"]                              # finished runs kept as they were
    per_ev = sorted(s["test_ev"] for s in doc["summary"] if s["condition"] == "per_ev")
    assert per_ev == [0.0, 1.0]                                          # EV 0 comes from the EV-0 run
    assert doc["per_ev_is_upper_bound"] in (True, False)
    assert {r["contrast"] for r in doc["contrasts"]} >= {"ev_mix − ev0_trained", "under − over"}


def test_experiments_sharing_checkpoints_train_the_ev0_srgb_run_once(synthetic_dir, tmp_path):
    ckpt = tmp_path / "ckpt"
    prof = replace(TINY, per_ev_biases=())
    _drive(run_experiment("isp", _project(), synthetic_dir, tmp_path / "isp", seeds=1, profile_override=prof,
                          checkpoints=ckpt))
    isp_srgb = next(r for r in json.loads((tmp_path / "isp" / "results.json").read_text())["runs"]
                    if r["role"]["representation"] == "srgb")
    stamp = (ckpt / f"{isp_srgb['key']}.pt").stat().st_mtime_ns
    _drive(run_experiment("exposure", _project(), synthetic_dir, tmp_path / "exp", seeds=1, profile_override=prof,
                          checkpoints=ckpt))
    exposure = json.loads((tmp_path / "exp" / "results.json").read_text())
    ev0 = next(r for r in exposure["runs"] if r["role"]["condition"] == "ev0_trained")
    assert ev0["key"] == isp_srgb["key"] and (ckpt / f"{ev0['key']}.pt").stat().st_mtime_ns == stamp
    assert [t["ev"] for t in ev0["tests"]] == [-1.0, 0.0, 1.0]
    assert _scores(ev0) == _scores(isp_srgb)                       # the isp run was tested at every EV too


def test_killed_experiment_resumes_without_duplicates(synthetic_dir, tmp_path):
    code = ("import sys; from dataclasses import replace\n"
            "from workbench.experiments.detection import PROFILES, run_experiment\n"
            "from workbench.detect.synthetic import synthetic_project\n"
            "p = synthetic_project(); p = p.updated(experiment=p.experiment.updated(ev_biases=[-1.0, 0.0, 1.0]))\n"
            "prof = replace(PROFILES['quick'], name='tiny', image_hw=(48, 64),"
            " epochs={'mobile': 1, 'resnet18': 1}, crop_hw=None, batch_size=4, per_ev_biases=(1.0,),"
            " curve_points=1)\n"
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


def test_command_line_names_a_missing_data_set(tmp_path):
    from workbench.cli import main
    assert main(["experiment", "isp", "city_detection_quick", "--data", str(tmp_path / "nothing"),
                 "--out", str(tmp_path / "out")]) == 2


def test_a_resumed_experiment_on_a_re_rendered_data_set_ends_as_an_uninterrupted_one(tmp_path):
    """What a later sitting does: the data set and checkpoints are gone, the result folder is
    kept; the set is made again (same fingerprint) and only the missing runs train."""
    import shutil

    from workbench.detect.synthetic import make_synthetic_dataset
    make_synthetic_dataset(tmp_path / "set", frames=14)
    full = _drive(run_experiment("isp", _project(), tmp_path / "set", tmp_path / "full", seeds=1,
                                 profile_override=TINY, checkpoints=tmp_path / "ck_full"))
    cancel = CancelToken()
    with pytest.raises(JobCancelled):
        _drive(run_experiment("isp", _project(), tmp_path / "set", tmp_path / "out", seeds=1, profile_override=TINY,
                              cancel=cancel, checkpoints=tmp_path / "ck"), cancel, cancel_after=1)
    shutil.rmtree(tmp_path / "set")
    shutil.rmtree(tmp_path / "ck")
    make_synthetic_dataset(tmp_path / "again", frames=14)
    resumed = _drive(run_experiment("isp", _project(), tmp_path / "again", tmp_path / "out", seeds=1,
                                    profile_override=TINY, checkpoints=tmp_path / "ck"))
    assert len(resumed.reused) == 1 and len(resumed.trained) == 2
    a, b = (json.loads((tmp_path / d / "results.json").read_text()) for d in ("full", "out"))
    assert b["complete"] and a["dataset"]["fingerprint"] == b["dataset"]["fingerprint"]
    assert {r["key"]: _scores(r) for r in b["runs"]} == {r["key"]: _scores(r) for r in a["runs"]}
    assert len(full.trained) == 3
    assert a["summary"] == b["summary"] and a["contrasts"] == b["contrasts"]


def test_processes_filling_one_folder_by_net_merge_their_runs(synthetic_dir, tmp_path):
    prof = replace(TINY, nets=("mobile", "resnet18"))
    first = _drive(run_experiment("isp", _project(), synthetic_dir, tmp_path, seeds=1, profile_override=prof,
                                  nets=("mobile",)))
    assert len(first.trained) == 3 and not json.loads((tmp_path / "results.json").read_text())["complete"]
    second = _drive(run_experiment("isp", _project(), synthetic_dir, tmp_path, seeds=1, profile_override=prof,
                                   nets=("resnet18",)))
    assert len(second.trained) == 3 and len(second.reused) == 3
    doc = _check_outputs(tmp_path, "isp", 6)
    assert doc["complete"] and {s["net"] for s in doc["summary"]} == {"mobile", "resnet18"}


def test_budget_study_lends_its_runs_to_the_isp_experiment(synthetic_dir, tmp_path):
    budget = _drive(run_experiment("budget", _project(), synthetic_dir, tmp_path / "budget", seeds=2,
                                   profile_override=TINY))
    doc = _check_outputs(tmp_path / "budget", "budget", 4)
    assert len(budget.trained) == 4 and doc["complete"]
    epochs = sorted((r["role"]["budget_factor"], r["config"]["epochs"]) for r in doc["runs"])
    assert epochs == [(1, 1), (1, 1), (2, 2), (2, 2)]
    verdict = doc["budget_enough"]["mobile"]
    gains = [next(t["map"] for t in r["tests"] if t["ev"] == 0.0) * (1 if r["role"]["budget_factor"] == 2 else -1)
             for r in doc["runs"]]
    assert verdict["gain"] == pytest.approx(sum(gains) / 2) and verdict["enough"] == (verdict["gain"] < 0.01)
    isp = _drive(run_experiment("isp", _project(), synthetic_dir, tmp_path / "isp", seeds=2, profile_override=TINY,
                                reuse_from=(tmp_path / "budget",)))
    assert len(isp.trained) == 4 and len(isp.reused) == 2                  # the two sRGB runs are lent
    runs = json.loads((tmp_path / "isp" / "results.json").read_text())["runs"]
    lent = [r for r in runs if r["role"]["representation"] == "srgb"]
    assert all("budget_factor" not in r["role"] for r in lent) and len(lent) == 2
    assert set(read_bootstraps(tmp_path / "isp")) == {r["key"] for r in runs}


def test_a_run_claimed_by_a_live_process_is_left_to_it_and_a_dead_ones_claim_is_taken(synthetic_dir, tmp_path):
    import socket

    from workbench.compute.job_claims import claim, release
    ckpt = tmp_path / "ck"
    ckpt.mkdir()
    from workbench.detect.data import DetectionDataset
    keys = [job.key for _, job in plan_runs("isp", TINY, 1, DetectionDataset(synthetic_dir, project=_project()), ckpt)]
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    try:
        for key, pid in ((keys[0], live.pid), (keys[1], dead.pid)):
            (ckpt / f"{key}.claim").write_text(json.dumps({"pid": pid, "host": socket.gethostname()}))
        result = _drive(run_experiment("isp", _project(), synthetic_dir, tmp_path / "out", seeds=1,
                                       profile_override=TINY, checkpoints=ckpt))
        assert sorted(result.trained) == sorted(keys[1:])            # the live claim is respected
        assert not json.loads((tmp_path / "out" / "results.json").read_text())["complete"]
        assert sorted(p.name for p in ckpt.glob("*.claim")) == [f"{keys[0]}.claim"]
    finally:
        live.kill()
        live.wait()
    assert claim(ckpt, keys[0])                         # its holder is gone: the claim is taken over
    assert claim(ckpt, keys[0])                         # this process's own claim is its own again
    (ckpt / f"{keys[0]}.claim").write_text(json.dumps({"pid": os.getppid(), "host": socket.gethostname()}))
    assert not claim(ckpt, keys[0])                     # another live process holds it
    release(ckpt, keys[0])
    assert (ckpt / f"{keys[0]}.claim").exists()          # only the holder releases a claim
    (ckpt / f"{keys[0]}.claim").write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname()}))
    release(ckpt, keys[0])
    assert not (ckpt / f"{keys[0]}.claim").exists()


def test_a_budget_that_grows_keeps_its_old_runs_as_the_ladder_and_trains_only_the_new_2b(synthetic_dir, tmp_path):
    """A budget that grows re-plans the runs: the old 2B run is the new B run and serves it untrained;
    the old B run stays in the budget folder's runs as the ladder's step below (it was superseded,
    outside the analysis, before the ladder), so the analysis reads both steps; the ISP experiment
    borrows only the run at the current budget."""
    _drive(run_experiment("budget", _project(), synthetic_dir, tmp_path / "budget", seeds=1, profile_override=TINY))
    grown = replace(TINY, epochs={"mobile": 2, "resnet18": 2})
    job = run_experiment("budget", _project(), synthetic_dir, tmp_path / "budget", seeds=1, profile_override=grown)
    assert "1 runs of earlier budgets kept as the ladder" in next(job).message
    result = _drive(job)
    assert len(result.reused) == 1 and len(result.trained) == 1            # 2 epochs: done; 4: trained
    doc = json.loads((tmp_path / "budget" / "results.json").read_text())
    assert sorted((r["config"]["epochs"], r["role"]["budget_factor"]) for r in doc["runs"]) == [(1, 0.5), (2, 1),
                                                                                                 (4, 2)]
    assert doc["superseded_runs"] == [] and doc["complete"]
    verdict = doc["budget_enough"]["mobile"]
    assert verdict["epochs"] == 2 and [s["epochs"] for s in verdict["ladder"]] == [1, 2]
    assert verdict["status"] in ("open", "too large")                      # one seed decides no step
    isp = run_experiment("isp", _project(), synthetic_dir, tmp_path / "isp", seeds=1, profile_override=grown,
                         reuse_from=(tmp_path / "budget",))
    assert "1 already done (1 from other folders)" in next(isp).message       # lent before any training
    isp.close()
    lent = json.loads((tmp_path / "isp" / "results.json").read_text())["runs"]
    assert [r["config"]["epochs"] for r in lent] == [2]


def test_a_folder_rewritten_without_training_takes_the_grown_budgets_runs(synthetic_dir, tmp_path, capsys):
    """After a budget grows, `--no-train` rewrites an ISP folder from what it holds and what the
    budget folder lends: its sRGB run at the old budget moves to superseded_runs, the one at the
    new budget takes its place, and nothing is trained."""
    from workbench.cli import main
    prof = TINY
    _drive(run_experiment("budget", _project(), synthetic_dir, tmp_path / "budget", seeds=1, profile_override=prof))
    _drive(run_experiment("isp", _project(), synthetic_dir, tmp_path / "isp", seeds=1, profile_override=prof,
                          reuse_from=(tmp_path / "budget",)))
    grown = replace(prof, epochs={"mobile": 2, "resnet18": 2})
    _drive(run_experiment("budget", _project(), synthetic_dir, tmp_path / "budget", seeds=1, profile_override=grown))
    result = _drive(run_experiment("isp", _project(), synthetic_dir, tmp_path / "isp", seeds=1,
                                   profile_override=grown, nets=(), reuse_from=(tmp_path / "budget",)))
    assert result.trained == [] and len(result.reused) == 1                  # the 2-epoch sRGB run, lent
    doc = json.loads((tmp_path / "isp" / "results.json").read_text())
    assert [(r["role"]["representation"], r["config"]["epochs"]) for r in doc["runs"]] == [("srgb", 2)]
    assert sorted((r["role"]["representation"], r["config"]["epochs"]) for r in doc["superseded_runs"]) == \
        [("linear", 1), ("raw", 1), ("srgb", 1)]
    assert not doc["complete"]
    assert main(["experiment", "isp", "city_detection_quick", "--data", str(synthetic_dir), "--out",
                 str(tmp_path / "cli"), "--no-train", "--nets", "mobile"]) == 2
    assert "--no-train" in capsys.readouterr().err and not (tmp_path / "cli").exists()


def test_the_command_line_rewrites_a_folder_without_training(synthetic_dir, tmp_path, capsys):
    from workbench.cli import main
    from workbench.project import save_project
    project = save_project(_project(), tmp_path / "synthetic.json")
    assert main(["experiment", "isp", str(project), "--data", str(synthetic_dir), "--out",
                 str(tmp_path / "cli"), "--profile", "quick", "--no-train"]) == 0
    assert json.loads(capsys.readouterr().out)["trained"] == 0
    doc = json.loads((tmp_path / "cli" / "results.json").read_text())
    assert doc["runs"] == [] and not doc["complete"]
