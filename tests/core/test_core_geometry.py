"""One camera geometry for every optics level and for the scene stage: a lens file, the focus,
the sensor size and the pixel pitch all re-sample the scene, and the optical image always lands
on the pixel grid (sample spacing = pixel pitch / oversample)."""
import math

import numpy as np
import pytest

from workbench.optics.lens import load_lens, paraxial
from workbench.pipeline import Pipeline
from workbench.project import load_project
from workbench.stages.geometry import project_geometry

LENS = "dgauss.50mm"


def edit(project, section, **changes):
    return project.updated(**{section: getattr(project, section).updated(**changes)})


def tiny(**optics):
    """The paper's camera on a 24×32 sensor of 3 µm pixels, 7 bands, cheap lens-level settings."""
    p = load_project("paper_camera")
    p = edit(p, "sensor", rows=24, cols=32)
    p = edit(p, "scene", wavelengths=p.scene.wavelengths.updated(step_nm=50.0))
    return edit(p, "optics", psf_field_zones=2, psf_azimuths=1, psf_wavelengths=1, psf_depth_nodes=1,
                rays_per_sample=4, **optics)


def spacing_on_pixel_grid(pipe):
    p = pipe.project
    return p.sensor.pixel_pitch_um * 1e-6 / p.scene.oversample


def test_a_lens_file_sets_the_field_of_view_from_its_focal_length():
    # Reproduced on the old main: psf_grid with dgauss.50mm sampled the scene over 43.99° (from
    # optics.focal_length_mm), so the optical image had 63.9 µm samples behind 3 µm pixels.
    pipe = Pipeline(tiny(model="psf_grid", lens_file=LENS))
    oi = pipe.optical_image()
    efl_m = paraxial(load_lens(LENS)).efl_mm * 1e-3
    camera = pipe.camera_geometry()
    assert camera.focal_length_m == pytest.approx(efl_m, rel=1e-9)
    p = paraxial(load_lens(LENS))             # the pinhole at the entrance pupil: |m|·s, m = −f/x (Newton)
    d = efl_m * 10.0 / (10.0 - (p.entrance_pupil_mm + p.ffl_mm) * 1e-3)
    assert pipe.scene().fov_deg == pytest.approx(math.degrees(2 * math.atan(32 * 3e-6 / 2 / d)), rel=1e-9)
    assert oi.sample_spacing_m == pytest.approx(3e-6, rel=1e-9)


@pytest.mark.parametrize("model, lens_file", [
    ("pinhole", None), ("diffraction_limited", None), ("thin_lens", None),
    ("pinhole", LENS), ("thin_lens", LENS), ("psf_grid", LENS), ("raytrace", LENS), ("auto", LENS)])
@pytest.mark.parametrize("oversample", [1, 2])
def test_every_optics_level_lands_on_the_pixel_grid(model, lens_file, oversample):
    project = edit(tiny(model=model, lens_file=lens_file), "scene", oversample=oversample)
    if oversample == 2 and model in ("raytrace", "auto"):
        project = edit(project, "sensor", rows=12, cols=16)
    pipe = Pipeline(project)
    oi = pipe.optical_image()
    assert oi.sample_spacing_m == pytest.approx(spacing_on_pixel_grid(pipe), rel=1e-9)
    assert oi.irradiance_photons.shape[:2] == pipe.camera_geometry().shape
    # every level saw the same geometry: the lens's focal length when a lens file is set
    f_m = paraxial(load_lens(LENS)).efl_mm * 1e-3 if lens_file else project.optics.focal_length_mm * 1e-3
    assert pipe.camera_geometry().focal_length_m == pytest.approx(f_m, rel=1e-9)
    assert oi.meta["image_distance_m"] == pytest.approx(pipe.camera_geometry().image_distance_m, rel=1e-12)


def test_the_full_lens_camera_uses_the_same_geometry():
    from workbench.optics.formation.full_model import full_model_camera
    project = tiny(model="raytrace", lens_file=LENS, focus_distance_m=3.0)
    camera = project_geometry(project)
    lens_camera = full_model_camera(project.optics, camera)
    assert lens_camera.fov_deg == pytest.approx(camera.hfov_deg, rel=1e-12)
    assert lens_camera.image_distance_m == camera.image_distance_m
    assert lens_camera.focus_distance_m == 3.0
    assert lens_camera.sensor_width_mm * 1e-3 / camera.shape[1] == pytest.approx(3e-6, rel=1e-12)


EDITS = {
    "focus": ("optics", dict(focus_distance_m=0.01)),        # 10 m → 1 cm: the image distance grows
    "lens file": ("optics", dict(lens_file=LENS)),
    "sensor size": ("sensor", dict(rows=30, cols=40)),
    "pixel pitch": ("sensor", dict(pixel_pitch_um=2.0)),
    "oversample": ("scene", dict(oversample=2)),
}


@pytest.mark.parametrize("what", list(EDITS))
def test_a_geometry_edit_resamples_the_scene(what):
    # Reproduced on the old main: focus 10 m → 0.01 m re-ran the optics on the old 43.99° scene.
    pipe = Pipeline(tiny())
    before = pipe.run()
    section, changes = EDITS[what]
    pipe.set_project(edit(pipe.project, section, **changes))
    after = pipe.run()
    assert pipe.recomputed == ["scene", "optics", "signal", "sensor", "isp"]
    camera = pipe.camera_geometry()
    assert after.scene.fov_deg == pytest.approx(camera.hfov_deg, rel=1e-12)
    assert after.scene.fov_deg != pytest.approx(before.scene.fov_deg, rel=1e-6) or what == "oversample"
    assert after.scene.shape == camera.shape
    assert after.optical_image.sample_spacing_m == pytest.approx(spacing_on_pixel_grid(pipe), rel=1e-9)
    fresh = Pipeline(pipe.project).run()
    np.testing.assert_array_equal(after.optical_image.irradiance_photons, fresh.optical_image.irradiance_photons)


def test_the_regrid_method_reruns_the_pixel_signal():
    # The hand-kept list of signal fields missed regrid_method: the old rate was kept.
    project = edit(tiny(), "scene", fov_deg=30.0)                    # off the pixel grid: resampled
    pipe = Pipeline(project)
    pipe.run()
    pipe.set_project(edit(project, "sensor", regrid_method="isetcam"))
    rate = pipe.signal_rate()
    np.testing.assert_array_equal(rate, Pipeline(pipe.project).signal_rate())
    assert not np.array_equal(rate, Pipeline(project).signal_rate())
