"""PSFs: the FFT kernel against the Airy pattern and the diffraction MTF; real-lens PSFs against
the f-number's Airy zero, the defocus pillbox, and each other."""
import math

import numpy as np
import pytest
from scipy.special import j1

from workbench.optics.lens import (diffraction_mtf, focus, load_lens, mtf_from_psf, paraxial, psf_diffraction,
                                   psf_from_pupil, psf_geometric, sensor_z_mm)
from workbench.optics.lens.paraxial import image_distance_mm


def _perfect_pupil(n, f_number, ref_mm=10.0):
    a = ref_mm / (2 * f_number)
    g = (np.arange(n) + 0.5) / n * 2 * a - a
    uu, vv = np.meshgrid(g, g)
    return (uu ** 2 + vv ** 2 <= a * a).astype(complex), 2 * a / n, np.eye(2) / ref_mm


def _first_zero_um(psf, spacing_um):
    c = psf.shape[0] // 2
    row = psf[c, c:]
    i = next(k for k in range(1, row.size - 1) if row[k] <= row[k - 1] and row[k] <= row[k + 1])
    return i * spacing_um


def test_perfect_pupil_gives_airy_first_zero():
    N, lam, sp = 4.0, 550.0, 0.1
    pupil, du, jac = _perfect_pupil(256, N)
    psf = psf_from_pupil(pupil, du, du, jac, lam, sp, 129)
    assert psf.sum() == pytest.approx(1.0) and np.isfinite(psf).all()
    assert abs(_first_zero_um(psf, sp) - 1.22 * lam * 1e-3 * N) <= sp
    # Profile follows [2 J1(x)/x]² near the core.
    x = np.arange(1, 20) * sp * math.pi / (lam * 1e-3 * N)
    c = 64
    airy = (2 * j1(x) / x) ** 2
    assert np.allclose(psf[c, c + 1:c + 20] / psf[c, c], airy, atol=0.02)


def test_perfect_pupil_mtf_matches_closed_form():
    """On the FFT's own grid the discrete PSF holds all the energy; its MTF is (2/π)(φ − cosφ sinφ)."""
    N, lam, n, n_fft = 4.0, 550.0, 128, 1024
    pupil, du, jac = _perfect_pupil(n, N)
    spacing = lam * 1e-3 * N * n / n_fft * (1 - 1e-12)   # λ/(n_fft·ΔL) in µm
    psf = psf_from_pupil(pupil, du, du, jac, lam, spacing, n_fft, n_fft=n_fft)
    f, m = mtf_from_psf(psf, spacing)
    nu_c = 1 / (lam * 1e-6 * N)
    sel = f <= nu_c
    assert np.max(np.abs(m[sel] - diffraction_mtf(f[sel], lam, N))) < 2e-2 / n * 8  # ~1e-3
    assert np.max(m[f > 1.02 * nu_c]) < 1e-6


def test_stopped_down_lens_is_diffraction_limited():
    lens = load_lens("automotive.2.4mm")
    lens = lens.with_stop_semi_aperture(lens.surfaces[lens.stop_index].semi_aperture_mm / 3)
    N = paraxial(lens).f_number
    lam, sp = 550.0, 0.25
    psf = psf_diffraction(lens, 0.0, lam, math.inf, sp, 65)
    assert abs(_first_zero_um(psf, sp) - 1.22 * lam * 1e-3 * N) <= sp


def test_geometric_defocus_matches_pillbox():
    """Stopped-down double Gauss focused at infinity, point at 1 m: a uniform disc of radius
    (XPD/2)·Δ/L (paraxial exit pupil, Δ = image shift, L = exit pupil → image)."""
    lens = load_lens("dgauss.50mm")
    lens = lens.with_stop_semi_aperture(2.0)
    p = paraxial(lens)
    s_img = image_distance_mm(lens, 1.0)
    delta = s_img - p.bfl_mm
    radius_um = p.exit_pupil_diameter_mm / 2 * delta / (s_img - p.exit_pupil_mm) * 1e3
    sp = 5.0
    psf = psf_geometric(lens, 0.0, 587.56, 1.0, sp, 81)
    yy, xx = (np.mgrid[:81, :81] - 40) * sp
    rms = math.sqrt((psf * (xx ** 2 + yy ** 2)).sum())
    assert rms == pytest.approx(radius_um / math.sqrt(2), rel=0.03)


def test_in_focus_point_at_one_metre_is_sharp():
    lens = focus(load_lens("dgauss.50mm").with_stop_semi_aperture(2.0), 1.0)
    psf = psf_geometric(lens, 0.0, 587.56, 1.0, 5.0, 21)
    assert psf[10, 10] > 0.9


def test_geometric_and_diffraction_agree_when_aberrations_dominate():
    lens = load_lens("dgauss.50mm")
    sp, sz = 2.0, 101
    g = psf_geometric(lens, 14.0, 550.0, math.inf, sp, sz)
    d = psf_diffraction(lens, 14.0, 550.0, math.inf, sp, sz)
    for p in (g, d):
        assert p.sum() == pytest.approx(1.0) and np.isfinite(p).all() and (p >= 0).all()
    yy, xx = (np.mgrid[:sz, :sz] - sz // 2) * sp
    cg, cd = (g * yy).sum(), (d * yy).sum()
    assert abs(cg) > 5 and cd == pytest.approx(cg, abs=1.0)  # coma shifts both the same way
    assert (g * xx).sum() == pytest.approx(0, abs=1e-9) and (d * xx).sum() == pytest.approx(0, abs=1e-6)
    assert np.corrcoef(g.ravel(), d.ravel())[0, 1] > 0.7


def test_psf_bad_grid_and_unreachable_field():
    lens = load_lens("dgauss.50mm")
    with pytest.raises(ValueError, match="grid_spacing_um"):
        psf_geometric(lens, 0.0, 550.0, math.inf, -1.0, 11)
    with pytest.raises(ValueError, match="size"):
        psf_diffraction(lens, 0.0, 550.0, math.inf, 1.0, 1)
    with pytest.raises(ValueError, match="image height 60"):
        psf_geometric(lens, 60.0, 550.0, math.inf, 1.0, 11)


def test_sensor_plane_moves_with_focus():
    lens = load_lens("dgauss.50mm")
    assert sensor_z_mm(focus(lens, 1.0)) > sensor_z_mm(lens)


def test_finite_object_defocus_diffraction_follows_geometry():
    """Point at 1 m, lens focused at infinity (≈8 waves of defocus): the diffraction PSF's spread and
    centroid follow the geometric blur (spherical source wave, reference sphere on the chief ray)."""
    lens = load_lens("dgauss.50mm").with_stop_semi_aperture(2.0)
    sp, n = 5.0, 81
    yy, xx = (np.mgrid[:n, :n] - n // 2) * sp
    for h in (0.0, 8.0):
        g = psf_geometric(lens, h, 587.56, 1.0, sp, n)
        d = psf_diffraction(lens, h, 587.56, 1.0, sp, n)
        rg = math.sqrt((g * (xx ** 2 + yy ** 2)).sum())
        rd = math.sqrt((d * (xx ** 2 + yy ** 2)).sum())
        assert rd == pytest.approx(rg, rel=0.08)
        assert (d * yy).sum() == pytest.approx((g * yy).sum(), abs=0.5)
