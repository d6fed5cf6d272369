"""Pinhole level: camera equation, cos⁴ fall-off, sampling, distortion, parameter validation."""
import math

import numpy as np
import pytest
from pydantic import ValidationError

from workbench.optics.formation import geometry, pinhole
from workbench.optics.params import OpticsParams, focal_length_for_fov_mm, fov_deg
from workbench.optics.types import OPTICS_MODELS
from workbench.scene.charts import uniform_scene
from workbench.scene.types import Scene

WL = np.array([450.0, 550.0, 650.0])


def _uniform(size=(32, 48), fov=44.0, distance=10.0, level=1e16):
    rad = np.full(size + (WL.size,), level, np.float32)
    return Scene(rad, WL, fov, distance)


def test_paper_camera_defaults():
    p = OpticsParams()
    assert p.focal_length_mm == pytest.approx(0.96 / math.tan(math.radians(22)), rel=1e-4)
    assert p.f_number == 4.0 and p.model == "pinhole"
    assert focal_length_for_fov_mm(44, 1.92) == pytest.approx(2.37608, rel=1e-5)
    assert fov_deg(focal_length_for_fov_mm(30.0, 6.4), 6.4) == pytest.approx(30.0)
    assert "pinhole" in OPTICS_MODELS


@pytest.mark.parametrize("bad", [{"model": "fisheye"}, {"f_number": 0}, {"transmittance": 1.5},
                                 {"off_axis": "cos3"}, {"lens_file": "../etc/passwd"},
                                 {"lens_file": "/abs/lens.json"}, {"distortion_k": (0.1, 0.2, 0.3, 0.4)},
                                 {"focus_distance_m": -1}])
def test_bad_params_are_refused_naming_the_field(bad):
    with pytest.raises(ValidationError) as err:
        OpticsParams(**bad)
    assert next(iter(bad)) in str(err.value)


@pytest.mark.parametrize("f_number,distance_m,transmittance", [(4.0, 10.0, 1.0), (2.0, 0.05, 0.8),
                                                               (11.0, 1e9, 0.5)])
def test_camera_equation_on_uniform_scene(f_number, distance_m, transmittance):
    """Centre irradiance vs πTL/(1+4N²(1+|m|)²), m = f/(f − s) from the thin-lens law."""
    p = OpticsParams(f_number=f_number, transmittance=transmittance, off_axis="none")
    scene = _uniform(distance=distance_m)
    oi = pinhole.radiance_to_irradiance(scene, p)
    f = p.focal_length_m
    m = f / (f - distance_m)
    expected = math.pi * transmittance * 1e16 / (1 + 4 * f_number ** 2 * (1 + abs(m)) ** 2)
    assert np.allclose(oi.irradiance_photons, expected, rtol=5e-3)
    assert oi.irradiance_photons.dtype == np.float32


def test_isetcam_anchor_factor_at_f4():
    """ISETCam: f/4, m≈0 → E/L = π/65 = 0.048332 (paraxial π/64 = 0.049087)."""
    oi = pinhole.radiance_to_irradiance(_uniform(distance=1e6), OpticsParams(off_axis="none"))
    assert oi.irradiance_photons[0, 0, 0] / 1e16 == pytest.approx(0.048332, rel=1e-4)


def test_sample_spacing_and_upright_image():
    p = OpticsParams()
    scene = _uniform()
    scene.radiance_photons[:4, :6] *= 10  # bright top-left corner
    oi = pinhole.radiance_to_irradiance(scene, p)
    d_img = 1 / (1 / p.focal_length_m - 1 / scene.distance_m)
    assert oi.sample_spacing_m == pytest.approx(2 * d_img * math.tan(math.radians(22)) / 48, rel=1e-9)
    assert oi.meta["image_distance_m"] == pytest.approx(d_img)
    assert oi.irradiance_photons[0, 0, 0] > 5 * oi.irradiance_photons[-1, -1, 0]


