"""The visible sun disc: energy, footprint and position against closed forms and Mitsuba's camera;
occlusion; the HDR of a city frame with the sun in view through sensor and ISP."""
from itertools import pairwise

import numpy as np
import pytest

from workbench.render.daylight import sun_direction, sun_irradiance
from workbench.render.film import box_bands
from workbench.render.params import DaylightParams
from workbench.render.sun_disc import (
    SUN_ANGULAR_RADIUS_DEG,
    sun_disc,
    sun_solid_angle_sr,
)
from workbench.scene.city.types import CameraPose, City, CityObject, Material, Mesh
from workbench.units import energy_to_photons

W, H = 64, 48
EL, AZ = 20.0, 200.0
DAYLIGHT = DaylightParams(sun_elevation_deg=EL, sun_azimuth_deg=AZ)
FILM = box_bands(400.0, 700.0, 6)


def pose_at_sun(d_pan=0.0, d_tilt=0.0, roll=0.0, el=EL, az=AZ):
    """A camera at the origin aimed (pan from +X, tilt up) at the sun, offset by d_pan/d_tilt."""
    return CameraPose(np.zeros(3), 90.0 - az + d_pan, el + d_tilt, roll)


def pixel_solid_angles_sr(fov_deg, width, height):
    """Exact solid angle of every pixel of a pinhole image (closed form for a rectangle on the
    unit-distance image plane: Ω = Σ ± atan(xy / √(1 + x² + y²)) over its corners)."""
    tx = np.tan(np.radians(fov_deg) / 2)
    x = np.linspace(-tx, tx, width + 1)
    y = np.linspace(-tx * height / width, tx * height / width, height + 1)
    xx, yy = np.meshgrid(x, y)
    f = np.arctan(xx * yy / np.sqrt(1 + xx ** 2 + yy ** 2))
    return f[1:, 1:] - f[1:, :-1] - f[:-1, 1:] + f[:-1, :-1]


def band_mean_sun_photons(el=EL):
    """E_sun,normal (photons/s/m²/nm) averaged over each of FILM's bands, on a 0.25 nm grid."""
    wl = np.arange(400.0, 700.001, 0.25)
    e = energy_to_photons(sun_irradiance(wl, el, DAYLIGHT.turbidity), wl)
    edges = np.linspace(400.0, 700.0, 7)
    return np.array([np.trapezoid(e[(wl >= a) & (wl <= b)], wl[(wl >= a) & (wl <= b)]) / (b - a)
                     for a, b in pairwise(edges)])


def all_sky():
    return np.ones((H, W), dtype=bool)


@pytest.mark.parametrize("fov_deg, d_pan, d_tilt, roll", [
    (2.0, 0.0, 0.0, 0.0),          # telephoto: the disc spans ~17 px
    (44.0, 0.0, 0.0, 0.0),         # the paper's FOV at 64 px: the disc is smaller than a pixel
    (44.0, 12.0, -8.0, 20.0),      # off axis (cos³ projection) with roll
])
def test_disc_integrates_to_the_direct_normal_irradiance(fov_deg, d_pan, d_tilt, roll):
    disc = sun_disc(FILM, pose_at_sun(d_pan, d_tilt, roll), fov_deg, W, H, DAYLIGHT, sky_mask=all_sky())
    rad = disc.add_to(np.zeros((H, W, 6), np.float32)).astype(np.float64)
    integral = np.einsum("hwk,hw->k", rad, pixel_solid_angles_sr(fov_deg, W, H))
    np.testing.assert_allclose(integral, band_mean_sun_photons(), rtol=0.01)   # measured ≤ 0.14 %


