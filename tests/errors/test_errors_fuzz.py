"""Fuzzing: generated project documents and lens files either load (and a project simulates at
16×12 px and at most 64 spp with finite outputs, and survives save → load) or are refused with a
WorkbenchError naming the field or file — never another exception, never NaN in an output.
Mutated data-set folders are refused with an InputFileError naming a file of the set or read
with the unmutated set's content (never accepted changed); dataset-verify agrees. The suite runs
16 of them; WORKBENCH_DATASET_FUZZ=N runs N (and WORKBENCH_FUZZ_REPORT=f.json writes the counts):
    WORKBENCH_DATASET_FUZZ=400 pytest tests/errors/test_errors_fuzz.py -k data_set

The fast subset runs in the normal tests; the big run is marked slow and runs 120 documents and
60 lens files in the suite (CI's 12-minute budget); the full probe of 1,200 and 600:
    WORKBENCH_FUZZ_SCALE=10 WORKBENCH_FUZZ_REPORT=fuzz.json pytest tests/errors/test_errors_fuzz.py -m slow
writes the counts to the named file."""
import json
import os
import tempfile
from collections import Counter
from pathlib import Path

import pytest
import torch
from errors_fuzz import (CHART_SAMPLES, SAMPLES, TINY_TRAIN, check_checkpoint_file, check_dataset, check_document,
                         check_lens_file, check_results_file, check_study_file, dataset_mutations, lens_files,
                         mutated_checkpoints, mutated_json_files, project_texts, results_document, study_document)
from hypothesis import HealthCheck, given, settings