def test_cos4th_is_exact_for_a_distant_image_plane():
    """Small field (image plane > 10 diagonals away): ISETCam's simple (d/√(d²+r²))⁴."""
    p = OpticsParams(f_number=2.0)
    scene = _uniform(size=(40, 40), fov=3.0)
    oi = pinhole.radiance_to_irradiance(scene, p)
    on_axis = geometry.camera_equation_factor(2.0, oi.meta["magnification"]) * 1e16
    x, y = geometry.sample_positions_m((40, 40), oi.sample_spacing_m)
    d = oi.meta["image_distance_m"]
    expected = on_axis * (d / np.sqrt(d * d + x * x + y * y)) ** 4
    assert np.allclose(oi.irradiance_photons[..., 1], expected, rtol=1e-5)


def _disk_irradiance_numeric(h, d, a, n=600):
    """∫ over a Lambertian disk (radius a, distance d) of d²/ρ⁴ dA at lateral offset h (per unit L)."""
    r = (np.arange(n) + 0.5) / n * a
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    rr, pp = np.meshgrid(r, phi)
    rho2 = d * d + (rr * np.cos(pp) - h) ** 2 + (rr * np.sin(pp)) ** 2
    return float((d * d / rho2 ** 2 * rr).sum() * (a / n) * (2 * np.pi / (2 * n)))


@pytest.mark.parametrize("f_number", [1.4, 4.0])
def test_cos4th_exact_formula_matches_numerical_pupil_integral(f_number):
    d = 2.4e-3
    a = d / (2 * f_number)
    r = np.array([0.0, 0.5e-3, 1.0e-3, 2.0e-3])
    fall = geometry.cos4th_falloff(r, d, f_number, 0.0, image_diagonal_m=d)
    numeric = np.array([_disk_irradiance_numeric(h, d, a) for h in r])
    assert numeric[0] == pytest.approx(math.pi / (1 + 4 * f_number ** 2), rel=1e-4)
    assert np.allclose(fall, numeric / numeric[0], rtol=1e-4)
    assert np.all(np.diff(fall) < 0)


def test_exact_falloff_tends_to_cos4_for_a_small_aperture():
    d, r = 2.4e-3, np.linspace(0, 1.2e-3, 7)
    fall = geometry.cos4th_falloff(r, d, 200.0, 0.0, image_diagonal_m=d)
    assert np.allclose(fall, (d / np.hypot(d, r)) ** 4, rtol=1e-4)


def test_exact_falloff_stays_accurate_far_off_axis():
    """Against the formula at 60 digits (mpmath): 1 − a/√(a² + 4 tan²θa) cancelled in float64 at
    r/d ≳ 10⁴ and went negative (a 10⁻⁶ mm focal length gave negative irradiance)."""
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 60
    d, f_number = 1e-3, 4.0
    r = np.array([1e-6, 1e-3, 1e-1, 10.0, 1e4, 1e8])
    fall = geometry.cos4th_falloff(r, d, f_number, 0.0, image_diagonal_m=d)
    ta2 = 1 / (2 * mpmath.mpf(f_number)) ** 2
    for r_m, got in zip(r, fall):
        t2 = (mpmath.mpf(r_m) / d) ** 2
        root = mpmath.sqrt(t2 ** 2 + 2 * t2 * (1 - ta2) + (1 + ta2) ** 2)
        exact = 0.5 * (1 - (1 - ta2 + t2) / root) * (1 + ta2) / ta2
        assert got == pytest.approx(float(exact), rel=1e-12)


