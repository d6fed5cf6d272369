"""The flat field beyond the city (CityRecipe.horizon_field_m): the ground reaches nearly to the
horizon instead of ending in the black below-horizon half of the perez sky.

- Geometry and labels: a level camera at the city's edge looking outward sees the ground on
  exactly the pixels whose centre ray meets the plane z = 0 inside the field (an independent
  numpy ray-plane intersection), at the depth h / sin(−elevation); without the field those rows
  are background.
- Radiance: far from the city the field is a Lambertian plane under the sun and the perez sky,
  whose horizontal irradiance is SPCTRAL2's diffuse E_d by construction, so it reads
  ρ(λ) (E_sun sin θ_sun / π + E_d / π) (test_render_calibration's closed form) within 2 %.
- Off (0, the default) the city is the one it was, array for array; on, its extent grows by it.
"""
import numpy as np

from workbench.jobs import run_job
from workbench.render.daylight import DAYLIGHT_WAVELENGTHS_NM, sky_radiance, sun_irradiance
from workbench.render.film import box_bands
from workbench.render.labels import render_labels
from workbench.render.params import DaylightParams, RenderParams
from workbench.render.scene_builder import build_scene
from workbench.render.spectral import render_loaded
from workbench.scene.city import CameraPose, CityRecipe, generate_city

from render_helpers import band_mean_photons, check, north_rays

W, H, FOV_DEG, CAM_Z = 64, 48, 12.0, 1.5
FIELD_M = 2000.0


def _city(field_m: float):
    return generate_city(CityRecipe(seed=3, blocks_x=1, blocks_y=1, n_cars=0, n_pedestrians=0, n_buses=0,
                                    n_trucks=0, n_trees=0, n_lamps=0, n_benches=0, n_mailboxes=0,
                                    building_height_min_m=3.0, building_height_max_m=3.0,
                                    horizon_field_m=field_m))


def _pose(city):
    """5 m inside the north edge of the grass margin, 1.5 m up, looking north (+y), level."""
    margin_edge_y = city.extent_m[3] - city.meta["recipe"]["horizon_field_m"]
    x = 0.5 * (city.extent_m[0] + city.extent_m[2])
    return CameraPose(np.array([x, margin_edge_y - 5.0, CAM_Z]), pan_deg=90.0, tilt_deg=0.0, roll_deg=0.0)


def test_off_by_default_and_the_extent_grows_by_the_field():
    assert CityRecipe().horizon_field_m == 0.0
    off, on = _city(0.0), _city(FIELD_M)
    assert np.allclose(np.subtract(on.extent_m, off.extent_m), [-FIELD_M, -FIELD_M, FIELD_M, FIELD_M])
    assert [o.instance_id for o in on.objects] == [o.instance_id for o in off.objects]
    ground_off = next(o for o in off.objects if o.meta.get("part") == "margin")
    ground_on = next(o for o in on.objects if o.meta.get("part") == "margin")
    assert len(ground_off.meshes) == 1 and len(ground_on.meshes) == 2
    assert np.array_equal(ground_on.meshes[0].vertices, ground_off.meshes[0].vertices)
    far = ground_on.meshes[1].vertices
    assert far[:, 0].min() == on.extent_m[0] and far[:, 1].max() == on.extent_m[3] and not far[:, 2].any()


def test_the_field_is_labelled_ground_to_its_edge(mi):
    film = box_bands(400.0, 700.0, 2)
    d = north_rays(W, H, FOV_DEG)
    for field_m in (0.0, FIELD_M):
        city = _city(field_m)
        pose = _pose(city)
        scene, ids = build_scene(city, pose, FOV_DEG, W, H, film, DaylightParams(sky_model="perez"))
        labels = render_labels(scene, ids, W, H)
        ground_id = next(o.instance_id for o in city.objects if o.meta.get("part") == "margin")
        with np.errstate(divide="ignore"):
            t = np.where(d[..., 2] < 0, -CAM_Z / d[..., 2], np.inf)
        hit_y = pose.position_m[1] + t * d[..., 1]
        oracle = np.isfinite(t) & (hit_y <= city.extent_m[3])
        got = labels.instance_id == ground_id
        assert (got != oracle).mean() < 0.01, (field_m, (got != oracle).sum())
        if field_m == 0.0:
            assert not got.any()                      # the margin is behind the bottom of the view
        else:
            assert got.sum() > 0.4 * W * H
            np.testing.assert_allclose(labels.depth_m[got], t[got], rtol=2e-3)


def test_far_field_radiance_is_the_lambertian_closed_form(mi):
    """Sun ahead of the camera (the buildings' shadows fall back toward the city)."""
    elevation = 35.0
    day = DaylightParams(sky_model="perez", sun_elevation_deg=elevation, sun_azimuth_deg=0.0, turbidity=3.0)
    film = box_bands(420.0, 980.0, 4)
    city = _city(FIELD_M)
    scene, _ = build_scene(city, _pose(city), FOV_DEG, W, H, film, day, max_depth=3)
    out = run_job(render_loaded(scene, film, RenderParams(spp=256, chunk_spp=128, seed=5), fov_deg=FOV_DEG))
    grass = city.materials["grass"]
    wl = DAYLIGHT_WAVELENGTHS_NM
    rho = np.interp(wl, grass.wavelengths_nm, grass.reflectance)
    irradiance = sun_irradiance(wl, elevation, 3.0) * np.sin(np.radians(elevation)) / np.pi
    expected = band_mean_photons(wl, rho * (irradiance + sky_radiance(wl, elevation, 3.0)), film)
    check(out.radiance_photons[H // 2 + 2:], expected, "far field")
