"""`workbench metrics`, `compare` and `study` as a user runs them: reports written whole, a study
resumed without re-measuring, and bad requests refused by name."""
from __future__ import annotations

import json

import pytest

from workbench.cli import main
from workbench.project import load_project, save_project


@pytest.fixture(scope="module")
def small_camera(tmp_path_factory):
    """paper_camera on a 120×160 sensor (the charts scale with it): fast enough for the suite."""
    p = load_project("paper_camera")
    p = p.updated(name="small_camera", sensor=p.sensor.updated(rows=120, cols=160))
    return save_project(p, tmp_path_factory.mktemp("projects") / "small_camera.json")


def test_metrics_command_prints_and_writes_the_measurements(small_camera, tmp_path, capsys):
    assert main(["metrics", str(small_camera), "--out", str(tmp_path / "m")]) == 0
    out = capsys.readouterr().out
    assert "mtf50_cy_px" in out and "delta_e_mean" in out
    doc = json.loads((tmp_path / "m" / "metrics.json").read_text())
    assert {r["plane"] for r in doc["mtf"]} == {"raw R", "raw G", "raw B", "linear G", "sRGB luminance",
                                                "optics (model)", "pixel aperture (model)"}
    boot = doc["summary"]["mtf50_sd_cy_px"]                # one capture's bootstrap over the edge's rows
    sd = doc["uncertainty"]["mtf50_cy_px"]                 # over the noise draws: shown beside MTF50 everywhere
    assert 0 < boot < 0.05 and 0 < sd < 0.05
    line = next(x for x in out.splitlines() if x.split()[0] == "mtf50_cy_px")
    assert f"± {sd:.2g}" in line
    md = (tmp_path / "m" / "metrics.md").read_text()
    assert f"| mtf50_cy_px | {doc['summary']['mtf50_cy_px']:.4g} | {sd:.4g} |" in md and "| raw G |" in md
    assert f"| sRGB luminance | {doc['summary']['mtf50_cy_px']:.4g} | {boot:.4g} |" in md
    neutral = doc["colour"]["neutral_noise"]
    assert {r["patch"] for r in neutral} == {"white 9.5", "neutral 8", "neutral 6.5", "neutral 5", "neutral 3.5",
                                             "black 2"}
    for r in neutral:                       # ~25 pixels per channel on this small chart: σ within ±50 %
        if r["clipped"] == 0 and r["mean_e"] > 50:
            assert r["snr"] == pytest.approx(r["snr_model"], rel=0.5), r
    s = doc["summary"]
    assert 0.05 < s["mtf50_cy_px"] < 0.6 and 0 < s["delta_e_mean"] < s["delta_e_max"] < 30
    assert s["noise_equivalent_exposure_lux_s"] > 0
    assert (tmp_path / "m" / "metrics.png").stat().st_size > 10_000
    # held-out ΔE beside the fitted (training) patches', in the print-out, the JSON and the Markdown
    held, fitted = doc["colour"]["held_out"], doc["colour"]["fitted"]
    assert s["delta_e_held_out_mean"] == held["mean"] and s["delta_e_mean"] == fitted["mean"] <= held["mean"]
    assert f"ΔE2000 held-out patches (leave-one-out fits): mean {held['mean']:.2f}" in out
    assert f"ΔE2000 fitted (training) patches: mean {fitted['mean']:.2f}" in out
    md = (tmp_path / "m" / "metrics.md").read_text()
    assert f"| delta_e_held_out_mean | {held['mean']:.4g} | {doc['uncertainty']['delta_e_held_out_mean']:.4g} |" in md
    assert "fitted (training) patches" in md and "flat-fielded" in md


