"""The full lens model on city frames: Mitsuba traces every camera ray through the lens and the film
holds sensor irradiance (units checked end to end against the camera equation), the frame path
runs with labels on the same pixel grid as the pinhole path, and the fast Dr.Jit trace agrees ray
by ray with the float64 numpy trace."""
import json
import math

import numpy as np
import pytest

from workbench.optics.lens import irradiance_per_radiance, load_lens, paraxial, sensor_z_mm, trace_rays
from workbench.optics.params import OpticsParams
from workbench.units import photon_energy_J

LENS = "automotive.2.4mm"


def _optics(**kw) -> OpticsParams:
    return OpticsParams(model="raytrace", lens_file=LENS, **kw)


def _camera(params, focus_m, **width):
    from workbench.optics.formation.geometry import camera_geometry
    from workbench.optics.formation.full_model import full_model_camera
    return full_model_camera(params, camera_geometry(params, focus_m, (12, 16), **width))


def test_camera_follows_formation_lens_preparation():
    from workbench.optics.formation import lens_setup
    from workbench.optics.formation.geometry import camera_geometry
    scaled = _camera(_optics(scale_lens_to_focal_length=True, focal_length_mm=3.0, f_number=5.6),
                     10.0, sensor_width_m=1.92e-3)
    assert scaled.focal_length_m == pytest.approx(3.0e-3, rel=1e-9)
    assert paraxial(scaled.lens).f_number == pytest.approx(5.6, rel=1e-9) == scaled.f_number
    native = _camera(_optics(f_number=4.0), 10.0, fov_deg=44.0)
    assert native.focal_length_m == pytest.approx(paraxial(load_lens(LENS)).efl_mm * 1e-3, rel=1e-9)
    assert native.fov_deg == pytest.approx(44.0, rel=1e-9)
    # focused like raytrace: the lens formation/ focuses on the same object distance
    ref, _ = lens_setup.focused_lens(_optics(f_number=4.0), 10.0)
    assert sensor_z_mm(native.lens) == pytest.approx(sensor_z_mm(ref), abs=1e-12)
    fixed = _camera(_optics(focus_distance_m=2.0), 10.0, sensor_width_m=1e-3)
    assert fixed.focus_distance_m == 2.0
    with pytest.raises(ValueError, match="exactly one"):
        camera_geometry(_optics(), 10.0, (12, 16), sensor_width_m=1e-3, fov_deg=40.0)
    with pytest.raises(ValueError, match="sensor_width_m"):
        camera_geometry(_optics(), 10.0, (12, 16), sensor_width_m=-1e-3)


def test_uniform_environment_gives_camera_equation_irradiance_in_photons(mi):
    """Constant sky of L = 0.02 W/m²/sr/nm through the calibrated spectral film: on-axis irradiance
    = T · L_photons · E/L of the traced lens (the numpy estimator), in photons/s/m²/nm."""
    from workbench.jobs import run_job
    from workbench.optics.formation.full_model import full_model_optical_image
    from workbench.render.lens_camera import lens_sensor_dict
    from workbench.render.film import box_bands
    from workbench.render.params import RenderParams
    from workbench.render.spectral import render_loaded
    L_W = 0.02
    film = box_bands(450.0, 650.0, 4)
    params = _optics(f_number=2.8, transmittance=0.9, raytrace_diffraction=False)
    cam = _camera(params, math.inf, sensor_width_m=0.04e-3)   # 16 px within 25 µm of the axis
    to_world = mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0])
    sensor = lens_sensor_dict(cam.lens, film.mitsuba_film(16, 12), to_world, cam.sensor_width_mm)
    sensor["sampler"] = {"type": "independent", "sample_count": 1}
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "path", "max_depth": 2}, "sensor": sensor,
                          "sky": {"type": "constant", "radiance": {"type": "uniform", "value": L_W}}})
    rendered = run_job(render_loaded(scene, film, RenderParams(spp=1024, chunk_spp=1024), fov_deg=cam.fov_deg))
    oi = full_model_optical_image(rendered.radiance_photons, rendered.wavelengths_nm, cam, params)
    wl = np.linspace(449.0, 651.0, 20001)
    s = np.stack([np.interp(wl, film.wavelengths_nm, r) for r in film.responses])
    L_photons = np.trapezoid(L_W / photon_energy_J(wl) * s, wl, axis=1) / np.trapezoid(s, wl, axis=1)
    expected = 0.9 * L_photons * irradiance_per_radiance(cam.lens)
    got = oi.irradiance_photons.reshape(-1, 4).mean(0)
    assert np.isfinite(oi.irradiance_photons).all()
    assert got == pytest.approx(expected, rel=0.01)   # Monte Carlo σ ≈ 0.15 % at 1024 spp
    assert oi.sample_spacing_m == pytest.approx(0.04e-3 / 16)
    # units sanity against the paraxial camera equation π T L / (4 N²), independent of the
    # estimator: this wide-angle lens at f/2.8 delivers 0.935 of it on axis (pupil aberration)
    paraxial_ratio = got.mean() / (0.9 * L_photons.mean()) / (math.pi / (4 * 2.8 ** 2))
    assert paraxial_ratio == pytest.approx(0.935, abs=0.015)


