"""The budget study as a ladder: when the profile's budget B doubles, the old 2B runs serve as the
new B runs (not retrained), the old B runs stay in the budget folder's runs as the step below
(not superseded: they are the evidence that the budget grew), the analysis and chart read every
step, and the ISP and exposure experiments use only runs at the profile's current budget. No
training here: records are the committed standard folder's or made up for the analysis."""
import json
import shutil
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from workbench.experiments.budget import budget_analysis, settled_nets
from workbench.experiments.detection import (BUDGET_TOLERANCE, PROFILES, borrowed_runs, missing_runs, plot_results,
                                             sort_records, write_outputs)
from workbench.experiments.plan import BUDGET_SEEDS, STANDARD_EPOCHS, budget_ladder_configs, kept_roles, plan_configs
from workbench.experiments.results import read_bootstraps, read_results

COMMITTED = Path(__file__).resolve().parents[2] / "docs" / "results" / "schedule-study" / "budget-batch16"
COMMITTED_EPOCHS = {"mobile": 120, "resnet18": 80}        # the budget the committed folder was planned with
GROWN = {"mobile": 240, "resnet18": 160}
# the committed ladder was trained at batch 16 (the standard profile trains at batch 8 since)
BATCH16 = replace(PROFILES["standard"], batch_size=16)


# The committed folder grows every sitting: the tests read it as it stood when the ladder was built
# (2026-11-27, the split by city: these five runs, planned at COMMITTED_EPOCHS).
FROZEN_RUNS = {("mobile", 0, 120), ("mobile", 0, 240), ("mobile", 1, 120), ("resnet18", 0, 80), ("resnet18", 0, 160)}