def test_compare_of_smaller_pixels_reports_the_expected_trade(small_camera, tmp_path, capsys):
    p = load_project(small_camera)
    b = save_project(p.updated(name="small_pixels", sensor=p.sensor.updated(pixel_pitch_um=1.5)), tmp_path / "b.json")
    assert main(["compare", str(small_camera), str(b), "--out", str(tmp_path / "cmp")]) == 0
    doc = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    rows = {r["metric"]: r for r in doc["table"]}
    # a quarter of the area: a quarter of the electrons per lux·s, so 4× the noise-equivalent exposure,
    # and twice the resolution per millimetre at a similar MTF per pixel
    nee = rows["noise_equivalent_exposure_lux_s"]
    assert nee["B"] / nee["A"] == pytest.approx(4.0, rel=0.1) and nee[""] == "A better"
    assert rows["mtf50_lp_mm"]["B"] / rows["mtf50_lp_mm"]["A"] == pytest.approx(2.0, rel=0.15)
    md = (tmp_path / "cmp" / "compare.md").read_text()
    assert "| metric | A | B | B − A |" in md
    sd_a, sd_b = doc["A"]["summary"]["mtf50_sd_cy_px"], doc["B"]["summary"]["mtf50_sd_cy_px"]
    assert f"MTF50 ± 1σ (bootstrap over the edge's rows): A {doc['A']['summary']['mtf50_cy_px']:.4g} ± {sd_a:.2g}, " \
           f"B {doc['B']['summary']['mtf50_cy_px']:.4g} ± {sd_b:.2g} cy/px." in md
    assert (tmp_path / "cmp" / "compare.png").stat().st_size > 10_000
    assert doc["changed"] == [{"field": "sensor.pixel_pitch_um", "A": p.sensor.pixel_pitch_um, "B": 1.5}]
    assert f"Changed from A to B: sensor.pixel_pitch_um {p.sensor.pixel_pitch_um} → 1.5" in md


def test_compare_of_a_design_with_itself_is_the_same_everywhere(small_camera, tmp_path):
    """Two identical projects: nothing changed, and every metric reads 'same within ±x' with x the
    tolerance of the two designs' measured uncertainties (2·√(σA² + σB²)), not a fixed constant."""
    from workbench.metrics.study import difference_tolerance
    assert main(["compare", str(small_camera), str(small_camera), "--out", str(tmp_path / "cmp")]) == 0
    doc = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    assert doc["changed"] == []
    for r in doc["table"]:
        if r["A"] is None:
            continue
        x = difference_tolerance(doc["A"]["uncertainty"][r["metric"]], doc["B"]["uncertainty"][r["metric"]])
        assert r[""] == f"same within ±{x:.2g}" and r["±"] == pytest.approx(x), r
    sigma = doc["A"]["uncertainty"]
    for noisy in ("mtf50_cy_px", "snr_at_10pct_full_well_dB", "noise_equivalent_exposure_lux_s",
                  "delta_e_held_out_mean", "delta_e_mean"):
        assert sigma[noisy] > 0, noisy                     # measured over the noise draws
    assert sigma["read_noise_e"] == 0 and doc["A"]["noise_draws"] == 5
    md = (tmp_path / "cmp" / "compare.md").read_text()
    assert "the same design" in md and "2·√(σ_A² + σ_B²)" in md


def test_a_difference_within_the_measured_uncertainty_is_the_same(small_camera, tmp_path):
    """f/4 → f/8 leaves the sensor as it is: its noise-equivalent exposure moves by ~0.05 % (the
    exposure series lands on other signal levels), which the old code called 'A better'; within its
    measured uncertainty it is the same. The field that changed is named at the top."""
    from workbench.metrics.study import compare_verdict, difference_tolerance
    p = load_project(small_camera)
    b = save_project(p.updated(name="f8", optics=p.optics.updated(f_number=8.0)), tmp_path / "f8.json")
    assert main(["compare", str(small_camera), str(b), "--out", str(tmp_path / "cmp")]) == 0
    doc = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    md = (tmp_path / "cmp" / "compare.md").read_text()
    assert md.splitlines()[2] == "Changed from A to B: optics.f_number 4.0 → 8.0"
    nee = {r["metric"]: r for r in doc["table"]}["noise_equivalent_exposure_lux_s"]
    assert 0 < abs(nee["B − A"]) / nee["A"] < 0.002 and nee[""].startswith("same within ±"), nee
    # a 0.04 % difference against the measured uncertainty; the same σ and a 5 % difference
    sa = doc["A"]["uncertainty"]["noise_equivalent_exposure_lux_s"]
    a = nee["A"]
    assert compare_verdict("noise_equivalent_exposure_lux_s", a, a * 1.0004, sa, sa) == \
        f"same within ±{difference_tolerance(sa, sa):.2g}"
    assert compare_verdict("noise_equivalent_exposure_lux_s", a, a * 1.05, sa, sa) == "A better"
    # MTF50: 0.003 cy/px apart (beyond the old fixed ±0.002) is within the measured ±; a pinhole's
    # f-number changes the light, not the blur
    s50 = doc["A"]["uncertainty"]["mtf50_cy_px"]
    assert compare_verdict("mtf50_cy_px", 0.25, 0.253, s50, s50).startswith("same within")
    assert p.optics.model == "pinhole"
    assert {r["metric"]: r for r in doc["table"]}["mtf50_cy_px"][""].startswith("same within")


