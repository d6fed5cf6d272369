"""The pipeline driven from a worker thread while the window edits the project: a run works on
one snapshot, and no stage result is ever stored under a key it was not computed for."""
import functools
import threading

import numpy as np
import pytest

from workbench.pipeline import Pipeline
from workbench.project import load_project
from workbench.scene import charts


def edit(project, section, **changes):
    return project.updated(**{section: getattr(project, section).updated(**changes)})


@pytest.fixture
def project_a():
    p = load_project("paper_camera")
    return edit(edit(p, "sensor", rows=24, cols=32, noise_flag=0), "scene",
                wavelengths=p.scene.wavelengths.updated(step_nm=50.0))


@pytest.fixture
def edit_during_scene(monkeypatch):
    """Make the chart stage wait while `edit()` runs on another thread (the window's edit)."""
    state = {}
    original = charts.CHARTS["macbeth"]

    @functools.wraps(original)                        # the chart stage reads its signature
    def slow_chart(**kw):
        if "edit" in state:
            thread = threading.Thread(target=state.pop("edit"))
            thread.start()
            thread.join()
        return original(**kw)
    monkeypatch.setattr(charts, "CHARTS", {**charts.CHARTS, "macbeth": slow_chart})
    return state


def assert_like_fresh(pipe, project):
    """Every cached result the pipeline serves for `project` equals a fresh pipeline's."""
    pipe.set_project(project)
    got, fresh = pipe.run(), Pipeline(project).run()
    np.testing.assert_array_equal(got.optical_image.irradiance_photons, fresh.optical_image.irradiance_photons)
    np.testing.assert_array_equal(got.signal_rate_e_per_s, fresh.signal_rate_e_per_s)
    np.testing.assert_array_equal(got.sensor_image.dn, fresh.sensor_image.dn)
    np.testing.assert_array_equal(got.isp.srgb, fresh.isp.srgb)


@pytest.mark.parametrize("section, changes", [("sensor", dict(ev_bias=1.0)),
                                              ("optics", dict(off_axis="none")),
                                              ("isp", dict(demosaic="malvar2004"))])
def test_an_edit_during_a_run_never_stores_a_result_under_another_key(project_a, edit_during_scene,
                                                                      section, changes):
    project_b = edit(project_a, section, **changes)
    pipe = Pipeline(project_a)
    edit_during_scene["edit"] = lambda: pipe.set_project(project_b)
    image = pipe.sensor_image()                       # a stage getter runs the upstream stages too
    assert pipe.project is project_b
    fresh_a = Pipeline(project_a).run()
    np.testing.assert_array_equal(image.dn, fresh_a.sensor_image.dn)        # the run saw project A only
    assert_like_fresh(pipe, project_a)
    assert_like_fresh(pipe, project_b)


def test_a_job_returns_the_snapshot_it_started_with(project_a, edit_during_scene):
    project_b = edit(project_a, "sensor", ev_bias=1.0)
    pipe = Pipeline(project_a)
    edit_during_scene["edit"] = lambda: pipe.set_project(project_b)
    result = pipe.run()
    fresh_a = Pipeline(project_a).run()
    np.testing.assert_array_equal(result.sensor_image.dn, fresh_a.sensor_image.dn)
    np.testing.assert_array_equal(result.isp.srgb, fresh_a.isp.srgb)
    pipe.run()                                        # the next run picks up the edit
    assert pipe.recomputed == ["sensor", "isp"]
    assert_like_fresh(pipe, project_b)


def test_runs_from_two_threads_agree_with_fresh_pipelines(project_a):
    projects = [edit(project_a, "sensor", ev_bias=ev) for ev in (-1.0, 0.0, 0.5, 1.0)]
    pipe, errors = Pipeline(projects[0]), []

    def worker(i):
        try:
            for k in range(6):
                pipe.set_project(projects[(i + k) % len(projects)])
                pipe.run()
        except Exception as exc:   # noqa: BLE001  (reported below)
            errors.append(exc)
    threads = [threading.Thread(target=worker, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for p in projects:
        assert_like_fresh(pipe, p)


def test_run_job_stops_early_and_previews_a_stage(project_a):
    from workbench.jobs import run_job
    pipe = Pipeline(project_a)
    result = run_job(pipe.run_job(upto="sensor"))
    assert result.isp is None and result.sensor_image is not None
    assert pipe.recomputed == ["scene", "optics", "signal", "sensor"]