def test_barrel_distortion_moves_a_point_inward():
    size, fov = (41, 41), 40.0
    rad = np.zeros(size + (1,), np.float32)
    rad[19:22, 34:37] = 1e16   # a 3×3 block 15 samples right of centre
    scene = Scene(rad, np.array([550.0]), fov, 10.0)
    k1 = -0.5
    oi = pinhole.radiance_to_irradiance(scene, OpticsParams(distortion_k=(k1,), off_axis="none"))
    img = oi.irradiance_photons[..., 0]
    d, dx = oi.meta["image_distance_m"], oi.sample_spacing_m
    r_u = 15 * dx / d
    r_d = r_u * (1 + k1 * r_u ** 2)
    col_centroid = (img.sum(0) * np.arange(41)).sum() / img.sum()
    assert col_centroid - 20 == pytest.approx(r_d * d / dx, abs=0.5)   # nearest-patch resampling
    assert col_centroid - 20 < 14.9


@pytest.mark.parametrize("k", [(-0.5,), (0.4,), (-0.4, 0.1, -0.05)])
def test_distortion_moves_flux_without_changing_it(k):
    """distort_image applies the area Jacobian: a smooth off-axis blob keeps its flux (sum over the
    same sample grid; fine enough that nearest-sample aliasing stays < 0.1 %), which a purely
    geometric warp would change by 9–12 % here."""
    n, d = 641, 1e-3
    dx = 2 * d * math.tan(math.radians(20.0)) / n
    x, y = geometry.sample_positions_m((n, n), dx)
    blob = np.exp(-0.5 * (((x - 200 * dx) ** 2 + (y - 80 * dx) ** 2) / (24 * dx) ** 2))[..., None]
    out = geometry.distort_image(blob, dx, d, k)
    assert out.sum() == pytest.approx(blob.sum(), rel=0.003)
    ru = geometry.undistort_radius(np.hypot(x, y) / d, k)
    rd = np.hypot(x, y) / d
    k1, k2, k3 = tuple(k) + (0.0,) * (3 - len(k))
    scale = np.divide(ru, rd, out=np.ones_like(rd), where=rd > 0)
    jac = scale / (1 + 3 * k1 * ru ** 2 + 5 * k2 * ru ** 4 + 7 * k3 * ru ** 6)
    geometric_only = (out[..., 0] / jac).sum()
    assert abs(geometric_only / blob.sum() - 1) > 0.08


def test_undistort_inverts_the_radial_polynomial():
    k = (-0.3, 0.05, -0.01)
    r = np.linspace(0, 0.8, 17)
    rd = r * (1 + k[0] * r ** 2 + k[1] * r ** 4 + k[2] * r ** 6)
    assert np.allclose(geometry.undistort_radius(rd, k), r, atol=1e-12)


def test_folding_distortion_is_refused():
    with pytest.raises(ValueError, match="distortion_k"):
        pinhole.radiance_to_irradiance(_uniform(), OpticsParams(distortion_k=(-3.0,)))


def test_object_inside_focal_length_is_refused():
    with pytest.raises(ValueError, match="focal length"):
        pinhole.radiance_to_irradiance(_uniform(distance=1e-3), OpticsParams())


def test_hdr_scene_stays_finite():
    scene = uniform_scene(size=(16, 16), fov_deg=20, distance_m=5)
    scene.radiance_photons[8, 8] *= 1e8   # the sun in view
    oi = pinhole.radiance_to_irradiance(scene, OpticsParams())
    assert np.all(np.isfinite(oi.irradiance_photons)) and oi.irradiance_photons.min() > 0


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (5, 1)])
@pytest.mark.parametrize("model", ["pinhole", "diffraction_limited", "thin_lens"])
def test_tiny_and_empty_scenes_stay_finite(shape, model):
    from workbench.optics.formation import radiance_to_irradiance
    for value in (0.0, 1e15):
        scene = Scene(np.full(shape + (3,), value, np.float32), WL, 10.0, 5.0)
        oi = radiance_to_irradiance(scene, OpticsParams(model=model))
        assert oi.irradiance_photons.shape == shape + (3,)
        assert np.all(np.isfinite(oi.irradiance_photons)) and oi.irradiance_photons.min() >= 0
        assert (oi.irradiance_photons.max() > 0) == (value > 0)
