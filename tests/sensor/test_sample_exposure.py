"""The sample camera's own exposure keeps the Macbeth chart's white below clipping (issue 32, item
10: at the paper's rule, mean at 40 % of the swing, 12.4 % of its pixels clipped and 11 of 24
patches came out pure white), while the experiments keep the paper's rule: the exposure sweep and
the detection data read the experiment block, the data set's fingerprint and the committed result
folders are unchanged."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from workbench.detect.data import experiment_sensor
from workbench.pipeline import Pipeline
from workbench.project import load_project
from workbench.sensor import auto_exposure
from workbench.sensor.auto_exposure import describe_exposure, exposure_rule
from workbench.sensor.params import SENSOR_PRESETS

COMMITTED = Path(__file__).resolve().parents[2] / "docs" / "results"
PAPER_RULE = ("mean", 0.4)


def pure_white_patches(srgb: np.ndarray) -> int:
    """Macbeth patches of which most pixels are white in every channel."""
    from workbench.scene.charts import macbeth_layout
    layout = macbeth_layout(srgb.shape[:2])
    white = np.all(srgb >= 254.5 / 255, axis=-1)
    return sum(int(white[layout == k].mean() > 0.5) for k in range(24))


@pytest.fixture(scope="module")
def paper():
    project = load_project("paper_camera")
    return project, Pipeline(project).run()


def test_the_sample_camera_renders_the_chart_without_clipping(paper):
    project, result = paper
    image = result.sensor_image
    clipped_pct = 100 * np.count_nonzero(image.dn >= image.max_dn) / image.dn.size
    assert clipped_pct < 0.5 and pure_white_patches(result.isp.srgb) == 0, (clipped_pct, project.sensor)
    # the rule: its brightest pixel (white 9.5) at 90 % of the swing
    assert (project.sensor.auto_exposure_method, project.sensor.auto_exposure_level) == ("brightest", 0.9)
    assert describe_exposure(project.sensor) == "auto, brightest pixel at 90 % of the swing (at most 10 s)"


def test_at_the_papers_rule_the_same_chart_clips(paper):
    """What the sample showed before (and what the exposure experiment's EV 0 still shows)."""
    project, _ = paper
    pipe = Pipeline(project.updated(sensor=experiment_sensor(project)))
    result = pipe.run()
    image = result.sensor_image
    assert 100 * np.count_nonzero(image.dn >= image.max_dn) / image.dn.size > 10
    assert pure_white_patches(result.isp.srgb) >= 9


def test_the_experiments_keep_the_papers_exposure_rule(paper):
    project, result = paper
    exp = project.experiment
    assert (exp.auto_exposure_method, exp.auto_exposure_level) == PAPER_RULE
    assert experiment_sensor(project) == SENSOR_PRESETS["paper_table1"]          # the sample's sensor before
    assert exposure_rule(*PAPER_RULE) == "mean signal at 40 % of the swing"
    # the exposure sweep's EV 0: the paper's rule on the same frame, longer than the sample's own exposure
    from workbench.experiments.ev_sweep import ev_sweep_job
    from workbench.jobs import run_job
    rate = result.signal_rate_e_per_s
    (ev0,) = run_job(ev_sweep_job(project, rate, result.optical_image.wavelengths_nm, [0.0], thumbnail_width_px=80))
    paper_t = auto_exposure(rate, SENSOR_PRESETS["paper_table1"])
    assert ev0.exposure_s == pytest.approx(paper_t, rel=1e-12)
    assert float(np.mean(result.sensor_image.exposure_s)) < 0.5 * paper_t


def test_the_detection_data_and_the_committed_results_are_unchanged():
    from workbench.datasets.dataset import dataset_fingerprint
    from workbench.render.city_frame import render_city_frame
    quick = load_project("city_detection_quick")
    assert quick.sensor == SENSOR_PRESETS["paper_table1"].updated(rows=240, cols=320, pixel_pitch_um=6.0)
    sensor = experiment_sensor(quick)
    assert (sensor.auto_exposure_method, sensor.auto_exposure_level, sensor.ev_bias) == (*PAPER_RULE, 0.0)
    fingerprint = dataset_fingerprint(quick, "float16", render_city_frame)
    for name in ("budget-standard", "isp-standard", "schedule-study/budget-batch16"):
        doc = json.loads((COMMITTED / name / "results.json").read_text())
        committed = json.loads((COMMITTED / name / "project.json").read_text())
        assert doc["dataset"]["fingerprint"] == fingerprint, name
        assert committed["experiment"] == json.loads(quick.experiment.model_dump_json()), name
    for name in ("city_paper_camera", "city_day_clear_sky", "city_night", "slanted_edge_diffraction_f8"):
        sensor = load_project(name).sensor           # the other samples keep their rules
        assert (sensor.auto_exposure_method, sensor.auto_exposure_level) == PAPER_RULE, name
