"""Irradiance → mean electrons: the camera equation for a pixel, spectral QE data, regridding."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.optics.types import OpticalImage
from workbench.resource_dir import RESOURCES
from workbench.sensor import (channel_qe, irradiance_to_sensor_image, irradiance_to_signal_rate,
                              signal_rate_to_sensor_image)
from workbench.sensor.cfa import cfa_layout
from workbench.sensor.signal import resample_matrix

from sensor_helpers import WL16, make_params, uniform_oi


def _csv(name):
    path = RESOURCES / "sensors" / name
    header = path.read_text().splitlines()[0].split(",")
    return np.loadtxt(path, delimiter=",", skiprows=1), header


def _qe_by_hand(channel: str, wl: np.ndarray) -> np.ndarray:
    filters, names = _csv("bayer_dye_filters.csv")
    si, _ = _csv("silicon_photodiode_qe.csv")
    ir, _ = _csv("ir_cut_650.csv")
    f = np.interp(wl, filters[:, 0], filters[:, names.index(channel)])
    return f * np.interp(wl, si[:, 0], si[:, 1]) * np.interp(wl, ir[:, 0], ir[:, 1])


def test_mean_electrons_equal_the_camera_equation():
    """mean e⁻ = t · A · FF · Σ E(λ) QE_k(λ) Δλ, per CFA channel (noise off, analog read-out)."""
    p = make_params(rows=6, cols=8, noise_flag=-1, bit_depth=0, cfa_pattern="RGGB", fill_factor=0.6)
    e = 1e15 * (1 + 0.5 * np.sin(WL16 / 40.0))                      # photons/s/m²/nm
    t = 0.004
    img = signal_rate_to_sensor_image(irradiance_to_signal_rate(uniform_oi(p, e, WL16), p), p, t)
    dl = WL16[1] - WL16[0]
    area = (3e-6) ** 2
    for ch, (r, c) in {"R": (0, 0), "G": (0, 1), "B": (1, 1)}.items():
        expected = t * area * 0.6 * np.sum(e * _qe_by_hand(ch, WL16)) * dl
        assert img.electrons[r, c] == pytest.approx(expected, rel=1e-5)
        assert img.volts[r, c] == pytest.approx(expected * 1e-4, rel=1e-5)
    assert img.electrons[2, 3] == img.electrons[0, 1]                # G again, one tile over


def test_photodiode_and_filter_data_are_plausible():
    wl = np.arange(350.0, 1101.0, 5.0)
    qe = _csv("silicon_photodiode_qe.csv")[0][:, 1]
    peak = wl[np.argmax(qe)]
    assert 0.6 <= qe.max() <= 0.7 and 480 <= peak <= 620
    assert qe[wl == 1100][0] < 0.005 and qe[wl == 850][0] > 0.1
    ir = _csv("ir_cut_650.csv")[0][:, 1]
    assert ir[wl == 600][0] > 0.9 and ir[wl == 650][0] > 0.9 and ir[wl == 700][0] < 0.01
    filters, names = _csv("bayer_dye_filters.csv")
    assert np.all((filters[:, 1:] >= 0) & (filters[:, 1:] <= 1))
    visible = (wl >= 380) & (wl <= 700)
    for ch, lo, hi in (("B", 430, 480), ("G", 510, 560), ("R", 600, 700)):
        assert lo <= wl[visible][np.argmax(filters[visible, names.index(ch)])] <= hi
    assert filters[wl == 900, names.index("B")][0] > 0.5              # dye filters leak in the NIR


def test_resource_csvs_are_what_the_script_makes(tmp_path, monkeypatch):
    import importlib.util
    spec = importlib.util.spec_from_file_location("make", RESOURCES / "sensors" / "make_sensor_spectra.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    monkeypatch.setattr(mod, "HERE", tmp_path)
    mod.main()
    for f in tmp_path.glob("*.csv"):
        assert f.read_text() == (RESOURCES / "sensors" / f.name).read_text()


def test_channel_qe_zero_outside_data_and_ir_cut_switch():
    wl = np.array([300.0, 550.0, 850.0, 1200.0])
    with_cut = channel_qe(make_params(cfa_pattern="RCCC"), wl)
    no_cut = channel_qe(make_params(cfa_pattern="RCCC", ir_cut_file=None), wl)
    assert with_cut.shape == (4, 2)
    assert np.all(with_cut[[0, 3]] == 0) and np.all(no_cut[[0, 3]] == 0)
    assert with_cut[2].max() < 1e-4 and no_cut[2].min() > 0.1        # NIR only without the IR cut
    mono = channel_qe(make_params(cfa_pattern="MONO", photodiode_qe_file=None, ir_cut_file=None), wl)
    assert np.all(mono[[1, 2]] == 1.0)


@pytest.mark.parametrize("method", ["area", "isetcam"])
@pytest.mark.parametrize("spacing_um", [0.7, 1.5, 3.0, 4.2, 9.0])
def test_uniform_irradiance_gives_the_same_rate_on_any_grid(method, spacing_um):
    p = make_params(rows=10, cols=12, cfa_pattern="MONO")
    ref = irradiance_to_signal_rate(uniform_oi(p, 1e15, WL16), p)
    # an OI twice as large as the sensor so that every pixel is covered
    n = int(np.ceil(2 * 12 * 3.0 / spacing_um)) + 3
    got = irradiance_to_signal_rate(uniform_oi(p, 1e15, WL16, spacing_um * 1e-6, (n, n)), p, method=method)
    np.testing.assert_allclose(got, ref, rtol=1e-5)


def test_area_resampling_conserves_flux_and_zero_outside():
    m = resample_matrix(7, 1.3, 20, 0.9, "area").toarray()
    src = np.random.default_rng(0).random(7)
    # total flux: Σ dst·pitch = Σ src·spacing over the overlap (the sensor is wider than the OI)
    assert (m @ src).sum() * 0.9 == pytest.approx(src.sum() * 1.3, rel=1e-5)
    assert np.all(m[:2] == 0) and np.all(m[-2:] == 0)


def test_crop_fast_path_equals_general_path():
    p = make_params(rows=6, cols=8, cfa_pattern="RGGB")
    rng = np.random.default_rng(3)
    e = rng.random((10, 12, WL16.size), dtype=np.float32) * 1e15
    oi = OpticalImage(e, WL16, 3e-6, 4e-3, 4.0)
    fast = irradiance_to_signal_rate(oi, p)
    general = irradiance_to_signal_rate(OpticalImage(e, WL16, 3e-6 * (1 + 1e-5), 4e-3, 4.0), p)
    np.testing.assert_allclose(fast, general, rtol=2e-4)
    manual = (e[2:8, 2:10] @ np.asarray(channel_qe(p, WL16), dtype=np.float32))
    assert fast[0, 0] == pytest.approx(manual[0, 0, 0] * 9e-12 * 0.75 * 20, rel=1e-5)


@pytest.mark.parametrize("pattern", ["GRBG", "RGBW", "RCCC", "MONO"])
def test_crop_fast_path_equals_the_camera_equation_in_float64(pattern):
    """Every pixel of a 300×300 frame (row blocks in threads) against Σ_λ E·A·FF·QE·Δλ in
    float64 numpy, its channel read from the CFA tile; slightly negative irradiance (FFT optics)
    gives 0."""
    p = make_params(rows=300, cols=300, cfa_pattern=pattern)
    rng = np.random.default_rng(5)
    e = rng.random((304, 306, WL16.size), dtype=np.float32) * 1e15
    e[10:20, 10:20] = -1e9
    rate = irradiance_to_signal_rate(OpticalImage(e, WL16, 3e-6, 4e-3, 4.0), p)
    per_channel = e[2:302, 3:303].astype(np.float64) @ (channel_qe(p, WL16) * 20.0 * 9e-12 * 0.75)
    tile, _ = cfa_layout(pattern)
    channel = np.tile(tile, (150, 150))
    expected = np.maximum(np.take_along_axis(per_channel, channel[..., None], axis=2)[..., 0], 0.0)
    np.testing.assert_allclose(rate, expected, rtol=1e-5, atol=1e-6 * expected.max())
    assert rate[8:18, 7:17].max() == 0.0


def test_sensor_outside_the_optical_image_is_dark():
    p = make_params(rows=8, cols=8, cfa_pattern="MONO")
    rate = irradiance_to_signal_rate(uniform_oi(p, 1e15, WL16, shape=(4, 4)), p)
    assert rate[2:6, 2:6].min() > 0 and rate[:2].max() == 0 and rate[:, 6:].max() == 0


def test_nan_or_inf_irradiance_is_refused():
    p = make_params(rows=4, cols=4)
    oi = uniform_oi(p, 1e15, WL16)
    oi.irradiance_photons[1, 1, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        irradiance_to_sensor_image(oi, p)
    oi.irradiance_photons[1, 1, 3] = np.inf
    with pytest.raises(ValueError, match="Inf"):
        irradiance_to_signal_rate(oi, p)
    with pytest.raises(ValueError, match="H×W×Nλ"):
        irradiance_to_signal_rate(OpticalImage(np.ones((4, 4), np.float32), WL16, 3e-6, 4e-3, 4.0), p)


def test_point_of_light_lands_in_the_central_pixel():
    """OI and sensor are both centred: a 1 µm spot at the centre falls in the middle 3 µm pixel,
    which averages it over its 9 µm² (area method)."""
    p = make_params(rows=3, cols=3, cfa_pattern="MONO", photodiode_qe_file=None, ir_cut_file=None,
                    fill_factor=1.0)
    e = np.zeros((9, 9, 1), np.float32)
    e[4, 4, 0] = 9e15
    rate = irradiance_to_signal_rate(OpticalImage(e, np.array([550.0]), 1e-6, 4e-3, 4.0), p)
    assert rate[1, 1] == pytest.approx(1e15 * 9e-12, rel=1e-5)
    assert rate.sum() == pytest.approx(rate[1, 1])


@settings(max_examples=40, deadline=None)
@given(n_src=st.integers(1, 40), s=st.floats(0.2, 5.0), n_dst=st.integers(1, 40), pitch=st.floats(0.2, 5.0))
def test_area_matrix_conserves_covered_flux(n_src, s, n_dst, pitch):
    """Σ over pixels of (value × pitch) equals the OI flux inside the pixel array's extent."""
    m = resample_matrix(n_src, s, n_dst, pitch, "area")
    covered = min(n_src * s, n_dst * pitch)                          # both centred
    assert m.sum() * pitch == pytest.approx(covered, rel=1e-4)
    assert m.min() >= 0


