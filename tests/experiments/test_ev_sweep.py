"""EV sweep job: exposures double per EV from the experiment's auto-exposure, the frame equals the
pipeline's at the same settings, and a cancelled sweep returns nothing."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.errors import ParameterError
from workbench.experiments.ev_sweep import ev_sweep_job, ev_values
from workbench.jobs import CancelToken, JobCancelled, run_job
from workbench.pipeline import Pipeline
from workbench.project import load_project


@pytest.fixture(scope="module")
def frame():
    base = load_project("paper_camera")
    project = base.updated(sensor=base.sensor.updated(rows=60, cols=80))
    pipe = Pipeline(project)
    return project, pipe, pipe.signal_rate(), pipe.optical_image().wavelengths_nm


def test_ev_values():
    assert ev_values(-4, 4, 1) == [-4, -3, -2, -1, 0, 1, 2, 3, 4]
    assert ev_values(-1, 1, 0.5) == [-1, -0.5, 0, 0.5, 1]
    for args in ((-4, 4, 0), (4, -4, 1), (-100, 100, 0.01)):
        with pytest.raises(ParameterError):
            ev_values(*args)


def test_sweep_doubles_exposure_and_matches_the_pipeline(frame):
    project, pipe, rate, wl = frame
    points = run_job(ev_sweep_job(project, rate, wl, ev_values(-4, 4, 1), thumbnail_width_px=80))
    assert [p.ev for p in points] == list(range(-4, 5))
    t = np.array([p.exposure_s for p in points])
    np.testing.assert_allclose(t[1:] / t[:-1], 2.0, rtol=1e-9)
    ev0 = points[4]
    assert abs(ev0.mean_level - project.experiment.auto_exposure_level) < 0.05   # 'mean' AE at 0.4
    assert points[0].fraction_clipped == 0.0 and points[-1].fraction_clipped > 0.3
    assert all(b.fraction_clipped >= a.fraction_clipped for a, b in zip(points, points[1:]))
    assert points[0].snr_dB < points[2].snr_dB < points[4].snr_dB
    # EV 0 is the frame the pipeline makes with the experiment's auto-exposure.
    exp = project.experiment
    pipe.set_project(project.updated(sensor=project.sensor.updated(
        auto_exposure_method=exp.auto_exposure_method, auto_exposure_level=exp.auto_exposure_level,
        exposure_s=None, ev_bias=0.0)))
    srgb = (np.clip(pipe.isp_result().srgb, 0, 1) * 255 + 0.5).astype(np.uint8)
    np.testing.assert_array_equal(ev0.thumbnail, srgb)
    assert ev0.exposure_s == pytest.approx(float(np.mean(pipe.sensor_image().exposure_s)))


def test_cancelled_sweep_returns_nothing(frame):
    project, _, rate, wl = frame
    token = CancelToken()
    seen = []

    def on_progress(p):
        seen.append(p)
        if len(seen) == 3:
            token.cancel()
    with pytest.raises(JobCancelled):
        run_job(ev_sweep_job(project, rate, wl, ev_values(-4, 4, 1), token), on_progress)
    assert len(seen) == 3
