"""Thin-lens level: circle of confusion from the lens law, defocus by depth layers."""
import math

import numpy as np
import pytest

from workbench.optics.formation import diffraction, thin_lens
from workbench.optics.params import OpticsParams
from workbench.scene.types import Scene


def test_coc_equals_the_similar_triangles_of_the_lens_law():
    f, n, s = 0.05, 2.0, 2.0
    z = np.array([0.5, 1.0, 2.0, 5.0, 1e4, math.inf])
    a = f / n
    d_s = 1 / (1 / f - 1 / s)
    d_z = np.array([1 / (1 / f - 1 / zi) if np.isfinite(zi) else f for zi in z])
    expected = a * np.abs(d_z - d_s) / d_z
    assert np.allclose(thin_lens.circle_of_confusion_m(z, f, n, s), expected, rtol=1e-9)
    with pytest.raises(ValueError, match="focal length"):
        thin_lens.circle_of_confusion_m(np.array([0.01]), f, n, s)


def _point_scene(depth_point_m, focus_m, spacing_m=20e-6, size=96, f=0.05):
    d_img = 1 / (1 / f - 1 / focus_m)
    fov = math.degrees(2 * math.atan(spacing_m * size / 2 / d_img))
    rad = np.zeros((size, size, 1), np.float32)
    rad[size // 2, size // 2] = 1e18
    depth = np.full((size, size), focus_m, np.float32)
    depth[size // 2, size // 2] = depth_point_m
    return Scene(rad, np.array([550.0]), fov, focus_m, depth_m=depth)


@pytest.mark.parametrize("kernel", ["pillbox", "gaussian"])
def test_defocused_point_has_the_predicted_blur_size(kernel):
    """A point 1 m away, focus 2 m, 50 mm f/2: c = 641 µm ≈ 32 samples; ⟨r²⟩ = c²/8."""
    scene = _point_scene(1.0, 2.0)
    p = OpticsParams(focal_length_mm=50, f_number=2, off_axis="none", defocus_kernel=kernel, depth_layers=4)
    oi = thin_lens.radiance_to_irradiance(scene, p)
    img = oi.irradiance_photons[..., 0].astype(np.float64)
    c = thin_lens.circle_of_confusion_m(np.array([1.0]), 0.05, 2.0, 2.0)[0]
    yy, xx = np.indices(img.shape) - 48
    r2 = ((xx ** 2 + yy ** 2) * img).sum() / img.sum() * oi.sample_spacing_m ** 2
    assert math.sqrt(8 * r2) == pytest.approx(c, rel=0.03)
    assert img.sum() == pytest.approx(scene.radiance_photons.sum() * math.pi / (1 + 16 * (1 + 0.05 / 1.95) ** 2),
                                      rel=0.01)


def test_in_focus_scene_equals_the_diffraction_level():
    rng = np.random.default_rng(3)
    rad = rng.uniform(1e14, 1e15, (24, 32, 2)).astype(np.float32)
    scene = Scene(rad, np.array([500.0, 600.0]), 30.0, 5.0)   # no depth map: all at 5 m
    p = OpticsParams(f_number=2.8)
    a = thin_lens.radiance_to_irradiance(scene, p)
    b = diffraction.radiance_to_irradiance(scene, p)
    assert a.meta["layers"] == 1
    assert np.allclose(a.irradiance_photons, b.irradiance_photons, rtol=1e-5)


def test_only_the_out_of_focus_layer_is_blurred():
    rad = np.zeros((64, 64, 1), np.float32)
    rad[16, 16] = rad[48, 48] = 1e18
    depth = np.full((64, 64), 2.0, np.float32)
    depth[32:, :] = 0.8
    d_img = 1 / (1 / 0.05 - 1 / 2.0)
    fov = math.degrees(2 * math.atan(20e-6 * 32 / d_img))
    scene = Scene(rad, np.array([550.0]), fov, 2.0, depth_m=depth)
    oi = thin_lens.radiance_to_irradiance(scene, OpticsParams(focal_length_mm=50, f_number=2, off_axis="none"))
    img = oi.irradiance_photons[..., 0]
    assert img[16, 16] > 0.9 * img[10:23, 10:23].sum()     # sharp
    assert img[48, 48] < 0.01 * img[32:, 32:].sum()        # spread over the CoC
    assert np.all(np.isfinite(img)) and img.min() >= 0