def test_isetcam_default_pixel_counts_the_documented_electrons():
    """ISETCam anchor (research note §8): equal-energy 100 cd/m² at f/4 → 1.834e14 photons/s/m²/nm,
    and the default pixel (QE 1, FF 0.75, 2.8 µm) collects 3.34e5 e⁻/s."""
    from workbench.spectra import spd_photons_for_luminance
    wl = np.arange(400.0, 701.0, 10.0)
    radiance = spd_photons_for_luminance(np.ones(wl.size), wl, 100.0)
    assert radiance.mean() == pytest.approx(3.795e15, rel=2e-3)
    irradiance = np.pi * radiance / (1 + 4 * 4.0 ** 2)               # ISETCam's f/4, m = 0 form
    assert irradiance.mean() == pytest.approx(1.834e14, rel=2e-3)
    p = make_params("isetcam_default", rows=4, cols=4, cfa_pattern="MONO", filter_file=None, ir_cut_file=None)
    rate = irradiance_to_signal_rate(uniform_oi(p, irradiance, wl), p)
    np.testing.assert_allclose(rate, 3.34e5, rtol=3e-3)


@pytest.mark.parametrize("method", ["area", "isetcam"])
@pytest.mark.parametrize("spacing_um", [0.75, 1.0, 2.2])
def test_linear_ramp_is_sampled_at_the_pixel_centres(method, spacing_um):
    """Box averaging and symmetric blur + bilinear interpolation both return a linear ramp's value
    at each pixel centre: checks the centring of both grids (interior pixels)."""
    p = make_params(rows=6, cols=10, cfa_pattern="MONO", photodiode_qe_file=None, ir_cut_file=None,
                    fill_factor=1.0)
    n = int(round(60.0 / spacing_um))                                 # OI 60 µm wide, sensor 30 µm
    x_um = (np.arange(n) - (n - 1) / 2) * spacing_um
    e = np.broadcast_to((1e15 * (1 + x_um / 100.0)).astype(np.float32)[None, :, None], (n, n, 1)).copy()
    rate = irradiance_to_signal_rate(OpticalImage(e, np.array([550.0]), spacing_um * 1e-6, 4e-3, 4.0), p, method)
    centres_um = (np.arange(10) - 4.5) * 3.0
    expected = 1e15 * (1 + centres_um / 100.0) * 9e-12
    # 'area' reads the OI as a staircase (each sample constant over its width): exact when the
    # pitch is a whole number of samples, else off by at most slope × spacing / 4
    exact = method == "isetcam" or float(3.0 / spacing_um).is_integer()
    atol = 0.0 if exact else 1e15 / 100.0 * 9e-12 * spacing_um / 4
    np.testing.assert_allclose(rate[2, 1:-1], expected[1:-1], rtol=1e-4, atol=atol)


