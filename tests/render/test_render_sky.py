"""Sky models (render/sky.py): the Perez/Preetham luminance distribution against its closed form,
the hemispherical integral against adaptive quadrature (scipy, independent of the module's grid),
and the Mitsuba emitter against the numpy model (sky pixels, and a plane lit by the sky alone)."""
import numpy as np
import pytest
from scipy import integrate

from workbench.jobs import run_job
from workbench.render.daylight import DAYLIGHT_WAVELENGTHS_NM, sky_radiance, sun_direction, sun_irradiance
from workbench.render.film import box_bands
from workbench.render.params import DaylightParams, RenderParams
from workbench.render.scene_builder import build_scene
from workbench.render.sky import (angular_factor, perez_coefficients, preetham_zenith_luminance_cd_m2,
                                  sky_radiance_at, sky_spectrum)
from workbench.render.spectral import render_loaded
from workbench.scene.city.types import CameraPose
from workbench.spectra import luminous_efficiency

from render_helpers import RHO, band_mean_photons, check, flat_city

W, H = 64, 48
CLEAR = DaylightParams(sun_elevation_deg=30.0, sun_azimuth_deg=90.0, sun_scale=0.0, turbidity=3.0,
                       sky_model="perez")


def _dir(zenith_deg, azimuth_deg):
    z, a = np.radians(zenith_deg), np.radians(azimuth_deg)
    return np.array([np.cos(np.pi / 2 - z) * np.sin(a), np.cos(np.pi / 2 - z) * np.cos(a), np.cos(z)])


def luminance(day, d):
    wl = DAYLIGHT_WAVELENGTHS_NM
    return 683.0 * np.trapezoid(sky_radiance_at(day, d, wl) * luminous_efficiency(wl), wl)


def test_perez_luminance_ratios_follow_the_closed_form():
    """Y(θ,γ)/Y_zenith = F(θ,γ)/F(0,θs), F written out by hand for T = 3 (Preetham 1999)."""
    t = 3.0
    a, b, c, d, e = 0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251, \
        0.1206 * t - 2.5771, -0.0670 * t + 0.3703
    F = lambda th, g: (1 + a * np.exp(b / np.cos(th))) * (1 + c * np.exp(d * g) + e * np.cos(g) ** 2)
    theta_s = np.radians(60.0)
    y_zen = luminance(CLEAR, _dir(0, 0))
    for zen, az in ((30, 90), (60, 90), (75, 270), (45, 0), (80, 180)):
        dvec = _dir(zen, az)
        gamma = np.arccos(np.clip(dvec @ sun_direction(30.0, 90.0), -1, 1))
        want = F(np.radians(zen), gamma) / F(0.0, theta_s)
        assert luminance(CLEAR, dvec) / y_zen == pytest.approx(want, rel=1e-9)
    # the circumsolar region is brighter than the anti-solar sky at the same zenith angle
    assert luminance(CLEAR, _dir(60, 90)) > 3 * luminance(CLEAR, _dir(60, 270))
    np.testing.assert_allclose(perez_coefficients(t), [a, b, c, d, e])


def test_hemispherical_integral_is_spctral2_diffuse():
    """∫ g cos θ dω = π (adaptive quadrature), so E_h(λ) = π × sky_spectrum = SPCTRAL2 diffuse."""
    for day in (CLEAR, CLEAR.updated(turbidity=6.0, sun_elevation_deg=8.0),
                CLEAR.updated(sky_model="overcast")):
        f = lambda ph, th: angular_factor(day, _dir(np.degrees(th), np.degrees(ph))[None])[0] * \
            np.cos(th) * np.sin(th)
        val, err = integrate.dblquad(f, 0, np.pi / 2, 0, 2 * np.pi, epsabs=1e-6, epsrel=1e-6)
        assert val == pytest.approx(np.pi, rel=2e-4), day.sky_model
    wl = np.array([450.0, 850.0, 1000.0])
    np.testing.assert_allclose(sky_spectrum(CLEAR, wl), sky_radiance(wl, 30.0, 3.0))
    assert np.all(sky_spectrum(CLEAR, wl) > 0)                      # defined into the NIR
    # overcast: the CIE sky is 3× brighter at the zenith than at the horizon
    ov = CLEAR.updated(sky_model="overcast")
    assert angular_factor(ov, _dir(0, 0)[None])[0] / angular_factor(ov, _dir(89.999, 0)[None])[0] == \
        pytest.approx(3.0, rel=1e-4)
    glob = sun_irradiance(wl, 30.0, 3.0) * 0.5 + np.pi * sky_radiance(wl, 30.0, 3.0)
    np.testing.assert_allclose(np.pi * sky_spectrum(ov, wl), 0.3 * glob)


