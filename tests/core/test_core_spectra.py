"""Spectral foundations against closed forms and colour-science."""
import colour
import numpy as np
import pytest

from workbench import spectra, units


def test_photon_energy_closed_form():
    e = units.photon_energy_J(np.array([500.0]))
    assert e[0] == pytest.approx(6.62607015e-34 * 2.99792458e8 / 500e-9, rel=1e-12)
    spd = np.array([[1.0, 2.0, 3.0]])
    wl = np.array([450.0, 550.0, 650.0])
    np.testing.assert_allclose(units.photons_to_energy(units.energy_to_photons(spd, wl), wl), spd, rtol=1e-12)


def test_band_widths_uniform_and_irregular():
    np.testing.assert_allclose(units.band_widths_nm(np.arange(400, 701, 10.0)), 10.0)
    np.testing.assert_allclose(units.band_widths_nm(np.array([400.0, 410.0, 430.0])), [10.0, 15.0, 20.0])
    assert units.band_widths_nm(np.array([550.0]))[0] == 1.0


def test_equal_energy_100_cd_m2_photon_count():
    # ISETCam-derived anchor: equal-energy 100 cd/m² ≈ 3.795e15 photons/s/sr/m²/nm (mean over 400–700).
    wl = spectra.DEFAULT_WAVELENGTHS_NM
    photons = spectra.spd_photons_for_luminance(np.ones_like(wl), wl, 100.0)
    assert photons.mean() == pytest.approx(3.795e15, rel=0.01)
    assert float(spectra.luminance_from_photons(photons, wl)) == pytest.approx(100.0, rel=1e-9)


def test_luminance_matches_colour_science():
    wl = np.arange(360.0, 831.0, 1.0)
    spd = spectra.illuminant_spd("A", wl)
    ours = float(spectra.luminance_from_photons(units.energy_to_photons(spd, wl), wl))
    sd = colour.SpectralDistribution(dict(zip(wl, spd)))
    ref = colour.colorimetry.luminous_flux(sd)          # 683 ∫ S V dλ
    assert ours == pytest.approx(ref, rel=2e-3)


@pytest.mark.parametrize("name,xy", [("D65", (0.31271, 0.32902)), ("A", (0.44757, 0.40745))])
def test_illuminant_chromaticity(name, xy):
    wl = np.arange(380.0, 781.0, 5.0)
    xyz = spectra.xyz_from_photons(units.energy_to_photons(spectra.illuminant_spd(name, wl), wl), wl)
    np.testing.assert_allclose(xyz[:2] / xyz.sum(), xy, atol=1e-3)


def test_daylight_and_blackbody():
    wl = np.arange(400.0, 701.0, 10.0)
    d65 = spectra.illuminant_spd("D65", wl)
    d6504 = spectra.illuminant_spd("daylight:6504", wl)
    np.testing.assert_allclose(d6504 / d6504[15], d65 / d65[15], rtol=0.01)
    bb = spectra.blackbody_spd(5000.0, np.array([500.0]))
    lam = 500e-9
    planck = 2 * 6.62607015e-34 * 2.99792458e8**2 / lam**5 / np.expm1(
        6.62607015e-34 * 2.99792458e8 / (lam * 1.380649e-23 * 5000.0)) * 1e-9
    assert bb[0] == pytest.approx(planck, rel=2e-4)   # colour uses c2 = 1.4388e-2 (ITS-90)
    with pytest.raises(ValueError, match="4000–25000"):
        spectra.illuminant_spd("daylight:2000", wl)
    with pytest.raises(ValueError, match="allowed"):
        spectra.illuminant_spd("D66", wl)


def test_macbeth_reflectances_any_grid():
    for wl in (spectra.DEFAULT_WAVELENGTHS_NM, np.arange(380.0, 1001.0, 20.0), np.array([550.0])):
        refl = spectra.macbeth_reflectances(wl)
        assert refl.shape == (24, wl.size)
        assert np.all((refl > 0) & (refl < 1))
    names = spectra.macbeth_names()
    assert len(names) == 24 and names[0] == "dark skin" and names[-1] == "black 2 (1.5 D)"


def test_wavelength_grid_validation():
    np.testing.assert_allclose(spectra.wavelength_grid(400, 700, 10), spectra.DEFAULT_WAVELENGTHS_NM)
    with pytest.raises(ValueError):
        spectra.wavelength_grid(700, 400, 10)
    with pytest.raises(ValueError):
        spectra.wavelength_grid(100, 400, 10)
