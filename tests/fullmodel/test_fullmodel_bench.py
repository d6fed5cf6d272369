"""The benchmarks around the full model: `bench lens-camera` (cost per camera ray) and the city
frame of `bench optics`, whose reference is now the Mitsuba lens camera."""
import argparse
import math

import numpy as np
import pytest


def test_lens_camera_bench_quick_rows(mi):
    from workbench.bench.lens_camera import bench_lens_camera
    result = bench_lens_camera(argparse.Namespace(quick=True, json=False, out=None))
    assert {(r["lens"], r["scene"]) for r in result.rows} == {
        (lens, scene) for lens in ("automotive.2.4mm", "dgauss.50mm") for scene in ("environment", "cornell box")}
    for r in result.rows:
        assert r["lens_s"] > 0 and r["perspective_s"] > 0 and math.isfinite(r["ratio_lens_vs_perspective"])
        if r["lens"] == "dgauss.50mm":                # dispersive: also timed at the d line
            assert math.isfinite(r["ratio_no_dispersion"])
        if r["scene"] == "environment":              # 16² centre pixels at 8 spp: a few % noise
            assert r["centre_E_over_L"] == pytest.approx(r["numpy_E_over_L"], rel=0.08)


def test_optics_bench_city_reference_is_the_full_model_on_the_levels_grid(mi):
    from workbench.bench.optics import _camera, _city_scenes
    from workbench.optics.types import OPTICS_MODELS
    scene, full, notes = _city_scenes(32, 16)
    assert scene is not None and full is not None, notes
    ref, seconds, second = full
    assert seconds > 0 and ref.shape == second.shape == scene.shape
    assert np.isfinite(ref.irradiance_photons).all() and ref.irradiance_photons.max() > 0
    cam = _camera().model_copy(update={"focus_distance_m": scene.distance_m})
    pin = OPTICS_MODELS["pinhole"](scene, cam.model_copy(update={"model": "pinhole"}))
    assert pin.sample_spacing_m == pytest.approx(ref.sample_spacing_m, rel=1e-6)
    # The same camera equation: the two seeds' frame mean against the pinhole's (cos⁴) agrees to the
    # lens's relative illumination beyond cos⁴ (+3…5 % measured) and the Monte Carlo noise (seeds
    # differ by ~2 %); an f-number off by 4 %, a (1+|m|)² or π factor would move it by ≥ 8 %.
    seeds_mean = 0.5 * (ref.irradiance_photons.mean() + second.irradiance_photons.mean())
    assert seeds_mean / pin.irradiance_photons.mean() == pytest.approx(1.0, abs=0.07)
    assert second.irradiance_photons.mean() / ref.irradiance_photons.mean() == pytest.approx(1.0, abs=0.05)