FAST = settings(max_examples=60, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def test_the_check_really_simulates_an_unmutated_sample(tmp_path):
    for name in CHART_SAMPLES:
        assert check_document(json.dumps(SAMPLES[name]), tmp_path) == "simulated", name


@FAST
@given(case=project_texts(samples=CHART_SAMPLES))
def test_fuzzed_chart_projects_load_and_simulate_or_name_the_field(case):
    _name, text, _applied = case
    with tempfile.TemporaryDirectory() as folder:
        check_document(text, Path(folder))


@settings(FAST, max_examples=40)
@given(case=lens_files())
def test_fuzzed_lens_files_load_or_are_refused_naming_the_file(case):
    suffix, data, _applied = case
    with tempfile.TemporaryDirectory() as folder:
        check_lens_file(suffix, data, Path(folder))


def _big_run(strategy, check, n: int) -> tuple[Counter, Counter, list]:
    """Draw n cases from `strategy`, run `check` on each; count outcomes (in all and per sample or
    file type) and collect failures."""
    counts: Counter = Counter()
    per_kind: Counter = Counter()
    failures = []

    @settings(max_examples=n, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(case=strategy)
    def run(case):
        with tempfile.TemporaryDirectory() as folder:
            try:
                outcome = check(case, Path(folder))
            except Exception as exc:           # recorded and reported, the run goes on
                outcome = "traceback"
                failures.append((case[0], case[-1], f"{type(exc).__name__}: {exc}"[:300]))
            counts[outcome] += 1
            per_kind[f"{case[0]}: {outcome}"] += 1
    run()
    return counts, per_kind, failures


@pytest.mark.slow
def test_big_fuzz_run():
    scale = max(1, int(os.environ.get("WORKBENCH_FUZZ_SCALE", "1")))
    docs, doc_kinds, doc_failures = _big_run(project_texts(), lambda c, f: check_document(c[1], f), 120 * scale)
    lenses, lens_kinds, lens_failures = _big_run(lens_files(), lambda c, f: check_lens_file(c[0], c[1], f), 60 * scale)
    report = {"project_documents": {"tried": sum(docs.values()), **docs},
              "lens_files": {"tried": sum(lenses.values()), **lenses},
              "per_sample": dict(sorted(doc_kinds.items())), "per_lens_format": dict(sorted(lens_kinds.items())),
              "failures": doc_failures[:50] + lens_failures[:50]}
    if os.environ.get("WORKBENCH_FUZZ_REPORT"):
        Path(os.environ["WORKBENCH_FUZZ_REPORT"]).write_text(json.dumps(report, indent=1))
    assert docs["traceback"] == 0 and lenses["traceback"] == 0, report["failures"][:5]
    assert sum(docs.values()) >= 100 * scale


@pytest.fixture
def _memory_cap():
    """At most 3 GiB more address space while frames are replaced by links to /dev/zero: a reader
    that read one would fail here, not take the machine's memory."""
    import resource
    before = resource.getrlimit(resource.RLIMIT_AS)
    size_kib = int(next(line.split()[1] for line in open("/proc/self/status") if line.startswith("VmSize")))
    resource.setrlimit(resource.RLIMIT_AS, (size_kib * 1024 + (3 << 30), before[1]))
    yield
    resource.setrlimit(resource.RLIMIT_AS, before)


def test_mutated_data_sets_are_refused_naming_a_file_or_read_unchanged(_memory_cap):
    n = int(os.environ.get("WORKBENCH_DATASET_FUZZ", "16"))
    distinct = set()

    def check(case, folder):
        distinct.add(json.dumps([case[0], case[-1]]))
        return check_dataset(case, folder)
    counts, per_kind, failures = _big_run(dataset_mutations(), check, n)
    report = {"data_sets": {"tried": sum(counts.values()), "distinct": len(distinct), **counts},
              "per_file": dict(sorted(per_kind.items())), "failures": failures[:50]}
    if os.environ.get("WORKBENCH_FUZZ_REPORT"):
        Path(os.environ["WORKBENCH_FUZZ_REPORT"]).write_text(json.dumps(report, indent=1))
    assert set(counts) <= {"refused", "accepted_same"}, report
    assert sum(counts.values()) >= n * 0.9 and counts["refused"] > 0 and counts["accepted_same"] > 0, report
# ------------------------------------------------ read-back files: results, study, checkpoint (issue 34)
# A few of each in the suite (seconds); WORKBENCH_READBACK_FUZZ=N runs N of each kind and
# WORKBENCH_FUZZ_REPORT=FILE writes the counts:
#     WORKBENCH_READBACK_FUZZ=100 WORKBENCH_FUZZ_REPORT=readback.json \
#         pytest tests/errors/test_errors_fuzz.py -k readback
READBACK_N = int(os.environ.get("WORKBENCH_READBACK_FUZZ", "0"))


@pytest.fixture(scope="module")
def readback_bases(tmp_path_factory):
    """The sealed results.json and study.json texts, and a finished tiny training run (its
    checkpoint state, weights and history) on a 14-frame synthetic set."""
    from workbench.detect.checkpoint import load_checkpoint
    from workbench.detect.data import DetectionDataset
    from workbench.detect.engine import TrainConfig, train_detector
    from workbench.detect.synthetic import make_synthetic_dataset
    folder = tmp_path_factory.mktemp("readback")
    make_synthetic_dataset(folder / "set", frames=14)
    dataset = DetectionDataset(folder / "set")
    model, result = train_detector(dataset, TrainConfig(**TINY_TRAIN), folder / "run.pt")
    reference = ({k: v.clone() for k, v in model.state_dict().items()}, result.history)
    return {"results": results_document(), "study": study_document(), "dataset": dataset,
            "state": load_checkpoint(folder / "run.pt"), "reference": reference}


COMMITTED_RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results" / "schedule-study" / "budget-batch16" / "results.json"


def _readback_cases(bases):
    """(kind, strategy, check(case, folder)) of each read-back file: as this code writes them
    (sealed), and as written before sealing (the committed budget results, a study and a
    checkpoint without checksums), whose checks are then the structural ones alone."""
    results, study = json.loads(bases["results"]), json.loads(bases["study"])
    legacy_text, legacy_study = COMMITTED_RESULTS.read_text(), study_document(sealed=False)
    legacy, unsealed_study = json.loads(legacy_text), json.loads(legacy_study)
    unsealed_state = {k: v for k, v in bases["state"].items() if k != "checksum"}
    return [
        ("results", mutated_json_files(bases["results"]),
         lambda c, f: check_results_file(c[1], f, results, c[2])),
        ("study", mutated_json_files(bases["study"]), lambda c, f: check_study_file(c[1], f, study, c[2])),
        ("checkpoint", mutated_checkpoints(bases["state"]),
         lambda c, f: check_checkpoint_file(c[1], f, bases["dataset"], bases["reference"], c[2])),
        ("results_unsealed", mutated_json_files(legacy_text),
         lambda c, f: check_results_file(c[1], f, legacy, c[2])),
        ("study_unsealed", mutated_json_files(legacy_study),
         lambda c, f: check_study_file(c[1], f, unsealed_study, c[2])),
        ("checkpoint_unsealed", mutated_checkpoints(unsealed_state),
         lambda c, f: check_checkpoint_file(c[1], f, bases["dataset"], bases["reference"], c[2], sealed=False)),
    ]


def test_the_readback_bases_are_accepted_as_they_are(readback_bases, tmp_path):
    results, study = json.loads(readback_bases["results"]), json.loads(readback_bases["study"])
    assert check_results_file(readback_bases["results"].encode(), tmp_path, results, []) == "accepted_same"
    assert check_study_file(readback_bases["study"].encode(), tmp_path, study, []) == "accepted_same"
    import io as _io

    import torch
    buf = _io.BytesIO()
    torch.save(readback_bases["state"], buf)
    assert check_checkpoint_file(buf.getvalue(), tmp_path, readback_bases["dataset"], readback_bases["reference"],
                                 []) == "accepted_same"


def test_readback_fuzz_refuses_or_keeps_the_meaning(readback_bases):
    n = READBACK_N or 5
    report, failures = {}, []
    for kind, strategy, check in _readback_cases(readback_bases):
        counts, _, fails = _big_run(strategy, check, n)
        wrong = sum(f[2].startswith("AssertionError: accepted wrong") for f in fails)
        unnamed = sum(f[2].startswith("AssertionError") for f in fails) - wrong
        report[kind] = {"tried": sum(counts.values()), **counts, "accepted_wrong": wrong,
                        "refusals_not_naming_the_file": unnamed,
                        "internal_errors": len(fails) - wrong - unnamed}   # an exception no check made
        failures += [(kind, *f) for f in fails]
    report["failures"] = failures[:30]
    if os.environ.get("WORKBENCH_FUZZ_REPORT"):
        Path(os.environ["WORKBENCH_FUZZ_REPORT"]).write_text(json.dumps(report, indent=1, default=str))
    assert not failures, failures[:5]
