"""Units and closed forms of the render's pieces: film SRFs, photon calibration, daylight, spp."""
import numpy as np
import pytest
from pydantic import ValidationError

from workbench.render.daylight import (air_mass, extraterrestrial_irradiance, sky_radiance, sun_angles,
                                       sun_direction, sun_irradiance)
from workbench.render.film import box_bands, raised_cosine_basis, sensor_channels, sensor_wavelength_range
from workbench.render.params import DaylightParams, RenderParams
from workbench.render.sampling import noise_constant, spp_for_error, spp_for_shot_noise
from workbench.render.solar import solar_position
from workbench.units import photon_energy_J


def test_box_bands_partition_and_widths():
    f = box_bands(400, 700, 30)
    assert np.allclose(f.integrals_nm, 10.0)
    inside = (f.wavelengths_nm > 400.05) & (f.wavelengths_nm < 699.95)
    assert np.allclose(f.responses.sum(axis=0)[inside], 1.0)
    assert np.allclose(f.output_wavelengths_nm, np.arange(405, 700, 10))


def test_channels_to_radiance_is_band_mean_photons():
    """Channel = ∫ L_E s λ/λ_c dλ (what specfilm returns for our tilted SRFs) → band-mean photons."""
    f = box_bands(500, 900, 4)
    wl = np.arange(499.0, 901.0, 0.01)
    L_E = 0.1 + 1e-4 * np.abs(wl - 500) ** 1.5                            # W/m²/sr/nm
    s = np.stack([np.interp(wl, f.wavelengths_nm, r) for r in f.responses])
    ch = np.trapezoid(L_E * s * wl / f.centroids_nm[:, None], wl, axis=1)
    truth = np.trapezoid(L_E / photon_energy_J(wl) * s, wl, axis=1) / np.trapezoid(s, wl, axis=1)
    assert np.allclose(f.channels_to_radiance(ch[None, None]), truth, rtol=1e-6)


def test_basis_reconstructs_constant_exactly_and_smooth_spectra_closely():
    f = raised_cosine_basis(400, 1000, 12, output_step_nm=10)
    wl = f.wavelengths_nm
    for P, tol in ((np.full_like(wl, 3e16), 1e-9), (3e16 * (1 + 0.5 * np.exp(-((wl - 650) / 120) ** 2)), 0.025)):
        b = np.trapezoid(f.responses * P, wl, axis=1)                 # ∫ L_photons φ_k dλ
        ch = b * photon_energy_J(f.centroids_nm)                       # what the film reports
        rec = f.channels_to_radiance(ch[None, None])[0, 0]
        assert np.allclose(rec, np.interp(f.output_wavelengths_nm, wl, P), rtol=tol)


def test_sensor_channels_and_range():
    wl = np.arange(350.0, 1001.0, 5.0)
    qe = np.stack([np.exp(-((wl - c) / 40) ** 2) for c in (460, 540, 610, 850)])
    f = sensor_channels(wl, qe, names=["b", "g", "r", "nir"])
    assert np.allclose(f.output_wavelengths_nm, [460, 540, 610, 850], atol=0.5)
    assert np.allclose(f.integrals_nm, 40 * np.sqrt(np.pi), rtol=1e-3)
    lo, hi = sensor_wavelength_range(wl, qe, 0.01)
    assert 370 <= lo <= 380 and 930 <= hi <= 940
    with pytest.raises(ValueError, match="≥ 0"):
        sensor_channels(wl, -qe)


def test_sun_and_sky_magnitudes_and_colour():
    wide = np.geomspace(100.0, 1e6, 200_000)
    assert np.trapezoid(extraterrestrial_irradiance(wide), wide) == pytest.approx(1361, rel=1e-3)
    wl = np.arange(300.0, 4001.0, 1.0)
    assert air_mass(0.0) == pytest.approx(1.0, abs=1e-3) and air_mass(60.0) == pytest.approx(2.0, rel=0.01)
    noon = np.trapezoid(sun_irradiance(wl, 70.0, 3.0), wl)
    assert 750 < noon < 1050                                           # W/m², direct normal
    wl2 = np.array([450.0, 550.0, 850.0])
    ratio = sky_radiance(wl2, 50.0, 3.0) / sun_irradiance(wl2, 50.0, 3.0)
    assert ratio[0] > ratio[1] > ratio[2]                              # the sky is bluer than the sun
    assert np.all(sky_radiance(np.array([900.0, 1000.0]), 50.0, 3.0) > 0)   # NIR is lit
    # zenith sun, almost no aerosol: T(550 nm) = exp(−τ_R) with τ_R(550) ≈ 0.097 (Bodhaine 1999)
    t550 = sun_irradiance(np.array([550.0]), 90.0, 1.0) / extraterrestrial_irradiance(np.array([550.0]))
    assert t550[0] == pytest.approx(np.exp(-0.097 - 0.0002 * 0.55 ** -1.3), rel=3e-3)
    hazy = np.trapezoid(sun_irradiance(wl, 70.0, 8.0), wl)
    assert hazy < noon


def test_solar_position_closed_forms():
    el, az = solar_position(12.0, 40.0, 80)                            # ≈ equinox, solar noon
    assert el == pytest.approx(50.0, abs=0.6) and az == pytest.approx(180.0, abs=1e-6)
    el_m, az_m = solar_position(9.0, 40.0, 172)
    el_a, az_a = solar_position(15.0, 40.0, 172)
    assert el_m == pytest.approx(el_a) and az_m < 180 < az_a and az_m + az_a == pytest.approx(360)
    assert np.allclose(sun_direction(90.0, 0.0), [0, 0, 1], atol=1e-12)
    assert np.allclose(sun_direction(0.0, 90.0), [1, 0, 0], atol=1e-12)   # azimuth 90° = east = +X
    with pytest.raises(ValueError, match="time_of_day_h.*sun above the horizon"):    # refused when set
        DaylightParams(time_of_day_h=23.0)
    with pytest.raises(ValueError, match="time_of_day_h=23"):                         # and when rendered
        sun_angles(DaylightParams.model_construct(**{**DaylightParams().model_dump(), "time_of_day_h": 23.0}))


def test_spp_rules():
    assert spp_for_error(0.76, 0.05) == 232                            # research note: ≈ 229
    assert spp_for_error(0.0, 0.1) == 1 and spp_for_error(10.0, 1e-3, max_spp=100) == 100
    assert spp_for_shot_noise(0.76, 10_000, 0.3) == spp_for_error(0.76, 0.003)
    rng = np.random.default_rng(0)
    truth = rng.uniform(1, 2, (40, 50, 3))
    spp, c = 16, 0.8
    noisy = [truth * (1 + c / np.sqrt(spp) * rng.standard_normal(truth.shape)) for _ in range(2)]
    assert noise_constant(*noisy, spp, "per_channel") == pytest.approx(c * np.sqrt(np.mean(truth ** 2)) / truth.mean(), rel=0.05)


def test_params_refuse_bad_values():
    with pytest.raises(ValidationError, match="exactly one of spp"):
        RenderParams(spp=16, target_rel_error=0.05)
    with pytest.raises(ValidationError, match="band_count"):
        RenderParams(band_count=0)
    with pytest.raises(ValidationError, match="wavelength_max_nm"):
        RenderParams(wavelength_min_nm=700, wavelength_max_nm=500)
    with pytest.raises(ValidationError, match="sun_elevation_deg"):
        DaylightParams(sun_elevation_deg=-5)
