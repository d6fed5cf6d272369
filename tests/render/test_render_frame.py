"""A frame of the small demo city (no city-generator dependency) in every representation."""
import numpy as np
import pytest

from workbench.jobs import run_job
from workbench.render.demo_scene import demo_city, demo_pose
from workbench.render.film import box_bands
from workbench.render.params import DaylightParams, RenderParams
from workbench.render.scene_builder import build_scene
from workbench.render.spectral import render_spectral
from workbench.spectra import luminance_from_photons

W, H = 64, 48


def frame(params, **kw):
    return run_job(render_spectral(demo_city(), demo_pose(), params, width=W, height=H, fov_deg=44.0, **kw))


def test_bands_frame_is_finite_daylit_and_upright():
    s = frame(RenderParams(spp=4, band_count=6, wavelength_min_nm=400, wavelength_max_nm=1000))
    assert s.radiance_photons.shape == (H, W, 6) and s.radiance_photons.dtype == np.float32
    assert np.all(np.isfinite(s.radiance_photons)) and s.radiance_photons.min() >= 0
    assert s.radiance_photons[..., -1].mean() > 0                       # NIR band is lit
    assert s.depth_m.shape == (H, W) and np.all(np.isfinite(s.depth_m))
    lum = luminance_from_photons(s.radiance_photons, s.wavelengths_nm)
    assert 100 < np.median(lum) < 20_000                                 # cd/m², daylit street
    # the pedestrian stands at +Y (camera's left), the blue car at −Y (right); ground at the bottom
    ped = np.argwhere(np.abs(s.depth_m - 9.2) < 0.5)
    car = np.argwhere(np.abs(s.depth_m - 12.3) < 0.4)
    assert ped[:, 1].mean() < W / 2 < car[:, 1].mean()
    assert s.depth_m[-1].mean() < s.depth_m[H // 2].mean()


def test_basis_and_sensor_representations():
    b = frame(RenderParams(spp=4, representation="basis", basis_count=5, output_step_nm=20,
                           wavelength_min_nm=400, wavelength_max_nm=900))
    assert np.allclose(b.wavelengths_nm, np.arange(400, 901, 20)) and np.all(np.isfinite(b.radiance_photons))
    wl = np.arange(380.0, 1001.0, 10.0)
    qe = np.stack([np.exp(-((wl - c) / 35) ** 2) for c in (460, 540, 610)])
    s = frame(RenderParams(spp=4, representation="sensor"), sensor_qe=(wl, qe))
    assert s.radiance_photons.shape == (H, W, 3) and s.meta["representation"] == "sensor"
    assert np.allclose(s.meta["channel_centroids_nm"], [460, 540, 610], atol=1)


def test_scalar_variant_renders_the_same_scene():
    s = frame(RenderParams(spp=2, band_count=3, variant="scalar_spectral"))
    assert s.meta["variant"] == "scalar_spectral" and s.depth_m is None
    assert np.all(np.isfinite(s.radiance_photons)) and s.radiance_photons.mean() > 0


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="render resolution"):
        build_scene(demo_city(), demo_pose(), 44.0, 0, 48, box_bands(400, 700, 3), DaylightParams())
    city = demo_city()
    city.objects[1].meshes[0].material = "chrome"
    with pytest.raises(ValueError, match="chrome"):
        build_scene(city, demo_pose(), 44.0, W, H, box_bands(400, 700, 3), DaylightParams())
    with pytest.raises(ValueError, match="film needs"):
        build_scene(demo_city(), demo_pose(), 44.0, W, H, box_bands(300, 700, 3), DaylightParams())


def test_set_camera_pose_matches_a_fresh_build():
    from workbench.render.scene_builder import set_camera_pose
    from workbench.render.spectral import depth_map_m
    from workbench.render.variants import select_variant
    from workbench.scene.city.types import CameraPose

    select_variant("llvm_ad_spectral")
    film, day = box_bands(400, 700, 3), DaylightParams()
    moved = CameraPose(np.array([2.0, 1.0, 1.8]), pan_deg=10.0, tilt_deg=-5.0, roll_deg=3.0)
    scene, _ = build_scene(demo_city(), demo_pose(), 44.0, W, H, film, day)
    before = depth_map_m(scene)
    set_camera_pose(scene, moved)
    fresh, _ = build_scene(demo_city(), moved, 44.0, W, H, film, day)
    assert np.allclose(depth_map_m(scene), depth_map_m(fresh), rtol=1e-5)
    assert not np.allclose(before, depth_map_m(fresh))


def test_a_lens_camera_dict_replaces_the_pinhole():
    import mitsuba as mi

    from workbench.render.scene_builder import pinhole_sensor

    lens = pinhole_sensor(demo_pose(), 44.0) | {"type": "thinlens", "aperture_radius": 0.002,
                                                 "focus_distance": 12.0}
    s = frame(RenderParams(spp=2, band_count=3), lens_sensor=lens)
    assert np.all(np.isfinite(s.radiance_photons)) and s.radiance_photons.mean() > 0
    assert 5 < s.distance_m < 40 and mi.variant() == s.meta["variant"]