def test_disc_footprint_is_the_solar_diameter_at_a_narrow_fov():
    fov = 2.0
    disc = sun_disc(FILM, pose_at_sun(), fov, W, H, DAYLIGHT, sky_mask=all_sky())
    px_per_rad = W / 2 / np.tan(np.radians(fov) / 2)
    expected_px = 2 * np.tan(np.radians(SUN_ANGULAR_RADIUS_DEG)) * px_per_rad      # ≈ 17.1 px
    cov = disc.coverage
    width_px, height_px = cov[H // 2].sum(), cov[:, W // 2].sum()   # a chord through the centre
    assert abs(width_px - expected_px) <= 1 and abs(height_px - expected_px) <= 1
    assert cov.sum() == pytest.approx(np.pi * expected_px ** 2 / 4, rel=0.01)
    assert cov.max() == pytest.approx(1.0, abs=0.05)
    assert (cov > 0).sum() <= np.pi * (expected_px / 2 + 1.5) ** 2


def test_disc_sits_where_mitsubas_camera_looks_at_the_sun(mi):
    from workbench.render.scene_builder import pinhole_sensor

    fov = 4.0
    pose = pose_at_sun(0.7, -0.4, 25.0)
    cov = sun_disc(FILM, pose, fov, W, H, DAYLIGHT, sky_mask=all_sky()).coverage
    rows, cols = np.nonzero(cov)
    w = cov[rows, cols]
    cx, cy = (cols + 0.5) @ w / w.sum(), (rows + 0.5) @ w / w.sum()
    sensor = mi.load_dict({**pinhole_sensor(pose, fov), "film": {"type": "hdrfilm", "width": W, "height": H}})
    ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(float(cx / W), float(cy / H)), mi.Point2f(0.5, 0.5))
    d = np.array(ray.d, dtype=np.float64).ravel()
    off_deg = np.degrees(np.arccos(np.clip(d @ sun_direction(EL, AZ), -1, 1)))
    assert off_deg < 0.05 * fov / W                       # within 1/20 pixel of the sun's centre


def _blocking_wall_city():
    """One wall 100 m toward the sun covering the image-left half of the disc (edge on the axis)."""
    sun = sun_direction(EL, AZ)
    right = np.cross(sun, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)                        # image right for a camera aimed at the sun
    up = np.cross(right, sun)
    c = 100.0 * sun
    verts = np.array([c, c - 20 * right, c - 20 * right + 20 * up, c + 20 * up,
                      c - 20 * up, c - 20 * right - 20 * up])
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 5, 1]])
    wl = np.array([300.0, 1100.0])
    mat = Material("wall", wl, np.array([0.3, 0.3]))
    return City([CityObject("building", 1, [Mesh(verts, faces, "wall")])], {"wall": mat}, 0,
                (-200.0, -200.0, 200.0, 200.0))


