"""`workbench bench optics --quick` end to end (slow: it ray-traces every scene)."""
import argparse

import pytest


@pytest.mark.slow
def test_optics_bench_quick_writes_rows_and_plot(tmp_path, monkeypatch):
    """The quick optics bench end to end; its city frame at 32 columns and 16 spp (the full-model
    reference's physics is test_fullmodel_bench's)."""
    from workbench.bench import optics
    from workbench.bench.optics import bench_optics
    city_scenes = optics._city_scenes
    monkeypatch.setattr(optics, "_city_scenes", lambda cols, spp: city_scenes(32, 16))
    result = bench_optics(argparse.Namespace(quick=True, json=False, out=str(tmp_path)))
    levels = {r["level"].split(" (")[0] for r in result.rows}
    assert {"pinhole", "diffraction_limited", "thin_lens", "psf_grid", "raytrace"} <= levels
    assert any(r["level"].startswith("auto → ") for r in result.rows)
    for scene in {r["scene"] for r in result.rows}:
        rows = {r["level"]: r for r in result.rows if r["scene"] == scene}
        reference = next(r for level, r in rows.items() if "reference" in level)
        # a pinhole frame is a scale per sample; the reference traces 64 rays per sample
        assert 0 < rows["pinhole"]["warm_time_s"] < 0.2 * reference["time_s"], scene
    assert (tmp_path / "optics_speed_vs_error.png").stat().st_size > 1000
