"""Study fronts by ε-dominance, the same tolerance `compare` uses: a design is left off the front
only when another is better by more than ε on one metric and worse by no more than ε on the other
(ε = 2·√(σ₁² + σ₂²) of the pair's measured uncertainties); the study report states the rule and ε."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from workbench.metrics.charts import pareto_front
from workbench.metrics.study import epsilon_dominates, write_study

X, Y = "mtf50_cy_px", "snr_at_10pct_full_well_dB"
POINTS = {"A": (0.3035, 30.0), "B": (0.302, 29.0), "C": (0.350, 29.90), "D": (0.303, 31.0), "E": (0.3501, 29.95)}
SIGMA = (0.002, 0.1)                     # every design's: ε_x = 2√2·0.002 ≈ 0.0057, ε_y = 2√2·0.1 ≈ 0.28


def rows():
    return [{"design": n, X: x, Y: y} for n, (x, y) in POINTS.items()]


def test_epsilon_front_of_a_constructed_study():
    sigma = {n: SIGMA for n in POINTS}
    # D beats A by 1 dB at an MTF50 0.0005 lower (within ε): A is off; E is C within ε on both: both stay;
    # the plain front keeps A (nobody beats it on both) and drops C (E is higher by 0.0001 and 0.05 dB)
    assert pareto_front(rows(), X, Y, sigma=sigma) == ["C", "D", "E"]
    assert pareto_front(rows(), X, Y) == ["A", "D", "E"]
    with_sigma = {n: tuple(zip(p, SIGMA)) for n, p in POINTS.items()}
    assert epsilon_dominates(with_sigma["D"], with_sigma["A"], (True, True))
    assert not epsilon_dominates(with_sigma["A"], with_sigma["D"], (True, True))
    assert not epsilon_dominates(with_sigma["E"], with_sigma["C"], (True, True))
    assert not epsilon_dominates(with_sigma["C"], with_sigma["E"], (True, True))
    # lower is better: the same points, signs flipped
    flipped = [{"design": r["design"], X: -r[X], Y: -r[Y]} for r in rows()]
    assert pareto_front(flipped, X, Y, False, False, sigma) == ["C", "D", "E"]


def test_the_study_report_states_the_rule_and_the_epsilons(tmp_path):
    designs = [{"design": n, "values": {"sensor.pixel_pitch_um": i + 1.0}, "summary": {X: x, Y: y},
                "uncertainty": {X: SIGMA[0], Y: SIGMA[1]}, "seconds": 1.0}
               for i, (n, (x, y)) in enumerate(POINTS.items())]
    doc = {"project": "constructed", "planned": 5, "vary": {"sensor.pixel_pitch_um": [1, 2, 3, 4, 5]},
           "notes": [], "designs": designs}
    write_study(doc, tmp_path, X, Y)
    md = (tmp_path / "study.md").read_text()
    assert f"Pareto front of {X} and {Y}: C, D, E\n" in md
    eps = 2 * math.hypot(*[SIGMA[0]] * 2), 2 * math.hypot(*[SIGMA[1]] * 2)
    assert "ε-dominance" in md and f"{X} ε {eps[0]:.3g}–{eps[0]:.3g}; {Y} ε {eps[1]:.3g}–{eps[1]:.3g}" in md


def test_the_committed_study_reproduces_its_front_and_without_uncertainties_keeps_a_plain_one(tmp_path):
    """docs/metrics/study-pitch-fnumber (read-only): written again it publishes the same ε-dominance
    front; with its uncertainties taken out (a study measured before they existed) σ = 0, ε 0–0,
    and the plain Pareto front is within the ε front (ε-dominance leaves off fewer designs)."""
    folder = Path(__file__).resolve().parents[2] / "docs" / "metrics" / "study-pitch-fnumber"
    doc = json.loads((folder / "study.json").read_text())
    published = next(line for line in (folder / "study.md").read_text().splitlines() if line.startswith("Pareto front"))
    x, y = published.split(":")[0].removeprefix("Pareto front of ").split(" and ")
    write_study(doc, tmp_path / "again", x, y)
    assert published in (tmp_path / "again" / "study.md").read_text().splitlines()
    plain = {**doc, "designs": [{k: v for k, v in d.items() if k != "uncertainty"} for d in doc["designs"]]}
    write_study(plain, tmp_path / "plain", x, y)
    md = (tmp_path / "plain" / "study.md").read_text()
    assert "ε 0–0" in md
    front = next(line for line in md.splitlines() if line.startswith("Pareto front")).split(": ", 1)[1].split(", ")
    assert set(front) <= set(published.split(": ", 1)[1].split(", "))


@pytest.mark.parametrize("margin, dominated", [(0.0056, False), (0.0058, True)])   # ε = 2√2·0.002 ≈ 0.00566
def test_better_by_more_than_epsilon_is_needed(margin, dominated):
    p = ((0.30, 0.002), (30.0, 0.1))
    q = ((0.30 + margin, 0.002), (30.0, 0.1))
    assert epsilon_dominates(q, p, (True, True)) is dominated


def test_a_designs_map_carries_its_test_set_bootstrap_sd_as_its_uncertainty(monkeypatch):
    """measure_design with a detector: the mAP's σ is the standard deviation of its test-set
    bootstrap (design_map(bootstrap=MAP_BOOTSTRAP)), so compare and the front judge mAP by it too."""
    from workbench.metrics import detection, frame, study
    asked = {}

    def fake_map(project, detector, data, *, bootstrap=0):
        asked["bootstrap"] = bootstrap
        return {"map": 0.61, "map_bootstrap_sd": 0.012}
    monkeypatch.setattr(frame, "camera_metrics", lambda p: {"project": p.name, "summary": {}, "uncertainty": {}})
    monkeypatch.setattr(detection, "design_map", fake_map)
    from workbench.project import load_project
    job = study.DesignJob("d", {}, load_project("paper_camera").model_dump_json(), "ckpt.pt", "data")
    got = study.measure_design(job)
    assert asked["bootstrap"] == study.MAP_BOOTSTRAP
    assert got["summary"]["map"] == 0.61 and got["uncertainty"]["map"] == 0.012
