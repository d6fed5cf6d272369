"""A city project through the whole pipeline: render → optics → sensor → ISP, with labels."""
import numpy as np
import pytest

from workbench.pipeline import Pipeline
from workbench.project import load_project


def tiny_city(rows=48, cols=64, **render):
    p = load_project("city_paper_camera")
    pitch = p.sensor.pixel_pitch_um * p.sensor.cols / cols          # same field of view
    settings = {"spp": 4, "chunk_spp": 4, **render}
    return p.updated(sensor=p.sensor.updated(rows=rows, cols=cols, pixel_pitch_um=pitch),
                     render=p.render.updated(**settings))


def test_city_frame_runs_through_every_stage_and_caches_the_render():
    pipe = Pipeline(tiny_city())
    result = pipe.run()
    assert pipe.recomputed == ["scene", "optics", "signal", "sensor", "isp"]
    for arr in (result.optical_image.irradiance_photons, result.sensor_image.dn, result.isp.srgb):
        assert np.all(np.isfinite(arr))
    assert result.optical_image.irradiance_photons.shape[:2] == (48, 64)
    assert result.labels is not None and result.labels.class_id.shape == (48, 64)
    assert result.sensor_image.electrons.mean() > 100
    pipe.set_project(pipe.project.updated(isp=pipe.project.isp.updated(demosaic="malvar2004")))
    pipe.run()
    assert pipe.recomputed == ["isp"]                                  # no re-render


def _channel_electrons(project):
    img = Pipeline(project.updated(sensor=project.sensor.updated(noise_flag=-1, exposure_s=1e-3))).sensor_image()
    return np.array([img.electrons[img.channel_mask(k)].mean() for k in range(len(img.channel_names))])


@pytest.mark.slow
def test_sensor_channel_film_gives_the_electrons_of_a_spectral_film():
    # Oracle: the same frame rendered as 30 narrow bands and as the sensor's own 3 channel
    # responses must collect the same mean electrons per channel (Monte Carlo + band error).
    bands = _channel_electrons(tiny_city(spp=16, chunk_spp=16, representation="bands", band_count=30))
    channels = _channel_electrons(tiny_city(spp=16, chunk_spp=16, representation="sensor"))
    np.testing.assert_allclose(channels, bands, rtol=0.015)          # measured: ≤ 0.3 %


def test_render_noise_follows_the_sensor_shot_noise():
    p = tiny_city(spp=None, shot_noise_ratio=10.0, pilot_spp=2)
    pipe = Pipeline(p)
    meta = pipe.scene().meta
    target = pipe.scene_stage_result().meta["shot_noise_target_rel_error"]
    img = pipe.sensor_image()
    mean_e = img.electrons.mean()            # 'mean' auto-exposure at 0.4 of the swing ≈ 4000 e⁻
    assert target == pytest.approx(10.0 / np.sqrt(mean_e), rel=0.1)
    assert meta["spp"] >= 1


def test_a_stored_sensor_channel_frame_feeds_the_sensor_like_the_live_pipeline(tmp_path):
    from workbench.render.city_frame import frame_optical_image, frame_seeds, render_city_frame
    from workbench.datasets.dataset import FRAME_FORMAT, FRAME_VERSION, read_frame, write_frame
    from workbench.sensor import irradiance_to_signal_rate
    project = tiny_city(representation="sensor")
    live = Pipeline(project).signal_rate()
    frame = render_city_frame(project, frame_seeds(project.seed, 0))
    write_frame(tmp_path / "f.npz", frame, {"format": FRAME_FORMAT, "version": FRAME_VERSION, "index": 0}, "float16")
    stored, _ = read_frame(tmp_path / "f.npz")
    rate = irradiance_to_signal_rate(frame_optical_image(stored), project.sensor)
    np.testing.assert_allclose(rate, live, rtol=1e-3)                 # float16 storage: ≤ 2^-11


def test_the_city_render_is_a_nested_job_with_previews_that_stops_at_the_cancel_token():
    from workbench.jobs import CancelToken, JobCancelled
    pipe = Pipeline(tiny_city(spp=8, chunk_spp=2, preview_spp=2))
    token, steps = CancelToken(), []
    job = pipe.run_job(token)
    with pytest.raises(JobCancelled):
        for step in job:
            steps.append(step)
            if step.preview is not None:
                assert step.preview.shape[:2] == (48, 64) and 0 < step.fraction < 1 / 5
                token.cancel()                      # the render stops at its next chunk
    previews = [s for s in steps if s.preview is not None]
    assert len(previews) == 1 and previews[0].message.startswith("scene: frame 0: 2/8 spp")
    assert pipe.recomputed == []                     # the partial render was not stored
    result = pipe.run()
    assert pipe.recomputed[0] == "scene" and result.scene.meta["spp"] == 8


def test_sensor_channel_render_gets_the_sensors_colour_matrix():
    # A render in the sensor's own channels has 3 "bands" that are not wavelengths; the ISP must
    # still fit the sensor's colour matrix on the sensor's spectral grid (oracle: the same fit
    # made directly from the sensor's QE), not give a grey image.
    from workbench.isp.color import fit_sensor_to_xyz
    from workbench.sensor.cfa import SENSOR_SPECTRAL_GRID_NM, channel_qe
    project = tiny_city(24, 32, representation="sensor")
    isp = Pipeline(project).run().isp
    assert isp.colour_fit is not None and not any("grey" in n for n in isp.notes), isp.notes
    direct = fit_sensor_to_xyz(channel_qe(project.sensor, SENSOR_SPECTRAL_GRID_NM), SENSOR_SPECTRAL_GRID_NM,
                               project.isp.max_condition, preserve_white=project.isp.colour_transform == "macbeth_d65_wp")
    np.testing.assert_allclose(isp.colour_fit.matrix, direct.matrix, rtol=1e-9)
    assert np.abs(isp.srgb[..., 0] - isp.srgb[..., 2]).max() > 0.05          # not grey