def test_zenith_luminance_is_near_preetham():
    """Absolute level (SPCTRAL2 diffuse) vs Preetham's fitted zenith luminance: same order (±40 %)."""
    for el, t in ((30.0, 3.0), (60.0, 3.0), (45.0, 5.0)):
        day = CLEAR.updated(sun_elevation_deg=el, turbidity=t)
        ratio = luminance(day, _dir(0, 0)) / preetham_zenith_luminance_cd_m2(t, el)
        assert 0.6 < ratio < 1.4, (el, t, ratio)


@pytest.mark.parametrize("model", ["perez", "overcast"])
def test_mitsuba_sky_pixels_match_the_model(mi, model):
    """Camera rays that escape read the model's radiance in their direction (400–1000 nm bands)."""
    film = box_bands(400, 1000, 3)
    day = CLEAR.updated(sky_model=model)
    pose = CameraPose(np.array([0.0, 0.0, 1.0]), pan_deg=0.0, tilt_deg=40.0, roll_deg=0.0)
    mi_scene, _ = build_scene(flat_city(10.0), pose, 2.0, 8, 6, film, day, max_depth=2)
    out = run_job(render_loaded(mi_scene, film, RenderParams(spp=256, chunk_spp=256, seed=1), fov_deg=2.0))
    wl = DAYLIGHT_WAVELENGTHS_NM
    expected = band_mean_photons(wl, sky_radiance_at(day, pose.forward()[None], wl)[0], film)
    np.testing.assert_allclose(out.radiance_photons.mean(axis=(0, 1)), expected, rtol=0.01)


def test_plane_under_perez_sky_reads_rho_times_diffuse_over_pi(mi):
    """A Lambertian plane under the Perez sky alone: radiance ρ E_d/π, as under the uniform sky."""
    film = box_bands(400, 1000, 4)
    pose = CameraPose(np.array([0.0, 0.0, 1.0]), pan_deg=0.0, tilt_deg=-90.0, roll_deg=0.0)
    mi_scene, _ = build_scene(flat_city(1.0e5), pose, 20.0, W, H, film, CLEAR, max_depth=2)
    out = run_job(render_loaded(mi_scene, film, RenderParams(spp=32, chunk_spp=32, seed=3), fov_deg=20.0))
    wl = DAYLIGHT_WAVELENGTHS_NM
    check(out.radiance_photons, band_mean_photons(wl, RHO * sky_radiance(wl, 30.0, 3.0), film), "perez plane")


@pytest.mark.parametrize("model", ["uniform", "perez"])
def test_negligible_sky_or_sun_is_left_out_not_refused(mi, model):
    """A scale so small (1e-300, 5e-324: valid, ≥ 0) that the spectrum underflows Mitsuba's float32
    sampling tables leaves that light out, as a scale of 0 does (found by the big fuzz run)."""
    from workbench.render.sky import daylight_emitters
    for scales in ({"sky_scale": 1e-300}, {"sky_scale": 5e-324, "sun_scale": 5e-324}):
        day = DaylightParams(sky_model=model, **scales)
        em = daylight_emitters(day)
        assert "sky" not in em and ("sun" in em) == ("sun_scale" not in scales)
        film = box_bands(400.0, 700.0, 2)
        pose = CameraPose(np.array([0.0, 0.0, 2.0]), pan_deg=0.0, tilt_deg=-30.0, roll_deg=0.0)
        scene, _ = build_scene(flat_city(), pose, 30.0, 16, 12, film, day, max_depth=2)
        out = run_job(render_loaded(scene, film, RenderParams(spp=4, chunk_spp=4), fov_deg=30.0))
        assert np.all(np.isfinite(out.radiance_photons))
