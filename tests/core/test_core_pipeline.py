"""The staged pipeline: caching by dependency, hand-computed electrons, hard cases, no NaN."""
import numpy as np
import pytest

from workbench import spectra
from workbench.pipeline import Pipeline
from workbench.project import Project, load_project
from workbench.scene.params import SceneParams
from workbench.sensor.cfa import channel_qe
from workbench.stages.geometry import project_geometry
from workbench.units import band_widths_nm


def small(project: Project, rows=48, cols=64, keep_fov=True, **sensor) -> Project:
    """A smaller sensor; with keep_fov the pixels grow so the field of view stays the same."""
    pitch = project.sensor.pixel_pitch_um * (project.sensor.cols / cols if keep_fov else 1.0)
    return edit(project, "sensor", rows=rows, cols=cols, pixel_pitch_um=pitch, **sensor)


def edit(project: Project, section: str, **changes) -> Project:
    return project.updated(**{section: getattr(project, section).updated(**changes)})


def test_stages_recompute_only_downstream_of_a_change():
    project = small(load_project("paper_camera"))
    pipe = Pipeline(project)
    pipe.run()
    assert pipe.recomputed == ["scene", "optics", "signal", "sensor", "isp"]
    pipe.set_project(edit(project, "isp", demosaic="malvar2004"))
    pipe.run()
    assert pipe.recomputed == ["isp"]
    pipe.set_project(edit(pipe.project, "sensor", read_noise_V=2e-3))
    pipe.run()
    assert pipe.recomputed == ["sensor", "isp"]
    pipe.set_project(edit(pipe.project, "sensor", pixel_pitch_um=2.0))
    pipe.run()
    assert pipe.recomputed == ["scene", "optics", "signal", "sensor", "isp"]   # the field of view changed
    pipe.set_project(edit(pipe.project, "optics", f_number=2.8))
    pipe.run()
    assert pipe.recomputed == ["optics", "signal", "sensor", "isp"]


def test_mean_electrons_of_a_uniform_scene_match_the_hand_computed_value():
    # Camera equation + t·A·FF·ΣE·QE·Δλ by hand, noise off, fixed exposure.
    project = small(load_project("paper_camera"), rows=32, cols=32, noise_flag=-1, exposure_s=0.01,
                    bit_depth=0)
    project = edit(project, "scene", kind="uniform", adjust_illuminance_lux=None, mean_luminance_cd_m2=100.0)
    project = edit(project, "optics", off_axis="none")
    result = Pipeline(project).run()
    wl = project.scene.wavelengths.grid()
    radiance = result.scene.radiance_photons[0, 0].astype(np.float64)
    f_m, n, d = project.optics.focal_length_mm * 1e-3, project.optics.f_number, project.scene.distance_m
    m = f_m / (d - f_m)
    irradiance = np.pi * radiance / (1 + 4 * n**2 * (1 + m) ** 2)
    s = project.sensor
    qe = channel_qe(s, wl)
    expected = 0.01 * s.pixel_area_m2 * s.fill_factor * (irradiance * band_widths_nm(wl)) @ qe   # per channel
    img = result.sensor_image
    for k, name in enumerate(img.channel_names):
        got = img.electrons[img.channel_mask(k)].mean()
        assert got == pytest.approx(expected[k], rel=0.005), name


@pytest.mark.parametrize("sensor_changes", [
    dict(exposure_s=0.0),                       # zero exposure
    dict(exposure_s=100.0),                     # saturates every pixel
    dict(rows=1, cols=1),                       # 1×1 sensor
    dict(rows=7, cols=13),                      # odd-sized sensor
])
def test_hard_cases_stay_finite(sensor_changes):
    rows, cols = sensor_changes.pop("rows", 24), sensor_changes.pop("cols", 32)
    project = small(load_project("paper_camera"), rows=rows, cols=cols, keep_fov=False, **sensor_changes)
    result = Pipeline(project).run()
    for arr in (result.signal_rate_e_per_s, result.sensor_image.dn, result.isp.raw, result.isp.linear,
                result.isp.srgb):
        assert np.all(np.isfinite(arr))
    dn = result.sensor_image.dn
    if sensor_changes.get("exposure_s") == 100.0:
        assert np.all(dn == result.sensor_image.max_dn)
    if sensor_changes.get("exposure_s") == 0.0:
        assert dn.mean() < 2          # read noise only, clipped at 0