@pytest.fixture
def committed(tmp_path):
    """A copy of the committed budget folder cut back to FROZEN_RUNS (its superseded runs kept), in
    the roles the COMMITTED_EPOCHS plan gave them (B: factor 1, 2B: factor 2), and its document."""
    folder = tmp_path / "budget-standard"
    shutil.copytree(COMMITTED, folder)
    doc = read_results(folder)
    frozen = [{**r, "role": {**r["role"], "budget_factor": r["config"]["epochs"] // COMMITTED_EPOCHS[r["config"]["net"]]}}
              for r in doc["runs"] if (r["config"]["net"], r["config"]["seed"], r["config"]["epochs"]) in FROZEN_RUNS]
    assert len(frozen) == len(FROZEN_RUNS), "a run the ladder tests read is missing from the committed folder"
    doc = {**{k: v for k, v in doc.items() if k != "checksum"}, "runs": frozen,
           "settings": {**doc["settings"], "epochs": COMMITTED_EPOCHS}}
    write_outputs(doc, read_bootstraps(folder), folder)
    return folder, read_results(folder)


def _plan_args(doc):
    return (doc["settings"]["seeds"], tuple(doc["ev_biases"]), doc["dataset"]["fingerprint"],
            doc["dataset"]["split_digest"])


def _epochs(records):
    return sorted((r["config"]["net"], r["config"]["seed"], r["config"]["epochs"]) for r in records)


def test_the_standard_budget_is_set_in_one_place(monkeypatch):
    """STANDARD_EPOCHS is the standard profile's budget, and growing it is a one-line change of it."""
    import sys
    import types

    import workbench.experiments.plan as plan
    assert PROFILES["standard"].epochs == STANDARD_EPOCHS and set(STANDARD_EPOCHS) == set(PROFILES["standard"].nets)
    line = f"STANDARD_EPOCHS = {json.dumps(STANDARD_EPOCHS)}"
    source = Path(plan.__file__).read_text()
    assert source.count(line) == 1
    grown = types.ModuleType("grown_plan")
    monkeypatch.setitem(sys.modules, "grown_plan", grown)
    exec(compile(source.replace(line, f"STANDARD_EPOCHS = {json.dumps(GROWN)}"), plan.__file__, "exec"), grown.__dict__)
    assert grown.PROFILES["standard"].epochs == GROWN


def test_the_committed_budget_folder_grows_into_a_ladder_without_retraining(committed, tmp_path):
    """With the standard budget grown to mobile 240 / resnet18 160, the committed folder's 240- and
    160-epoch runs are the new B runs, its 120- and 80-epoch runs the ladder's step below, its runs
    of the old split stay superseded, and the runs to train are the 2B runs (480, 320) and seed 1's."""
    folder, doc = committed
    grown = replace(BATCH16, epochs=GROWN)
    args = _plan_args(doc)
    records = doc["runs"] + doc["superseded_runs"]
    runs, superseded = sort_records(records, kept_roles("budget", grown, *args))
    assert {r["key"] for r in superseded} == {r["key"] for r in doc["superseded_runs"]}     # the old split only
    factors = sorted((r["config"]["net"], r["config"]["seed"], r["config"]["epochs"], r["role"]["budget_factor"])
                     for r in runs)
    assert factors == [("mobile", 0, 120, 0.5), ("mobile", 0, 240, 1), ("mobile", 1, 120, 0.5),
                       ("resnet18", 0, 80, 0.5), ("resnet18", 0, 160, 1)]
    planned = plan_configs("budget", grown, *args)
    todo = missing_runs([key for _, key, _, _ in planned], records)
    config_of = {key: config for _, key, config, _ in planned}
    assert sorted((config_of[k].net, config_of[k].seed, config_of[k].epochs) for k in todo) == [
        ("mobile", 0, 480), ("mobile", 1, 240), ("mobile", 1, 480),
        ("resnet18", 0, 320), ("resnet18", 1, 160), ("resnet18", 1, 320)]
    # the folder as the grown profile writes it loads, and its analysis reads the ladder
    boots = read_bootstraps(folder)
    settings = {**doc["settings"], "epochs": GROWN}
    grown_doc = {**{k: v for k, v in doc.items() if k != "checksum"}, "settings": settings, "runs": runs,
                 "superseded_runs": superseded, **budget_analysis(runs, boots, BUDGET_TOLERANCE, GROWN),
                 "complete": False}
    out = tmp_path / "grown"
    out.mkdir()
    write_outputs(grown_doc, boots, out)
    again = read_results(out)
    assert _epochs(again["runs"]) == _epochs(runs) and len(again["superseded_runs"]) == len(superseded)
    mobile = again["budget_enough"]["mobile"]
    assert [(s["epochs"], s["to_epochs"], s["seeds"], s["decided"]) for s in mobile["ladder"]] == [
        (120, 240, [0], False)]
    assert mobile["ladder"][0]["gain"] == pytest.approx(0.6516 - 0.6207, abs=1e-3)
    assert mobile["epochs"] == 240 and mobile["gain"] is None and mobile["status"] == "open"
    assert (out / "budget.png").stat().st_size > 1000


def test_the_committed_folder_reads_as_before_under_the_standard_budget(committed):
    """Under today's standard budget the committed folder keeps its runs in their roles; its 120 → 240
    and 80 → 160 steps are on seed 0 only, so the budget is not settled yet."""
    folder, doc = committed
    assert doc["settings"]["epochs"] == COMMITTED_EPOCHS
    profile = replace(BATCH16, epochs=COMMITTED_EPOCHS)
    runs, superseded = sort_records(doc["runs"] + doc["superseded_runs"], kept_roles("budget", profile,
                                                                                    *_plan_args(doc)))
    assert [r["role"] for r in runs] == [r["role"] for r in doc["runs"]] and len(superseded) == 7
    verdict = budget_analysis(runs, read_bootstraps(folder), BUDGET_TOLERANCE, COMMITTED_EPOCHS)["budget_enough"]
    assert {net: (v["epochs"], round(v["gain"], 3), v["status"]) for net, v in verdict.items()} == {
        "mobile": (120, 0.031, "open"), "resnet18": (80, 0.062, "open")}


def test_isp_and_exposure_use_only_runs_at_the_current_budget(committed):
    """After the growth the ISP and exposure experiments borrow the 240/160-epoch runs from the
    budget folder, never the old 120/80 ones, and an old-budget record in their own folder is superseded."""
    folder, doc = committed
    args = _plan_args(doc)
    for kind in ("isp", "exposure"):
        for epochs, lent_epochs in ((COMMITTED_EPOCHS, [("mobile", 0, 120), ("mobile", 1, 120), ("resnet18", 0, 80)]),
                                    (GROWN, [("mobile", 0, 240), ("resnet18", 0, 160)])):
            profile = replace(BATCH16, epochs=epochs)
            jobs = [(role, SimpleNamespace(key=key, test_evs=test_evs))
                    for role, key, _, test_evs in plan_configs(kind, profile, *args)]
            lent, _ = borrowed_runs([folder], jobs, doc["dataset"]["fingerprint"])
            assert _epochs(lent) == lent_epochs
        runs, superseded = sort_records(doc["runs"], kept_roles(kind, replace(BATCH16, epochs=GROWN),
                                                                *args))
        assert _epochs(runs) == [("mobile", 0, 240), ("resnet18", 0, 160)]
        assert {r["config"]["epochs"] for r in superseded} == {120, 80}


def test_the_ladder_reaches_down_by_halves_and_is_never_trained():
    profile = replace(BATCH16, epochs={"mobile": 240, "resnet18": 80})
    ladder = budget_ladder_configs(profile, 2, (0.0,), "f" * 64, "s" * 64)
    got = sorted({(config.net, config.epochs, role["budget_factor"]) for role, _, config, _ in ladder})
    assert got == [("mobile", 15, 1 / 16), ("mobile", 30, 1 / 8), ("mobile", 60, 1 / 4), ("mobile", 120, 1 / 2),
                   ("resnet18", 5, 1 / 16), ("resnet18", 10, 1 / 8), ("resnet18", 20, 1 / 4),
                   ("resnet18", 40, 1 / 2)]
    planned = {key for _, key, _, _ in plan_configs("budget", profile, 2, (0.0,), "f" * 64, "s" * 64)}
    assert not planned & {key for _, key, _, _ in ladder}
    assert budget_ladder_configs(replace(profile, epochs={"mobile": 0, "resnet18": -4}), 2, (0.0,), "f" * 64) == []


def _run(net, seed, epochs, factor, value):
    return {"key": f"{net}-{seed}-{epochs}", "role": {"net": net, "seed": seed, "budget_factor": factor},
            "config": {"net": net, "seed": seed, "epochs": epochs}, "tests": [{"ev": 0.0, "map": value}]}


LADDER = {1: (0.40, 0.42), 2: (0.50, 0.52), 4: (0.55, 0.57), 8: (0.554, 0.574)}      # gains +0.1, +0.05, +0.004


@pytest.mark.parametrize("budget, seeds, status, gain", [
    (4, 2, "settled", 0.004),         # the first step that gains < 0.01
    (2, 2, "grow", 0.05),
    (8, 2, "too large", None),        # 4 → 8 already gains < 0.01; 8 → 16 not run
    (4, 1, "open", 0.004),            # one seed does not decide a step
])
def test_the_analysis_reads_every_step_and_says_whether_the_profiles_budget_is_settled(budget, seeds, status, gain,
                                                                                      tmp_path):
    runs = [_run("mobile", s, e, e / budget, v[s]) for e, v in LADDER.items() if e <= 2 * budget
            for s in range(seeds)]
    result = budget_analysis(runs, {}, BUDGET_TOLERANCE, {"mobile": budget})
    verdict = result["budget_enough"]["mobile"]
    assert verdict["status"] == status and verdict["epochs"] == budget
    assert verdict["gain"] == (None if gain is None else pytest.approx(gain))
    steps = [(s["epochs"], round(s["gain"], 3), s["enough"]) for s in verdict["ladder"]]
    assert steps == [(e, round(np.mean(LADDER[2 * e]) - np.mean(LADDER[e]), 3), e == 4)
                     for e in (1, 2, 4) if 2 * e <= 2 * budget]
    assert [r["epochs"] for r in result["contrasts"]] == [s[0] for s in steps]
    doc = {"kind": "budget", "project": "p", "profile": "tiny",
           "settings": {"seeds": seeds, "epochs": {"mobile": budget}}, **result}
    plot_results(json.loads(json.dumps(doc)), tmp_path / "budget.png")       # as read back from results.json
    assert (tmp_path / "budget.png").stat().st_size > 1000
    from matplotlib.figure import Figure

    from workbench.experiments.results import draw_results
    fig = Figure()
    draw_results(fig, json.loads(json.dumps(doc)))
    assert fig.axes[0].get_title() == f"mobile, B = {budget} epochs\n{verdict['text']}"
    assert [t.get_text() for t in fig.axes[0].texts if "seed" in t.get_text()] == [
        f"{s['gain']:+.3f}\n({seeds} seed{'s' * (seeds != 1)})" for s in verdict["ladder"]]


def test_a_net_whose_budget_is_settled_goes_on_while_the_other_nets_study_trains():
    """packaging/standard-results.sh starts a net's ISP and exposure runs once its own budget is
    settled; a net still open, growing or too large waits."""
    runs = [_run("mobile", s, e, e / 4, v[s]) for e, v in LADDER.items() for s in range(2)]
    runs += [_run("resnet18", 0, e, e / 4, v[0]) for e, v in LADDER.items()]      # 4 → 8 on one seed: open
    runs += [_run("tiny", s, e, e / 2, v[s]) for e, v in LADDER.items() if e <= 4 for s in range(2)]   # 2 → 4: grow
    verdicts = budget_analysis(runs, {}, BUDGET_TOLERANCE, {"mobile": 4, "resnet18": 4, "tiny": 2})["budget_enough"]
    assert {net: v["status"] for net, v in verdicts.items()} == {"mobile": "settled", "resnet18": "open", "tiny": "grow"}
    assert settled_nets(verdicts) == ["mobile"]
    assert settled_nets({}) == []


def test_a_budget_folder_written_before_the_ladder_is_drawn_with_its_verdict(committed, tmp_path):
    from matplotlib.figure import Figure

    from workbench.experiments.results import draw_results
    _, doc = committed
    old_keys = ("epochs", "gain", "seeds", "enough", "tolerance")       # budget_enough before the ladder
    verdicts = budget_analysis(doc["runs"], {}, BUDGET_TOLERANCE, COMMITTED_EPOCHS)["budget_enough"]
    doc = {**doc, "budget_enough": {net: {k: v[k] for k in old_keys} for net, v in verdicts.items()}}
    fig = Figure()
    draw_results(fig, doc)
    assert [ax.get_title() for ax in fig.axes] == [
        "mobile, B = 120 epochs\nB → 2B gains +0.031 on 1 seed(s): grow the budget",
        "resnet18, B = 80 epochs\nB → 2B gains +0.062 on 1 seed(s): grow the budget"]
    doc = {**doc, "settings": {**doc["settings"], "seeds": 5}}   # the profile's; the study trains BUDGET_SEEDS
    fig = Figure()
    draw_results(fig, doc)
    assert f"{BUDGET_SEEDS} seed(s)" in fig._suptitle.get_text()


def test_the_standard_profile_trains_resnet18_as_the_batch_16_ladder_did_and_borrows_its_runs():
    """Batch per net (plan.STANDARD_BATCH): `mobile` at 8, `resnet18` at 16, so the standard budget
    study lent resnet18's 320-epoch runs from the committed batch-16 ladder instead of training them
    (while its B was 320; since B grew to 640 those runs are the budget folder's ladder)."""
    from workbench.errors import ParameterError
    from workbench.experiments.plan import STANDARD_BATCH
    doc = read_results(COMMITTED)
    args = _plan_args(doc)
    at_320 = replace(PROFILES["standard"], epochs={**STANDARD_EPOCHS, "resnet18": 320})
    planned = plan_configs("budget", at_320, *args)
    assert {(c.net, c.batch_size) for _, _, c, _ in planned} == set(STANDARD_BATCH.items())
    jobs = [(role, SimpleNamespace(key=key, test_evs=test_evs)) for role, key, _, test_evs in planned]
    lent, _ = borrowed_runs([COMMITTED], jobs, doc["dataset"]["fingerprint"])
    assert _epochs(lent) == [("resnet18", 0, 320), ("resnet18", 1, 320)]
    with pytest.raises(ParameterError, match="batch_size"):
        plan_configs("budget", replace(PROFILES["standard"], batch_size={"mobile": 8}), *args)
