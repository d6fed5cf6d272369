"""Automatic level-of-detail selection against the full model, and the 'auto' model."""
import numpy as np
import pytest

from workbench.optics.formation import radiance_to_irradiance
from workbench.optics.params import ErrorBudget, OpticsParams
from workbench.optics.formation.selector import reference_level, select_level
from workbench.scene.types import Scene

WL = np.arange(400.0, 701.0, 50.0)


def _paper_scene(depth=None):
    """640 columns over 44°: the paper's 3 µm sampling (only 4 rows: the probe sets the cost)."""
    return Scene(np.ones((4, 640, WL.size), np.float32), WL, 44.0, 10.0, depth_m=depth)


def test_paper_camera_at_f4_needs_diffraction():
    """3 µm samples at f/4: the Airy disk (2.7 µm radius) is not negligible; the pinhole fails."""
    level, report = select_level(_paper_scene(), OpticsParams(f_number=4.0))
    assert level == "diffraction_limited" and report["reference"] == "diffraction_limited"
    pin = report["levels"][0]
    assert pin["level"] == "pinhole" and not pin["passes"] and "MTF50" in pin["why_not"]
    assert level in report["why"]


def test_loose_budget_or_coarse_sampling_allows_the_pinhole():
    level, _ = select_level(_paper_scene(), OpticsParams(f_number=4.0),
                            ErrorBudget(max_rel_rms_error=0.5, max_mtf50_error=1.0))
    assert level == "pinhole"
    coarse = Scene(np.ones((4, 32, WL.size), np.float32), WL, 44.0, 10.0)   # 60 µm samples
    level, report = select_level(coarse, OpticsParams(f_number=2.0))
    assert level == "pinhole" and report["levels"][0]["passes"]


def test_strong_defocus_needs_the_thin_lens():
    depth = np.full((4, 640), 10.0, np.float32)
    depth[:, :100] = 1.0                                   # a near object, focus at 10 m
    level, report = select_level(_paper_scene(depth), OpticsParams(f_number=1.4))
    assert report["reference"] == "thin_lens" and level == "thin_lens"
    assert report["probe"]["worst_coc_um"] > 3.0
    assert all(not r["passes"] for r in report["levels"][:-1])


def test_auto_model_runs_the_chosen_level_and_reports_it():
    scene = Scene(np.ones((8, 640, WL.size), np.float32), WL, 44.0, 10.0)
    oi = radiance_to_irradiance(scene, OpticsParams(model="auto", f_number=4.0))
    assert oi.meta["model"] == "diffraction_limited"
    assert oi.meta["auto"]["chosen"] == "diffraction_limited" and oi.meta["auto"]["why"]
    assert np.all(np.isfinite(oi.irradiance_photons))


@pytest.mark.slow
def test_real_lens_field_checks_rule_out_the_lens_free_levels():
    """Automotive wide angle at f/2.68, 30 µm samples: cos⁴ misses the lens's vignetting."""
    scene = Scene(np.ones((12, 64, 3), np.float32), np.array([450.0, 550.0, 650.0]), 44.0, 10.0)
    level, report = select_level(scene, OpticsParams(lens_file="automotive.2.4mm", f_number=2.68))
    assert report["reference"] == "psf_grid" and level == "psf_grid"     # spot ≈ Airy: wave regime
    assert report["field"]["corner_ri_error"] > 0.05
    assert all("corner illumination" in r["why_not"] for r in report["levels"][:3])


def test_reference_is_ray_tracing_only_in_the_geometric_regime():
    field = {"rms_spot_um_axis": 12.0, "rms_spot_um_corner": 44.0, "airy_radius_um": 2.7}
    assert reference_level(True, {}, field)[0] == "raytrace"
    field = {"rms_spot_um_axis": 1.8, "rms_spot_um_corner": float("nan"), "airy_radius_um": 2.7}
    assert reference_level(True, {}, field)[0] == "psf_grid"
    assert reference_level(False, {"worst_coc_um": 0.0, "sample_spacing_um": 3.0}, {})[0] == "diffraction_limited"
    assert reference_level(False, {"worst_coc_um": 4.0, "sample_spacing_um": 3.0}, {})[0] == "thin_lens"
