"""The render benchmark runs end to end in --quick mode and reports what it promises."""
import argparse

import numpy as np
import pytest


@pytest.mark.slow
def test_bench_render_quick(tmp_path, monkeypatch):
    """The whole quick render bench, its feature table cut to the baseline case (every case's row is
    test_feature_bench_rows_per_case_and_resolution's; here the list of cases is checked)."""
    from workbench.bench import render_features as rf
    from workbench.bench.render import bench_render

    cases = rf.feature_cases()
    assert {"paint clearcoat", "detailed assets", "tunnel exit view (day, luminaires)"} <= {c.name for c in cases}
    assert cases[0].name == rf.BASELINE
    monkeypatch.setattr(rf, "feature_cases", lambda: cases[:1])
    from workbench.bench import render_noise_scenes as rns
    monkeypatch.setattr(rns, "CASES", rns.CASES[:1])                  # its own test below covers the rest
    monkeypatch.setattr(rns, "noise_plan", lambda quick: (1, 8, 4, 8))
    res = bench_render(argparse.Namespace(quick=True, json=False, out=str(tmp_path)))
    assert {r["repr"] for r in res.rows} >= {"bands6", "bands30", "basis6", "sensor3"}
    for r in res.rows:
        assert np.isfinite(r["err_broadband"]) and r["time_s"] > 0 and r["peak_rss_MB"] > 0
    big = {r["repr"]: r for r in res.rows if r["spp"] == max(x["spp"] for x in res.rows)}
    small = {r["repr"]: r for r in res.rows if r["spp"] == min(x["spp"] for x in res.rows)}
    assert all(big[k]["err_broadband"] < small[k]["err_broadband"] for k in big)   # error falls with spp
    cost = res.extra["cost_640x480_2pct"][0]
    assert cost["spp_for_2pct"] >= 1 and cost["err_broadband_measured"] is None and cost["core_min_per_frame"] > 0 and cost["npz_float16_MB"] > 0
    assert (tmp_path / "bench_render.png").exists()
    assert [r["scene"] for r in res.extra["scene_noise"]] == [rns.DAY]
    feats = res.extra["features_2pct"]
    assert [(r["case"], r["res"]) for r in feats] == [(rf.BASELINE, "48x36"), (rf.BASELINE, "96x72")]


@pytest.mark.slow
def test_feature_bench_rows_per_case_and_resolution():
    """The feature table: one row per case and resolution, times and noise constants positive,
    Koschmieder fog with its fogging time, x_baseline 1 for the baseline (a tiny run of 3 cases)."""
    from workbench.bench import render_features as rf
    from workbench.render.variants import select_variant
    select_variant()
    cases = [c for c in rf.feature_cases() if c.name in (rf.BASELINE, "fog V=150 m koschmieder",
                                                          "night HPS, view light selection")]
    film, fov = rf.bench_camera_film()
    rows = rf.feature_costs(film, fov, [(24, 18), (32, 24)], [(2, 4), (1, 2)], cases)
    assert [(r["case"], r["res"]) for r in rows] == [(c.name, res) for res in ("24x18", "32x24") for c in cases]
    for r in rows:
        assert r["cpu_s_per_spp"] > 0 and r["c_broadband"] > 0 and r["spp_for_2pct"] >= 1
        assert r["cpu_s_per_frame_2pct"] > 0 and (r["fog_cpu_s"] > 0) == ("koschmieder" in r["case"])
        assert r["x_baseline"] > 0 and (r["x_baseline"] == 1.0 or r["case"] != rf.BASELINE)
    assert len({c.name for c in rf.feature_cases()}) == len(rf.feature_cases())


@pytest.mark.slow
def test_scene_noise_rows_before_and_after(monkeypatch):
    """The night/tunnel/day noise table (render_noise_scenes): a row per case, setting and frame,
    ratios and costs finite and positive, the night's 'after' row the shading light selection, the
    day frame the unit of cost (a tiny plan: day and night, one frame, 16 and 4 spp, 1/32 size)."""
    from workbench.bench import render_noise_scenes as rns
    monkeypatch.setattr(rns, "CASES", rns.CASES[:2])
    monkeypatch.setattr(rns, "noise_plan", lambda quick: (1, 16, 4, 8))
    rows = rns.scene_noise_rows(True)
    assert [(r["scene"], r["setting"].split()[0]) for r in rows] == [(rns.DAY, "before"), ("night", "before"),
                                                                    ("night", "after")]
    assert "light_selection=shading" in rows[2]["setting"]
    for r in rows:
        assert all(np.isfinite(r[k]) and r[k] >= 0
                   for k in ("median", "p90", "edge", "power", "power_clipped", "power_dim", "top_0.1pct"))
        assert isinstance(r["fireflies"], int) and r["fireflies"] >= 0
        assert r["spp_at_criterion"] >= 1 and r["core_s_per_kpx_at_criterion"] > 0 and r["cpu_s"] > 0
    assert rows[0]["x_day_cost"] == 1.0
