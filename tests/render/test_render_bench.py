"""The render benchmark runs end to end in --quick mode and reports what it promises."""
import argparse

import numpy as np
import pytest


@pytest.mark.slow
def test_bench_render_quick(tmp_path):
    from workbench.bench.render import bench_render
    from workbench.bench.render_features import feature_cases

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
    feats = {r["case"]: r for r in res.extra["features_2pct"]}
    assert len(feats) == len(feature_cases()) and {"paint clearcoat", "detailed assets"} <= set(feats)
    assert all(r["s_per_spp"] > 0 and r["c_broadband"] > 0 for r in feats.values())
    assert feats["baseline (uniform sky)"]["x_baseline"] == 1.0
