"""A results.json is trusted only if its records are what the plan made (issue 34): a run listed
twice, a run not in the plan, a metric out of range, a record whose digest or checksum does not
match are refused naming the file and the run; the committed result folders (records written
before sealing) load and keep every run; run_experiment refuses arguments of the wrong type."""
import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

from workbench.errors import InputFileError, ParameterError
from workbench.experiments.detection import PROFILES, _load_previous, run_experiment
from workbench.experiments.records import config_digest, run_key
from workbench.experiments.results import read_results

TINY = replace(PROFILES["quick"], name="tiny", image_hw=(48, 64), epochs={"mobile": 1, "resnet18": 1},
               crop_hw=None, batch_size=4, per_ev_biases=(1.0,), curve_points=1)
COMMITTED = Path(__file__).resolve().parents[2] / "docs" / "results"


def _project():
    from workbench.detect.synthetic import synthetic_project
    p = synthetic_project()
    return p.updated(experiment=p.experiment.updated(ev_biases=[-1.0, 0.0, 1.0]))


def _drive(job):
    while True:
        try:
            next(job)
        except StopIteration as stop:
            return stop.value


@pytest.fixture(scope="module")
def sealed(synthetic_dir, tmp_path_factory):
    """A result folder of a tiny ISP experiment written by this code (sealed records)."""
    import torch
    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("isp")
    _drive(run_experiment("isp", _project(), synthetic_dir, out, seeds=1, profile_override=TINY))
    return out


def _copy_with(folder: Path, tmp_path: Path, edit) -> Path:
    target = tmp_path / "edited"
    shutil.copytree(folder, target)
    doc = json.loads((target / "results.json").read_text())
    edit(doc)
    (target / "results.json").write_text(json.dumps(doc))
    return target


def test_new_records_carry_their_digest_and_checksums(sealed):
    doc = read_results(sealed)
    assert doc["checksum"]
    fingerprint = doc["dataset"]["fingerprint"]
    split = doc["dataset"]["split_digest"]
    for run in doc["runs"]:
        assert run["split_digest"] == split
        assert run["digest"] == config_digest(run["config"], fingerprint, split)
        assert run["key"] == run_key(run["config"], fingerprint, split) and run["checksum"]
        assert all(t["checksum"] for t in run["tests"])


def _not_in_plan(doc):
    run = json.loads(json.dumps(doc["runs"][0]))
    run["config"]["seed"] = 7
    run["role"]["seed"] = 7
    run["key"] = run_key(run["config"], doc["dataset"]["fingerprint"], run.get("split_digest"))
    for name in ("digest", "checksum"):
        run.pop(name)
    for t in run["tests"]:
        t.pop("checksum")
    doc["runs"].append(run)


def _set_test(name, value):
    def edit(doc):
        doc["runs"][0]["tests"][0][name] = value
    return edit


@pytest.mark.parametrize("edit, fragment", [
    (lambda d: d["runs"].append(d["runs"][0]), "listed twice"),
    (lambda d: d["superseded_runs"].append(d["runs"][1]), "listed twice"),
    (_not_in_plan, "not a run of this experiment's plan"),
    (_set_test("map", 2.5), "not in 0…1"),
    (_set_test("map", math.nan), "not in 0…1"),
    (_set_test("ap", {"car": -0.1}), "AP per class"),
    (lambda d: d["runs"][0]["config"].update(lr=0.1), "key does not name its config"),
    (lambda d: d["runs"][0].update(digest="0" * 64), "digest does not match"),
    (lambda d: d["runs"][0]["train"].update(train_map=0.999), "checksum does not match"),
    (lambda d: d["runs"][0]["tests"][0].update(map=0.999), "checksum does not match"),
    (lambda d: d["runs"][0]["train"].update(history=[]), "loss history"),
    (lambda d: d["runs"][0]["train"]["history"][0].update(heatmap=math.nan), "loss history"),
    (lambda d: d["runs"][0]["machine"].update(threads="abc"), "machine.threads"),
    (lambda d: d["runs"][0]["tests"][0].update(seconds=-1.0), "test.seconds"),
    (lambda d: d["classes"].append(d["classes"][0]), "classes"),
    (lambda d: d["runs"][0].update(role={**d["runs"][0]["role"], "seed": 3}), "plan"),
    (lambda d: d["dataset"].update(fingerprint="0" * 16), "key does not name its config on this data set"),
    (lambda d: d["summary"][0].update(mean_map=2.5), "summary row"),
    (lambda d: d["summary"][0].update(mean_map=0.999), "changed after it was written"),
    (lambda d: d.update(complete=False), "changed after it was written"),
])
def test_a_record_the_plan_did_not_make_is_refused_naming_the_file_and_run(sealed, tmp_path, edit, fragment):
    folder = _copy_with(sealed, tmp_path, edit)
    with pytest.raises(InputFileError, match=fragment) as info:
        read_results(folder)
    message = str(info.value)
    assert str(folder / "results.json") in message and "\n" not in message
    if "summary" not in fragment and "written" not in fragment:
        assert "run '" in message


