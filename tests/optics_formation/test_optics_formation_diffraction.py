"""Diffraction-limited level and the slanted-edge MTF, against closed forms."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.special import erf

from workbench.optics.formation import diffraction, fourier, mtf, pinhole
from workbench.optics.params import OpticsParams
from workbench.scene.charts import slanted_edge_scene
from workbench.scene.types import Scene


def _analytic_mtf(nu_over_cutoff):
    phi = np.arccos(np.minimum(nu_over_cutoff, 1.0))
    return (2 / np.pi) * (phi - np.cos(phi) * np.sin(phi))


def test_mtf_formula_matches_the_phi_form():
    s = np.linspace(0, 1.2, 50)
    otf = diffraction.diffraction_mtf(s / (550e-9 * 4.0), 550e-9, 4.0)
    assert np.allclose(otf, _analytic_mtf(s), atol=1e-12)
    assert otf[0] == 1.0 and np.all(otf[s >= 1] == 0)


def test_slanted_edge_mtf_of_a_gaussian_edge():
    """Point-sampled erf edge (σ = 1.2 samples): MTF = exp(−2π²σ²f²)."""
    sigma, angle = 1.2, math.radians(5.0)
    rows, cols = 96, 64
    jj, ii = np.meshgrid(np.arange(cols) + 0.5 - cols / 2, np.arange(rows) + 0.5 - rows / 2)
    dist = (jj - ii * math.tan(angle)) * math.cos(angle)
    img = 0.1 + 0.5 * (1 + erf(dist / (sigma * math.sqrt(2))))
    res = mtf.slanted_edge_mtf(img, window=False)
    f = res.frequency_cyc_per_sample
    expected = np.exp(-2 * np.pi ** 2 * sigma ** 2 * f ** 2)
    assert res.edge_angle_deg == pytest.approx(-5.0, abs=0.05) or res.edge_angle_deg == pytest.approx(5.0, abs=0.05)
    assert np.max(np.abs(res.mtf - expected)[f <= 0.5]) < 0.01
    assert res.mtf50_cyc_per_sample == pytest.approx(math.sqrt(math.log(2) / 2) / (math.pi * sigma), rel=0.02)


def test_slanted_edge_refuses_flat_and_axis_aligned_images():
    with pytest.raises(ValueError, match="no edge"):
        mtf.slanted_edge_mtf(np.ones((32, 32)))
    img = np.zeros((32, 32))
    img[:, 16:] = 1
    with pytest.raises(ValueError, match="1–30°"):
        mtf.slanted_edge_mtf(img)


def _supersample_response(f, n, angle_rad):
    """Response of the chart's n×n supersampled area coverage, projected on the edge normal."""
    def dirichlet(g):
        g = np.asarray(g, dtype=np.float64)
        den = n * np.sin(np.pi * g / n)
        return np.where(np.abs(g) < 1e-12, 1.0, np.sin(np.pi * g) / np.where(den == 0, 1, den))
    return dirichlet(f * math.cos(angle_rad)) * dirichlet(f * math.sin(angle_rad))


def test_formed_edge_mtf_matches_the_diffraction_mtf():
    """f/8 at 550 nm, spacing set so the cut-off sits at 0.4 cycles/sample."""
    p = OpticsParams(f_number=8.0, off_axis="none", focal_length_mm=4.0)
    cutoff_per_sample = 0.4
    wl = 550e-9
    d_img = 1 / (1 / p.focal_length_m - 1 / 10.0)
    n_w = p.f_number * d_img / p.focal_length_m
    spacing = cutoff_per_sample * wl * n_w
    size = (128, 96)
    fov = math.degrees(2 * math.atan(spacing * size[1] / 2 / d_img))
    scene = slanted_edge_scene(angle_deg=5.0, contrast=0.8, size=size, fov_deg=fov, distance_m=10.0,
                               wavelengths_nm=np.array([550.0]))
    oi = diffraction.radiance_to_irradiance(scene, p)
    res = mtf.slanted_edge_mtf(oi.irradiance_photons, window=False)
    f = res.frequency_cyc_per_sample
    expected = _analytic_mtf(f / cutoff_per_sample) * _supersample_response(f, 8, math.radians(5.0))
    sel = f <= 0.5
    assert np.max(np.abs(res.mtf[sel] - expected[sel])) < 0.02
    fine = np.linspace(0, 0.5, 5001)
    exp50 = mtf.mtf50(fine, _analytic_mtf(fine / cutoff_per_sample) * _supersample_response(fine, 8, math.radians(5)))
    assert res.mtf50_cyc_per_sample == pytest.approx(exp50, rel=0.02)
    assert res.frequency_cyc_per_mm(oi.sample_spacing_m)[1] > 0


