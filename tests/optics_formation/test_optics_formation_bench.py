"""`workbench bench optics --quick` end to end (slow: it ray-traces every scene)."""
import argparse

import pytest


@pytest.mark.slow
def test_optics_bench_quick_writes_rows_and_plot(tmp_path):
    from workbench.bench.optics import bench_optics
    result = bench_optics(argparse.Namespace(quick=True, json=False, out=str(tmp_path)))
    levels = {r["level"].split(" (")[0] for r in result.rows}
    assert {"pinhole", "diffraction_limited", "thin_lens", "psf_grid", "raytrace"} <= levels
    assert any(r["level"].startswith("auto → ") for r in result.rows)
    for r in result.rows:
        assert r["time_s"] >= 0
    assert (tmp_path / "optics_speed_vs_error.png").stat().st_size > 1000
