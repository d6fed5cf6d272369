"""Ray-traced level through the shipped double Gauss: camera equation, fall-off, geometry."""
import math

import numpy as np
import pytest

from workbench.optics.formation import pinhole, raytrace
from workbench.optics.params import OpticsParams
from workbench.scene.types import Scene

WL = np.array([550.0])


def _uniform(size=(12, 16), fov=30.0, distance=1e6):
    return Scene(np.full(size + (1,), 1e16, np.float32), WL, fov, distance)


@pytest.mark.parametrize("f_number", [2.03, 4.0])
def test_on_axis_irradiance_at_infinity_matches_the_camera_equation(f_number):
    """Double Gauss focused at infinity: E/L on axis within 2 % of π/(4N²)."""
    p = OpticsParams(lens_file="dgauss.50mm", f_number=f_number, rays_per_sample=256)
    oi = raytrace.radiance_to_irradiance(_uniform(size=(4, 4), fov=2.0), p)
    e = oi.irradiance_photons[1:3, 1:3, 0].mean() / 1e16
    assert e == pytest.approx(math.pi / (4 * f_number ** 2), rel=0.02)
    assert oi.f_number == pytest.approx(f_number)


def test_falloff_is_monotone_and_below_cos4_when_vignetted():
    p = OpticsParams(lens_file="dgauss.50mm", f_number=2.03, rays_per_sample=256, off_axis="cos4th")
    rt = raytrace.radiance_to_irradiance(_uniform(size=(2, 32), fov=40.0), p).irradiance_photons[0, 16:, 0]
    ph = pinhole.radiance_to_irradiance(_uniform(size=(2, 32), fov=40.0),
                                        OpticsParams(focal_length_mm=50.358, f_number=200)).irradiance_photons[0, 16:, 0]
    ri, cos4 = rt / rt[0], ph / ph[0]
    assert np.all(np.diff(ri) < 0.01)
    assert np.all(ri[4:] <= cos4[4:] + 0.01) and ri[-1] < 0.6 * cos4[-1]


def test_image_is_upright_and_at_the_pinhole_position():
    rad = np.zeros((16, 16, 1), np.float32)
    rad[2:4, 12:14] = 1e16               # upper right
    scene = Scene(rad, WL, 20.0, 1e6)
    rt = raytrace.radiance_to_irradiance(scene, OpticsParams(lens_file="dgauss.50mm", f_number=8,
                                                             rays_per_sample=64))
    img = rt.irradiance_photons[..., 0]
    rows, cols = np.indices(img.shape)
    cy, cx = (rows * img).sum() / img.sum(), (cols * img).sum() / img.sum()
    assert cy == pytest.approx(2.5, abs=0.3) and cx == pytest.approx(12.5, abs=0.3)


def test_missing_lens_file_is_a_clear_error():
    with pytest.raises(ValueError, match="lens_file"):
        raytrace.radiance_to_irradiance(_uniform(), OpticsParams(model="raytrace"))