def test_hdr_tunnel_through_every_sensor_preset_has_no_overflow():
    from workbench.sensor.params import SENSOR_PRESETS
    for name, preset in SENSOR_PRESETS.items():
        project = Project(scene=SceneParams(kind="hdr_tunnel", wavelengths=dict(start_nm=400, stop_nm=1000,
                                                                                  step_nm=50)),
                          sensor=preset)
        project = small(project, rows=30, cols=40, keep_fov=False)
        result = Pipeline(project).run()
        irr = result.optical_image.irradiance_photons
        assert irr.max() / max(irr[irr > 0].min(), 1e-30) > 1e5
        for arr in (result.signal_rate_e_per_s, result.sensor_image.dn, result.isp.srgb):
            assert np.all(np.isfinite(arr)), name
        assert result.sensor_image.dn.max() <= result.sensor_image.max_dn


def test_camera_field_of_view_is_the_papers():
    assert project_geometry(load_project("paper_camera")).hfov_deg == pytest.approx(44.0, abs=0.01)


def test_illuminance_adjustment():
    project = small(load_project("paper_camera"))
    oi = Pipeline(project).optical_image()
    lux = spectra.illuminance_from_photons(oi.irradiance_photons.reshape(-1, oi.wavelengths_nm.size).mean(0),
                                           oi.wavelengths_nm)
    assert float(lux) == pytest.approx(1000.0, rel=1e-4)


@pytest.mark.parametrize("model", ["pinhole", "diffraction_limited", "thin_lens"])
def test_the_illuminance_scaling_changes_only_the_optics_own_array(model):
    """The optical image is scaled in place (it is the optics model's new array): the scene's
    radiance is left as it was and a second run gives the same irradiance, not a rescaled one."""
    from workbench.stages.optics import form_optical_image
    from workbench.stages.scene import chart_scene
    project = small(load_project("paper_camera"))
    project = project.updated(optics=project.optics.updated(model=model))
    geometry = project_geometry(project)
    scene = chart_scene(project.scene, geometry)
    radiance = scene.radiance_photons.copy()
    first = form_optical_image(scene, project.optics, geometry, 1000.0).irradiance_photons
    second = form_optical_image(scene, project.optics, geometry, 1000.0).irradiance_photons
    assert np.array_equal(scene.radiance_photons, radiance)
    assert np.array_equal(first, second) and not np.shares_memory(first, second)


def test_pipeline_job_cancels_between_stages():
    from workbench.jobs import CancelToken, JobCancelled
    token = CancelToken()
    pipe = Pipeline(small(load_project("paper_camera")))
    job = pipe.run_job(token)
    first = next(job)
    assert first.message == "scene" and first.fraction == 0.0
    assert next(job).message == "optics"
    token.cancel()
    with pytest.raises(JobCancelled):
        next(job)
    assert pipe.recomputed == ["scene", "optics"]    # the announced stage ran; none after the cancel
    pipe.run()                                         # a new run goes on from the cached stages
    assert pipe.recomputed == ["signal", "sensor", "isp"]


def test_going_back_to_an_earlier_project_finds_every_stage_cached():
    """Undo after edits: the earlier results are still in the cache (several per stage, least
    recently used out first), so nothing recomputes and the very same arrays come back."""
    project = small(load_project("paper_camera"))
    pipe = Pipeline(project)
    first = pipe.run()
    for changed in (edit(project, "sensor", analog_gain=2.0), edit(project, "scene", distance_m=5.0),
                    edit(project, "isp", demosaic="malvar2004")):
        pipe.set_project(changed)
        pipe.run()
    pipe.set_project(project)
    again = pipe.run()
    assert pipe.recomputed == [] and again.isp is first.isp and again.optical_image is first.optical_image


def test_the_stage_cache_keeps_to_its_memory_budget():
    from workbench.pipeline import result_nbytes
    project = small(load_project("paper_camera"))
    one = Pipeline(project)
    one.run()
    per_run = one.cache_bytes()
    assert per_run == sum(result_nbytes(v) for e in one._cache.values() for v, _, _ in e.values()) > 0
    pipe = Pipeline(project, cache_mb=2.5 * per_run / 2 ** 20)
    for gain in (1.5, 2.0, 2.5, 3.0):
        pipe.set_project(edit(project, "scene", distance_m=gain * 4))     # every stage new each time
        pipe.run()
        assert pipe.cache_bytes() <= 2.5 * per_run
    pipe.set_project(edit(project, "scene", distance_m=3.0 * 4))          # the newest is kept
    pipe.run()
    assert pipe.recomputed == []
