"""`workbench bench isp --quick` runs and reports the figures it promises."""
import argparse

import numpy as np

from isp_synthetic import BAYER_TILES, camera_like_qe, macbeth_chart, sensor_image
from workbench.isp import ISPParams, sensor_image_to_srgb, xyz_to_srgb
from workbench.bench.isp import bench_isp


def test_bench_isp_quick():
    result = bench_isp(argparse.Namespace(quick=True, json=False, out=None))
    stages = [r["stage"] for r in result.rows]
    assert any("sensor_image_to_srgb" in s for s in stages) and any("menon2007" in s for s in stages)
    assert all(r["median_ms"] > 0 and r["cpu_ms"] > 0 for r in result.rows)
    by_stage = {r["stage"]: r["cpu_ms"] for r in result.rows}   # the full ISP costs more than one step of it
    assert by_stage["sRGB encode"] < by_stage["sensor_image_to_srgb bilinear + matrix + gray_world + sRGB"]
    assert result.rows[0]["max_err_vs_colour_demosaicing"] < 1e-5
    assert 0 <= result.extra["delta_e_2000_mean"] < 3


def test_xyz_to_srgb_matches_the_pipeline():
    qe = camera_like_qe()
    img, _ = macbeth_chart(qe)
    for normalize in ("swing", "max"):
        res = sensor_image_to_srgb(sensor_image(img, BAYER_TILES["RGGB"], "RGB", qe),
                          ISPParams(illuminant_correction="none", normalize=normalize, highlights="clip"))
        np.testing.assert_allclose(xyz_to_srgb(res.xyz, normalize), res.srgb, atol=1e-5)