def test_pixels_that_do_not_see_the_sky_get_no_sun(mi):
    from workbench.render.labels import render_labels
    from workbench.render.scene_builder import build_scene

    fov, pose = 2.0, pose_at_sun()
    free = sun_disc(FILM, pose, fov, W, H, DAYLIGHT, sky_mask=all_sky()).coverage
    scene, ids = build_scene(_blocking_wall_city(), pose, fov, W, H, FILM, DAYLIGHT)
    labels = render_labels(scene, ids, W, H)
    assert (labels.instance_id[:, : W // 2] == 1).all() and (labels.instance_id[:, W // 2:] == 0).all()
    traced = sun_disc(FILM, pose, fov, W, H, DAYLIGHT, mi_scene=scene).coverage
    masked = sun_disc(FILM, pose, fov, W, H, DAYLIGHT, sky_mask=labels.instance_id == 0).coverage
    for cov in (traced, masked):
        assert cov[:, : W // 2 - 1].max() == 0                     # behind the wall: nothing
        np.testing.assert_allclose(cov[:, W // 2 + 1:], free[:, W // 2 + 1:])   # open sky: all of it
        assert cov.sum() == pytest.approx(free.sum() / 2, rel=0.03)


def test_a_sensor_channel_film_reports_the_qe_weighted_mean_of_the_disc():
    # Two sensor channels whose QE curves are FILM's first two bands must report those bands.
    from workbench.render.film import sensor_channels
    from workbench.render.sun_disc import sun_film_radiance

    film = sensor_channels(FILM.wavelengths_nm, 0.6 * FILM.responses[:2], names=["a", "b"])
    np.testing.assert_allclose(sun_film_radiance(film, DAYLIGHT), sun_film_radiance(FILM, DAYLIGHT)[:2],
                               rtol=1e-9)
    omega = sun_solid_angle_sr()
    np.testing.assert_allclose(sun_film_radiance(FILM, DAYLIGHT) * omega, band_mean_sun_photons(), rtol=2e-3)


def test_sun_visible_false_and_a_sun_out_of_view_add_nothing():
    rad = np.full((H, W, 6), 7.0, np.float32)
    off = sun_disc(FILM, pose_at_sun(), 2.0, W, H, DAYLIGHT.updated(sun_visible=False), sky_mask=all_sky())
    assert off.meta["status"] == "off" and np.array_equal(off.add_to(rad), rad)
    away = sun_disc(FILM, pose_at_sun(d_pan=90.0), 44.0, W, H, DAYLIGHT, sky_mask=all_sky())
    assert away.meta["pixels"] == 0 and np.array_equal(away.add_to(rad), rad)
    assert sun_solid_angle_sr() == pytest.approx(6.8e-5, rel=0.01)


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="mi_scene .* or sky_mask"):
        sun_disc(FILM, pose_at_sun(), 2.0, W, H, DAYLIGHT)
    with pytest.raises(ValueError, match="sky_mask must be 48×64"):
        sun_disc(FILM, pose_at_sun(), 2.0, W, H, DAYLIGHT, sky_mask=np.ones((4, 4), bool))
    disc = sun_disc(FILM, pose_at_sun(), 2.0, W, H, DAYLIGHT, sky_mask=all_sky())
    with pytest.raises(ValueError, match="radiance must be 48×64×6"):
        disc.add_to(np.zeros((H, W, 3), np.float32))


def sunrise_city(sun_visible=True):
    """The paper's city at 64×48, camera on the south street looking east at a sun 5° high
    (10° FOV, longer pixels, so that the disc covers whole pixels), tilted 2° so the road is in view."""
    from workbench.project import load_project
    p = load_project("city_paper_camera")
    pitch = 2e3 * p.optics.focal_length_mm * np.tan(np.radians(5.0)) / W      # 10° horizontal FOV
    daylight = p.render.daylight.updated(sun_elevation_deg=5.0, sun_azimuth_deg=90.0, sun_visible=sun_visible)
    pose = p.pose.updated(mode="manual", manual_position_xy_m=(-20.0, 1.75), manual_pan_deg=0.0,
                          manual_tilt_deg=2.0, manual_roll_deg=0.0)
    return p.updated(sensor=p.sensor.updated(rows=H, cols=W, pixel_pitch_um=pitch),
                     pose=pose,
                     render=p.render.updated(spp=4, chunk_spp=4, daylight=daylight))


def _shadowed_ground(mi, project, render):
    """H×W bool: road/ground pixels whose point (pixel-centre ray × depth) cannot see the sun."""
    from workbench.render.scene_builder import build_scene
    from workbench.render.sun_disc import pinhole_frame
    from workbench.scene.city import generate_city, sample_camera_poses

    city = generate_city(project.city.model_copy(update={"arrangement": render.meta["arrangement"]}))
    pose = sample_camera_poses(city, project.pose, 1, 0)[0]
    scene, _ = build_scene(city, pose, render.meta["fov_deg"], W, H, FILM, project.render.daylight)
    fwd, right, down = pinhole_frame(pose)
    tx = np.tan(np.radians(render.meta["fov_deg"]) / 2)
    x = ((np.arange(W) + 0.5) / W * 2 - 1) * tx
    y = ((np.arange(H) + 0.5) / H * 2 - 1) * tx * H / W
    d = fwd + x[None, :, None] * right + y[:, None, None] * down
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    p = (pose.position_m + render.labels.depth_m[..., None] * d).reshape(-1, 3) + [0.0, 0.0, 0.01]
    sun = sun_direction(project.render.daylight.sun_elevation_deg, project.render.daylight.sun_azimuth_deg)
    ray = mi.Ray3f(mi.Point3f(*(np.ascontiguousarray(p[:, k], np.float32) for k in range(3))),
                   mi.Vector3f(*(float(v) for v in sun)))
    blocked = np.array(scene.ray_test(ray), dtype=bool).reshape(H, W)
    ground_ids = [k for k, n in render.labels.class_names.items() if n in ("road", "ground")]
    return blocked & np.isin(render.labels.class_id, ground_ids)


def test_city_frame_with_the_sun_in_view_stays_finite_through_sensor_and_isp(mi):
    from workbench.pipeline import Pipeline

    pipe = Pipeline(sunrise_city())
    result = pipe.run()
    render = pipe.scene_stage_result()
    assert render.meta["sun_disc"]["status"] == "composited" and render.meta["sun_disc"]["pixels"] > 0
    rad = render.scene.radiance_photons.astype(np.float64).mean(axis=2)
    shadow = _shadowed_ground(mi, pipe.project, render)
    assert shadow.sum() >= 5                                         # 12 here
    assert rad.max() / np.median(rad[shadow]) > 1e6      # HDR beyond 10⁶:1 (measured 2.0e6)
    for arr in (result.optical_image.irradiance_photons, result.sensor_image.volts,
                result.sensor_image.dn, result.isp.srgb):
        assert np.all(np.isfinite(arr))
    sun_px = np.unravel_index(np.argmax(rad), rad.shape)
    assert result.sensor_image.dn[sun_px] == result.sensor_image.max_dn     # clipped at the swing
    dark = Pipeline(sunrise_city(sun_visible=False))
    dark_render = dark.scene_stage_result()
    assert dark_render.meta["sun_disc"]["status"] == "off"
    assert dark_render.scene.radiance_photons.max() < 1e-3 * render.scene.radiance_photons.max()