def test_otf_filter_conserves_energy_and_keeps_uniform_fields_uniform():
    rad = np.zeros((64, 64, 2), np.float32)
    rad[30:34, 30:34] = 1e15
    scene = Scene(rad, np.array([450.0, 650.0]), 1.0, 10.0)
    p = OpticsParams(f_number=16.0, off_axis="none")
    pin = pinhole.radiance_to_irradiance(scene, p)
    dl = diffraction.radiance_to_irradiance(scene, p)
    for c in range(2):
        assert dl.irradiance_photons[..., c].sum() == pytest.approx(pin.irradiance_photons[..., c].sum(), rel=2e-3)
    assert dl.irradiance_photons[31, 31, 1] < pin.irradiance_photons[31, 31, 1]
    flat = Scene(np.full((20, 30, 2), 3e15, np.float32), np.array([450.0, 650.0]), 10.0, 10.0)
    out = diffraction.radiance_to_irradiance(flat, p).irradiance_photons
    assert np.allclose(out, out[0, 0], rtol=1e-5)


@settings(max_examples=15, deadline=None)
@given(st.integers(8, 40), st.integers(8, 40), st.floats(1.0, 3.0))
def test_otf_filter_conserves_light_and_keeps_the_centroid(rows, cols, sigma_samples):
    """A Gaussian PSF (OTF(0) = 1, non-negative) on an object with a dark margin of 5σ: no light
    crosses the border, so the total is kept (to the PSF's truncated tail and ringing, < 1e-3)
    and the centroid stays put (a shifted crop or an unnormalised OTF would fail)."""
    m = int(np.ceil(5 * sigma_samples))
    rng = np.random.default_rng(rows * 100 + cols)
    img = np.zeros((rows + 2 * m, cols + 2 * m, 1))
    img[m:m + rows, m:m + cols, 0] = rng.uniform(0, 1, (rows, cols))

    def otf(c, fy, fx):
        return np.exp(-2 * np.pi ** 2 * sigma_samples ** 2 * (fy ** 2 + fx ** 2))
    out, clipped = fourier.apply_otf(img, 1.0, otf, pad=fourier.pad_width(img.shape[:2], 2))
    assert np.all(np.isfinite(out)) and out.min() >= 0
    assert out.sum() == pytest.approx(img.sum(), rel=1e-3)
    ii, jj = np.indices(img.shape[:2])
    for grid in (ii, jj):
        centroid = lambda a: (a[..., 0] * grid).sum() / a.sum()  # noqa: E731
        assert centroid(out) == pytest.approx(centroid(img), abs=0.01)
    assert not np.allclose(out, img, atol=1e-3)         # it did blur


def test_hdr_sun_in_view_stays_finite_and_non_negative():
    wl = np.array([450.0, 550.0, 650.0])
    rad = np.full((64, 64, 3), 1e14, np.float32)
    rad[30:33, 30:33] = 1e22          # 10⁸:1
    scene = Scene(rad, wl, 2.0, 10.0)
    oi = diffraction.radiance_to_irradiance(scene, OpticsParams(f_number=2.0))
    e = oi.irradiance_photons
    assert np.all(np.isfinite(e)) and e.min() >= 0
    # the blur moves light, it does not make any: the total is the pinhole's (same camera
    # equation) up to the negative ringing clipped to 0 (+0.4 % measured)
    plain = pinhole.radiance_to_irradiance(scene, OpticsParams(f_number=2.0))
    assert e.sum(dtype=np.float64) == pytest.approx(plain.irradiance_photons.sum(dtype=np.float64), rel=0.01)
    # the OTF is cut at Nyquist here (λN < 2 samples), so the sun's ringing zeroes a ring of
    # background samples (2.9 % measured), all around the sun, none at the frame's edge
    assert oi.meta["clipped_fraction"] < 0.05
    zero_i, zero_j = np.nonzero(e[..., 1] == 0)
    assert np.hypot(zero_i - 31, zero_j - 31).max() < 28


def test_airy_cell_kernel_transfer_is_the_diffraction_mtf_times_the_cell():
    """Kernel = Airy integrated over cells: its transfer is OTF(ν)·sinc(νΔ) (fine cells, no alias)."""
    wl, n, dx = 550e-9, 8.0, 550e-9 * 8.0 / 4
    k = diffraction.airy_cell_kernel(wl, n, dx)
    assert k.sum() == pytest.approx(1.0) and k.min() >= 0
    size = 512
    grid = np.zeros((size, size))
    h = k.shape[0] // 2
    grid[:k.shape[0], :k.shape[1]] = k
    grid = np.roll(grid, (-h, -h), axis=(0, 1))
    line = np.real(np.fft.fft2(grid))[0, : size // 2]
    f = np.fft.fftfreq(size, d=dx)[: size // 2]
    expected = diffraction.diffraction_mtf(f, wl, n) * np.sinc(f * dx)
    assert np.max(np.abs(line - expected)) < 0.02
    coarse = diffraction.airy_cell_kernel(wl, 4.0, 30e-6)      # cell ≫ Airy: nearly all in the centre
    assert coarse[coarse.shape[0] // 2, coarse.shape[1] // 2] > 0.97