def test_an_experiment_refuses_to_resume_on_a_damaged_folder(synthetic_dir, sealed, tmp_path):
    folder = _copy_with(sealed, tmp_path, _set_test("map", 2.5))
    with pytest.raises(InputFileError, match="results.json"):
        _drive(run_experiment("isp", _project(), synthetic_dir, folder, seeds=1, profile_override=TINY))


def test_records_written_before_sealing_still_count(synthetic_dir, sealed, tmp_path):
    def unseal(doc):
        doc.pop("checksum")
        for run in doc["runs"]:
            run.pop("digest")
            run.pop("checksum")
            for t in run["tests"]:
                t.pop("checksum")
    folder = _copy_with(sealed, tmp_path, unseal)
    assert len(read_results(folder)["runs"]) == 3
    result = _drive(run_experiment("isp", _project(), synthetic_dir, folder, seeds=1, profile_override=TINY))
    assert len(result.reused) == 3 and not result.trained


@pytest.mark.parametrize("name", ["budget-standard", "isp-standard", "schedule-study/budget-batch16"])
def test_the_committed_result_folders_load_and_keep_every_run(tmp_path, name):
    """The committed folders (filled over sittings, by older code too) load with today's checks and
    keep every record they hold, current and superseded."""
    folder = tmp_path / name
    shutil.copytree(COMMITTED / name, folder)
    raw = json.loads((folder / "results.json").read_text())
    runs, superseded = len(raw["runs"]), len(raw.get("superseded_runs", []))
    assert runs + superseded > 0
    doc = read_results(folder)
    assert len(doc["runs"]) == runs and len(doc["superseded_runs"]) == superseded
    kept, _ = _load_previous(folder, doc["kind"], doc["dataset"]["fingerprint"], doc["profile"])
    assert len(kept) == runs + superseded                            # a resume counts every one of them


@pytest.mark.parametrize("argument, value", [("seeds", True), ("seeds", 2.0), ("workers", True), ("workers", -1),
                                             ("checkpoints", ""), ("checkpoints", "  "), ("reuse_from", "a/folder"),
                                             ("nets", "mobile"), ("profile", 3), ("compute", "local")])
def test_run_experiment_refuses_arguments_of_the_wrong_type(synthetic_dir, tmp_path, argument, value):
    with pytest.raises(ParameterError, match=argument):
        next(run_experiment("isp", _project(), synthetic_dir, tmp_path / "out", **{argument: value}))
    assert not (tmp_path / "out").exists()


def test_the_command_line_refuses_an_empty_checkpoint_folder(synthetic_dir, tmp_path, capsys, monkeypatch):
    from workbench.cli import main
    monkeypatch.chdir(tmp_path)
    assert main(["experiment", "isp", "city_detection_quick", "--data", str(synthetic_dir), "--out",
                 str(tmp_path / "out"), "--checkpoints", ""]) == 2
    assert "checkpoints" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