@pytest.mark.parametrize("method", ["area", "isetcam"])
def test_regrid_of_a_vanishing_optical_image_is_bounded(method):
    """A field of view of 1e-9° makes the optical samples ~10¹⁰ times finer than a pixel: the
    regrid matrix stays as small as the image (it used to loop once per sample in a pixel: a hang)."""
    from workbench.sensor.signal import REGRID_METHODS
    m = REGRID_METHODS.get(method)(6, 1e-16, 10, 3e-6)
    assert m.shape == (10, 6) and m.nnz <= 10 * 7
    assert np.all(np.isfinite(m.toarray()))


@pytest.mark.parametrize("oversample", [1, 2, 3, 4])
def test_a_photodiode_pixel_integrates_over_its_sqrt_fill_factor_square(oversample):
    """A sinusoid of 0.3 cy/px, given as cell averages (what charts and renders store), reaches the
    pixels with the photodiode's |sinc(√FF · f)| (here 0.928 at FF 0.5), in phase, at every scene
    oversample; the microlens pixel keeps the full pitch's sinc(f) (0.858)."""
    from workbench.sensor.params import SensorParams
    f_cy_px, k = 0.3, oversample
    s = 3e-6 / k
    x = (np.arange(64 * k) - (64 * k - 1) / 2) * s
    f = f_cy_px / 3e-6
    cells = 1 + 0.5 * np.sinc(s * f) * np.cos(2 * np.pi * f * x)
    oi = OpticalImage(np.broadcast_to(cells[None, :, None], (16 * k, 64 * k, 1)).astype(np.float32).copy(),
                      np.array([550.0]), s, 1e-3, 4.0)
    xc = (np.arange(64) - 31.5) * 3e-6
    basis = np.c_[np.ones(64), np.cos(2 * np.pi * f * xc), np.sin(2 * np.pi * f * xc)][8:56]
    for aperture, expected in (("photodiode", np.sinc(np.sqrt(0.5) * f_cy_px)), ("microlens", np.sinc(f_cy_px))):
        sp = SensorParams(rows=16, cols=64, fill_factor=0.5, pixel_aperture=aperture, cfa_pattern="MONO",
                          filter_file=None, photodiode_qe_file=None, ir_cut_file=None)
        row = irradiance_to_signal_rate(oi, sp.pixel_response)[8].astype(np.float64)
        mean, cos, sin = np.linalg.lstsq(basis, row[8:56], rcond=None)[0]
        assert cos / mean / 0.5 == pytest.approx(expected, abs=0.002) and abs(sin / mean) < 0.001, aperture