def test_the_verdict_uses_the_uncertainties_it_is_given():
    from workbench.metrics.study import compare_verdict
    assert compare_verdict("delta_e_mean", 2.0, 2.0) == "same within ±0"
    assert compare_verdict("delta_e_mean", 2.0, 2.001) == "A better"            # exact figures: any difference
    assert compare_verdict("delta_e_mean", 2.0, 2.09, 0.03, 0.04) == "same within ±0.1"       # 2·√(0.03² + 0.04²)
    assert compare_verdict("delta_e_mean", 2.0, 2.11, 0.03, 0.04) == "A better"
    assert compare_verdict("mtf50_cy_px", 0.30, 0.32, 0.004, 0.003) == "B better"
    assert compare_verdict("mtf50_cy_px", 0.30, None, 0.004, 0.003) == ""


def test_study_runs_the_grid_resumes_and_draws_the_pareto_chart(small_camera, tmp_path, capsys):
    out = tmp_path / "study"
    args = ["study", str(small_camera), "--vary", "sensor.pixel_pitch_um=1.5,3", "--vary", "sensor.read_noise_V=0.001",
            "--out", str(out)]
    assert main(args) == 0
    doc = json.loads((out / "study.json").read_text())
    assert [d["design"] for d in doc["designs"]] == ["pixel_pitch_um=1.5 read_noise_V=0.001",
                                                      "pixel_pitch_um=3 read_noise_V=0.001"]
    assert all(d["seconds"] > 0 for d in doc["designs"])
    assert (out / "pareto.png").stat().st_size > 5_000 and "Pareto front" in (out / "study.md").read_text()
    capsys.readouterr()
    assert main(args) == 0                                   # a rerun measures nothing again
    assert "2 designs, 2 already measured" in capsys.readouterr().err
    assert json.loads((out / "study.json").read_text())["designs"] == doc["designs"]


@pytest.mark.parametrize("vary, message", [
    ("sensor.pixel_pitch_um", "SECTION.FIELD=V1,V2"),
    ("sensor.no_such_field=1,2", "no_such_field"),
    ("nosection.x=1", "nosection"),
    ("sensor.pixel_pitch_um=-1", "pixel_pitch_um"),
])
def test_study_refuses_a_bad_grid_by_name_and_writes_nothing(small_camera, tmp_path, capsys, vary, message):
    assert main(["study", str(small_camera), "--vary", vary, "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "s").exists()


def test_study_refuses_a_folder_of_another_study(small_camera, tmp_path, capsys):
    out = tmp_path / "s"
    assert main(["study", str(small_camera), "--vary", "optics.f_number=4", "--out", str(out)]) == 0
    assert main(["study", str(small_camera), "--vary", "optics.f_number=8", "--out", str(out)]) == 2
    assert "holds another study" in capsys.readouterr().err


def test_study_with_a_detector_needs_its_data_and_a_real_checkpoint(small_camera, tmp_path, capsys):
    assert main(["study", str(small_camera), "--vary", "optics.f_number=4", "--out", str(tmp_path / "s"),
                 "--detector", str(tmp_path / "none.pt")]) == 2
    assert "--detector/--data" in capsys.readouterr().err
    assert main(["study", str(small_camera), "--vary", "optics.f_number=4", "--out", str(tmp_path / "s"),
                 "--detector", str(tmp_path / "none.pt"), "--data", str(tmp_path)]) == 2
    assert "no such checkpoint" in capsys.readouterr().err