def _tiny_city_project(model: str, lux: float | None = None):
    from workbench.project import Project, load_project
    from workbench.scene.city.recipe import CityRecipe, PoseParams
    doc = json.loads(load_project("paper_camera").model_dump_json())
    doc["scene"].update(kind="city", adjust_illuminance_lux=lux, fov_deg=None, distance_m=10.0)
    doc["city"] = CityRecipe(blocks_x=1, blocks_y=1).model_dump()
    doc["pose"] = PoseParams().model_dump()
    doc["sensor"].update(rows=48, cols=64, pixel_pitch_um=30.0)     # the paper's 1.92 mm sensor, 1/10 res.
    doc["render"].update(spp=2, band_count=4, max_depth=2)
    doc["optics"].update(model=model, lens_file=LENS, f_number=2.68, focal_length_mm=2.3761)
    return Project.model_validate(doc)


def test_city_frame_renders_through_the_lens_with_matching_labels(mi):
    from workbench.render.city_frame import frame_optical_image, frame_seeds, render_city_frame
    full = render_city_frame(_tiny_city_project("raytrace"), frame_seeds(0, 1))
    pin = render_city_frame(_tiny_city_project("pinhole"), frame_seeds(0, 1))
    irr = full.irradiance_photons
    assert irr.shape == (48, 64, 4) and irr.dtype == np.float32
    assert np.isfinite(irr).all() and irr.min() >= 0 and irr.max() > 0
    assert full.meta["optics_model"].startswith("full")
    assert full.meta["sample_spacing_m"] == pytest.approx(30e-6, rel=1e-9)
    assert full.meta["focal_length_m"] == pytest.approx(paraxial(load_lens(LENS)).efl_mm * 1e-3, rel=1e-9)
    assert full.meta["f_number"] == pytest.approx(2.68, rel=1e-9)
    oi = frame_optical_image(full)
    assert oi.shape == full.labels.shape == (48, 64)
    # Same pose, same pixel grid, upright: the lens (distortion < 1 %) labels the pixels as the pinhole
    # does except along object edges, and large objects' boxes agree within a pixel.
    assert np.mean(full.labels.instance_id == pin.labels.instance_id) > 0.97
    boxes = {o.instance_id: o.bbox_xywh for o in pin.labels.objects if o.visible_px >= 20}
    assert boxes
    for o in full.labels.objects:
        if o.instance_id in boxes:
            assert np.allclose(o.bbox_xywh, boxes[o.instance_id], atol=1), (o.class_name, o.bbox_xywh)
    # Overall brightness: the pinhole's cos⁴ camera equation vs the lens's traced one (vignetting)
    ratio = irr.mean() / pin.irradiance_photons.mean()
    assert 0.7 < ratio < 1.1


def test_city_frame_full_model_scales_to_the_asked_illuminance(mi):
    from workbench import spectra
    from workbench.render.city_frame import frame_seeds, render_city_frame, uses_full_lens_model
    project = _tiny_city_project("raytrace", lux=1000.0)
    assert uses_full_lens_model(project.optics)
    assert not uses_full_lens_model(project.optics.model_copy(update={"lens_file": None}))
    assert not uses_full_lens_model(project.optics.model_copy(update={"model": "psf_grid"}))
    frame = render_city_frame(project, frame_seeds(0, 2))
    mean = frame.irradiance_photons.reshape(-1, frame.irradiance_photons.shape[-1]).mean(0)
    assert spectra.illuminance_from_photons(mean, frame.wavelengths_nm) == pytest.approx(1000.0, rel=1e-4)


@pytest.mark.parametrize("name, heights_mm", [(LENS, (0.0, 0.6, 1.15)), ("dgauss.50mm", (0.0, 12.0, 21.0))])
def test_fast_trace_agrees_with_numpy_ray_by_ray(mi, name, heights_mm):
    """Division-free sphere hits and unnormalised sphere normals: same survivors (float32 may flip
    rays grazing an aperture edge) and exit directions within float32 error, across the field."""
    import drjit as dr

    from workbench.optics.lens.analysis import rear_pupil_box
    from workbench.render.lens_camera.kernels import trace_reverse
    lens = load_lens(name)
    zs, zr = sensor_z_mm(lens), lens.total_track_mm
    for h in heights_mm:
        x0, x1, y0, y1 = rear_pupil_box(lens, h)       # rays on +y; a 60² grid over 1.2× the box
        cx, cy, hw = (x0 + x1) / 2, (y0 + y1) / 2, 0.6 * max(x1 - x0, y1 - y0)
        xx, yy = np.meshgrid(np.linspace(cx - hw, cx + hw, 60), np.linspace(cy - hw, cy + hw, 60))
        src = np.array([0.0, h, zs])
        d = np.column_stack([xx.ravel(), yy.ravel(), np.full(xx.size, zr)]) - src
        d /= np.linalg.norm(d, axis=1)[:, None]
        ref = trace_rays(lens, np.tile(src, (len(d), 1)), d, 587.6, reverse=True)
        n = len(d)
        f = [mi.Float(np.ascontiguousarray(a, dtype=np.float32))
             for a in (np.zeros(n), np.full(n, h), np.full(n, zs), d[:, 0], d[:, 1], d[:, 2])]
        out = trace_reverse(lens, *f, None, dr, mi)
        ok = np.array(out[6], dtype=bool)
        assert ref.valid.sum() > 400
        assert (ok != ref.valid).sum() <= 3
        both = ok & ref.valid
        dirs = np.column_stack([np.array(v) for v in out[3:6]])[both]
        assert np.allclose(dirs, ref.dirs[both], atol=3e-5)
        assert np.allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-5)
