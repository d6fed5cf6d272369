"""Radiometric oracle: a Lambertian plane of known reflectance under known light.

Closed forms: under a constant environment L the sky pixels read L and the plane ρL; under a
directional sun of normal irradiance E at elevation θ the plane reads ρ E sinθ / π; under a
uniform sky alone, ρ L_sky. All as band-mean photon radiance ∫L λ/(hc) s dλ / ∫s.
Tolerance: 5 standard errors of the image mean, from the measured per-pixel std (the Monte
Carlo error of the mean), plus 0.3 % for float32 accumulation and the 0.1-nm band-edge ramps."""
import numpy as np
import pytest

from workbench.jobs import run_job
from workbench.render.daylight import sky_radiance, sun_irradiance
from workbench.render.film import box_bands
from workbench.render.params import DaylightParams, RenderParams
from workbench.render.scene_builder import build_scene
from workbench.render.spectral import render_loaded
from workbench.scene.city.types import CameraPose

from render_helpers import RHO, band_mean_photons, check, flat_city

W, H = 64, 48


def test_constant_environment(mi):
    """Plane in the lower half of the view, sky in the upper: sky = L, plane = ρL."""
    film = box_bands(400, 1000, 6)
    wl = np.linspace(350, 1000, 27)
    L = 0.05 + 0.04 * np.sin(wl / 40.0)                     # structured spectrum, W/m²/sr/nm
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": 4},
             "sensor": {"type": "perspective", "fov": 40, "fov_axis": "x",
                        "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 1], target=[1, 0, 1], up=[0, 0, 1]),
                        "film": film.mitsuba_film(W, H), "sampler": {"type": "independent"}},
             "env": {"type": "constant", "radiance": {"type": "spectrum", "value": list(zip(wl, L))}},
             "ground": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(1e4),
                        "bsdf": {"type": "diffuse", "reflectance": {"type": "spectrum", "value": RHO}}}}
    out = run_job(render_loaded(mi.load_dict(scene), film, RenderParams(spp=192, chunk_spp=96, seed=3), fov_deg=40))
    expected = band_mean_photons(wl, L, film)
    rad = out.radiance_photons
    check(rad[: H // 2 - 2], expected, "sky")
    check(rad[H // 2 + 2:], RHO * expected, "ground")
    assert out.depth_m[0, 0] == pytest.approx(1.0e4)          # sky depth is the finite background


@pytest.mark.parametrize("elevation_deg", [60.0, 25.0])
def test_sun_only(mi, elevation_deg):
    """Directional daylight sun of known irradiance: plane radiance = ρ E sin(elevation) / π."""
    film = box_bands(400, 1000, 8)
    day = DaylightParams(sun_elevation_deg=elevation_deg, sun_azimuth_deg=200.0, sky_scale=0.0, turbidity=2.5)
    pose = CameraPose(np.array([0.0, 0.0, 2.0]), pan_deg=30.0, tilt_deg=-90.0, roll_deg=0.0)
    mi_scene, ids = build_scene(flat_city(), pose, 30.0, W, H, film, day, max_depth=3)
    out = run_job(render_loaded(mi_scene, film, RenderParams(spp=64, chunk_spp=64, seed=1), fov_deg=30.0))
    from workbench.render.daylight import DAYLIGHT_WAVELENGTHS_NM as wl
    E = sun_irradiance(wl, elevation_deg, 2.5)
    expected = band_mean_photons(wl, RHO * E * np.sin(np.radians(elevation_deg)) / np.pi, film)
    check(out.radiance_photons, expected, "sun-lit plane")
    # noise model (research/mitsuba.md §1): 4 wavelengths per sample → rel. std √((N/4 − 1)/spp)
    rel_std = out.radiance_photons.reshape(-1, 8).std(axis=0) / expected
    assert np.allclose(rel_std, np.sqrt((8 / 4 - 1) / 64), rtol=0.15)
    assert ids == {"ground_1_0": ids["ground_1_0"]} and ids["ground_1_0"].instance_id == 1
    assert out.depth_m[H // 2, W // 2] == pytest.approx(2.0, rel=1e-3)


def test_sky_only(mi):
    """Uniform daylight sky alone over an (effectively) infinite plane: radiance = ρ L_sky."""
    film = box_bands(400, 1000, 4)
    day = DaylightParams(sun_elevation_deg=40.0, sun_scale=0.0, turbidity=4.0)
    pose = CameraPose(np.array([0.0, 0.0, 1.0]), pan_deg=0.0, tilt_deg=-90.0, roll_deg=0.0)
    mi_scene, _ = build_scene(flat_city(1.0e5), pose, 20.0, W, H, film, day, max_depth=3)
    out = run_job(render_loaded(mi_scene, film, RenderParams(spp=16, chunk_spp=16, seed=2), fov_deg=20.0))
    from workbench.render.daylight import DAYLIGHT_WAVELENGTHS_NM as wl
    expected = band_mean_photons(wl, RHO * sky_radiance(wl, 40.0, 4.0), film)
    check(out.radiance_photons, expected, "sky-lit plane")
