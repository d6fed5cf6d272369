"""PSF-grid level: weights, PSF orientation, agreement with the diffraction and ray-traced levels."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from workbench.optics.formation import diffraction, mtf, psf_grid, raytrace
from workbench.optics.params import OpticsParams
from workbench.scene.charts import slanted_edge_scene
from workbench.scene.types import Scene


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-10, 10), min_size=1, max_size=20), st.integers(1, 9), st.booleans())
def test_hat_weights_sum_to_one_and_are_non_negative(values, k, periodic):
    v = np.array(values)
    nodes = np.arange(k) * 2 * np.pi / k if periodic else np.linspace(-5, 5, k)
    w = psf_grid.hat_weights(v, nodes, periodic=periodic)
    assert np.allclose(w.sum(0), 1.0) and w.min() >= -1e-12


def test_psf_is_turned_to_point_outwards():
    psf = np.zeros((9, 9))
    psf[8, 4] = 1.0                                      # +y (outward) in sensor axes
    assert np.argwhere(psf_grid._oriented(psf, 0.0) > 0.5).tolist() == [[0, 4]]            # up
    assert np.argwhere(psf_grid._oriented(psf, np.pi / 2) > 0.3).tolist() == [[4, 8]]      # right
    assert np.argwhere(psf_grid._oriented(psf, np.pi) > 0.5).tolist() == [[8, 4]]          # down


def test_on_axis_edge_matches_the_diffraction_level_when_stopped_down():
    """Automotive lens at f/8, 1 µm samples: near diffraction-limited on axis."""
    p = OpticsParams(lens_file="automotive.2.4mm", f_number=8.0, psf_field_zones=2, psf_wavelengths=1)
    dx, d = 1e-6, 2.3761e-3
    scene = slanted_edge_scene(size=(64, 64), fov_deg=math.degrees(2 * math.atan(32 * dx / d)),
                               distance_m=1e9, wavelengths_nm=np.array([550.0]))
    a = psf_grid.radiance_to_irradiance(scene, p)
    b = diffraction.radiance_to_irradiance(scene, p.model_copy(update={"focal_length_mm": 2.3761}))
    ma, mb = (mtf.slanted_edge_mtf(o.irradiance_photons, window=False) for o in (a, b))
    g = np.linspace(0, 0.5, 51)
    diff = np.interp(g, ma.frequency_cyc_per_sample, ma.mtf) - np.interp(g, mb.frequency_cyc_per_sample, mb.mtf)
    assert np.max(np.abs(diff)) < 0.03
    assert ma.mtf50_cyc_per_sample == pytest.approx(mb.mtf50_cyc_per_sample, rel=0.03)
    assert a.irradiance_photons.mean() == pytest.approx(b.irradiance_photons.mean(), rel=0.02)


def test_uniform_field_agrees_with_the_ray_traced_level():
    """Double Gauss f/2: relative illumination (vignetting) and distortion from the lens."""
    scene = Scene(np.full((12, 16, 1), 1e16, np.float32), np.array([550.0]), 30.0, 1e6)
    p = OpticsParams(lens_file="dgauss.50mm", f_number=2.03, rays_per_sample=1024, psf_field_zones=2,
                     psf_wavelengths=1)
    a = psf_grid.radiance_to_irradiance(scene, p).irradiance_photons[..., 0]
    b = raytrace.radiance_to_irradiance(scene, p).irradiance_photons[..., 0]
    assert np.allclose(a, b, rtol=0.04)
    assert a[0, 0] < 0.5 * a[6, 8]                      # vignetted corner
    assert np.all(np.isfinite(a))
