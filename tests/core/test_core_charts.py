"""Analytic charts: exact radiance, luminance and dynamic range."""
import numpy as np
import pytest

from workbench import spectra
from workbench.scene import charts


def _lum(scene):
    return spectra.luminance_from_photons(scene.radiance_photons.astype(np.float64), scene.wavelengths_nm)


def test_uniform_scene_luminance():
    s = charts.uniform_scene("A", 250.0, size=(5, 7))
    lum = _lum(s)
    np.testing.assert_allclose(lum, 250.0, rtol=1e-5)
    assert s.radiance_photons.dtype == np.float32


def test_macbeth_patches_are_reflectance_times_illuminant():
    s = charts.macbeth_scene("D65", 100.0, size=(48, 72))
    layout = s.meta["layout"]
    assert set(np.unique(layout)) == set(range(-1, 24))
    wl = s.wavelengths_nm
    refl = spectra.macbeth_reflectances(wl)
    white = s.radiance_photons[layout == 18].mean(0) / refl[18]      # white patch → illuminant
    for k in (0, 5, 13, 23):
        np.testing.assert_allclose(s.radiance_photons[layout == k].mean(0), refl[k] * white, rtol=1e-4)
    assert _lum(s).mean() == pytest.approx(100.0, rel=1e-4)


def test_slanted_edge_geometry():
    s = charts.slanted_edge_scene(angle_deg=0.0, contrast=0.5, size=(8, 8), supersample=4)
    lum = _lum(s)
    assert np.all(lum[:, :4] < lum[:, 4:])
    assert lum[:, 5].mean() / lum[:, 2].mean() == pytest.approx(2.0, rel=1e-4)   # (1)/(1-0.5)


def test_hdr_tunnel_dynamic_range_and_finite():
    s = charts.hdr_tunnel_scene(size=(60, 80))
    lum = _lum(s)
    assert lum.max() / lum.min() >= 1e5
    assert np.all(np.isfinite(s.radiance_photons))


@pytest.mark.parametrize("size", [(1, 1), (3, 5)])
def test_tiny_and_odd_sizes(size):
    for make in charts.CHARTS.values():
        s = make(size=size)
        assert s.radiance_photons.shape[:2] == size
        assert np.all(np.isfinite(s.radiance_photons))


def test_bad_sizes_are_refused():
    with pytest.raises(ValueError, match="at least 1"):
        charts.uniform_scene(size=(0, 4))
    with pytest.raises(ValueError, match="too large"):
        charts.uniform_scene(size=(100000, 100000))


def test_chart_depth_is_measured_along_each_ray():
    s = charts.uniform_scene(size=(3, 101), fov_deg=90.0, distance_m=2.0)
    assert s.depth_m[1, 50] == pytest.approx(2.0, rel=1e-3)                    # on axis
    tan_x = (0.5 - 101 / 2) * 2 * np.tan(np.radians(45)) / 101              # left column centre
    assert s.depth_m[1, 0] == pytest.approx(2.0 * np.hypot(1.0, tan_x), rel=1e-5)
