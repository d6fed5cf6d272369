"""Issue 34, item 5: the probe's internal errors and nameless messages, each a check now. One test
per class: a job's unchecked error, a checkpoint without weights, a full disk during `lens plot`,
dataset-noise's --frames, a frame whose irradiance holds NaN, an exposure too short to measure."""
from __future__ import annotations

import errno
import zipfile

import numpy as np
import pytest

from workbench.cli import main
from workbench.errors import InputFileError, ParameterError, WorkbenchError
from workbench.project import load_project, save_project


@pytest.fixture(scope="module")
def small_set(tmp_path_factory):
    from workbench.detect.synthetic import make_synthetic_dataset
    folder = tmp_path_factory.mktemp("synthetic_set")
    make_synthetic_dataset(folder, frames=3, rows=24, cols=32)
    return folder


@pytest.fixture
def chart_project(tmp_path):
    p = load_project("paper_camera")
    return p.updated(name="small_camera", sensor=p.sensor.updated(rows=60, cols=80))


def _stderr_line(capsys) -> str:
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err + captured.out
    lines = captured.err.strip().splitlines()
    assert lines, captured
    return lines[-1]


def test_a_jobs_unchecked_error_is_an_internal_error_with_its_type(chart_project, tmp_path, capsys, monkeypatch):
    """It read "job … failed: 'model'" with exit 2, as if it were the user's input."""
    import workbench.metrics.study as study
    from workbench.compute import ComputeSpec, run_jobs
    from workbench.compute.local import JobFailed

    def broken(job):
        raise KeyError("model")
    with pytest.raises(JobFailed, match=r"failed: KeyError: 'model'") as bug:
        list(run_jobs(broken, [1], ComputeSpec(workers=0)))
    assert bug.value.is_bug

    def refused(job):
        raise ParameterError("sensor.rows", -1, "must be ≥ 1")
    with pytest.raises(JobFailed, match=r"failed: sensor\.rows: must be ≥ 1") as user:
        list(run_jobs(refused, [1], ComputeSpec(workers=0)))
    assert not user.value.is_bug

    monkeypatch.setattr(study, "measure_design", broken)
    path = save_project(chart_project, tmp_path / "p.json")
    assert main(["study", str(path), "--vary", "sensor.rows=48", "--out", str(tmp_path / "s")]) == 3
    line = _stderr_line(capsys)
    assert "internal error (a bug, not your input)" in line and "KeyError: 'model'" in line


def test_a_checkpoint_without_weights_is_named(tmp_path):
    from workbench.metrics.detection import trained_model
    path = tmp_path / "run.pt"
    with pytest.raises(InputFileError, match=r"run\.pt: holds no trained weights \(no 'model' entry\)"):
        trained_model(path, {"done": True, "config": "{}"}, None, 3, 4)


def test_a_full_disk_during_lens_plot_leaves_no_empty_png_and_names_the_file(tmp_path, capsys, monkeypatch):
    import workbench.files as files

    def full(fd, data):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(files, "_write_all", full)
    out = tmp_path / "plots"
    assert main(["lens", "plot", "dgauss.50mm", "--out", str(out)]) == 2
    line = _stderr_line(capsys)
    assert "layout.png" in line and "No space left on device" in line
    assert [f.name for f in out.iterdir()] == [".workbench.lock"]   # no 0-byte layout.png, no temporary left
                                                                      # (the lock file of one writer a folder stays)


@pytest.mark.parametrize("frames", [-1, 0, 4])
def test_dataset_noise_refuses_frames_outside_the_set(small_set, capsys, frames):
    """--frames -1 measured every frame but the last; 0 ended in an internal error."""
    assert main(["dataset-noise", str(small_set), "--frames", str(frames)]) == 2
    line = _stderr_line(capsys)
    assert "--frames" in line and (f"at most the data set's 3 frames" in line if frames > 0 else "≥ 1" in line)


def test_a_frame_whose_irradiance_holds_nan_is_named(small_set, tmp_path):
    """The optical image holds NaN' named neither the frame nor the file."""
    import shutil

    from workbench.detect.data import DetectionDataset, experiment_sensor, load_signal_rates
    folder = tmp_path / "set"
    shutil.copytree(small_set, folder)
    dataset = DetectionDataset(folder)
    record = dataset.frames[0]
    with zipfile.ZipFile(record.path) as z, np.load(record.path) as npz:
        arrays = {k: npz[k] for k in npz.files}
        names = z.namelist()
    assert "irradiance.npy" in names
    arrays["irradiance"] = np.full(arrays["irradiance"].shape, np.nan, np.float32)
    with open(record.path, "wb") as fh:
        np.savez(fh, **arrays)
    try:
        load_signal_rates(record, experiment_sensor(dataset.project), dataset.fingerprint)
    except WorkbenchError as exc:
        assert isinstance(exc, InputFileError) and record.path.name in str(exc)
    else:
        pytest.fail("a frame of NaN irradiance was read")


def test_an_exposure_too_short_to_measure_names_the_exposure(chart_project, tmp_path, capsys):
    """1e-12 s: the e-SFR said 'a row of the region has no edge (a flat row): choose a region'."""
    path = save_project(chart_project.updated(sensor=chart_project.sensor.updated(exposure_s=1e-12)),
                        tmp_path / "dark.json")
    assert main(["metrics", str(path)]) == 2
    line = _stderr_line(capsys)
    assert "sensor.exposure_s" in line and "too dark" in line and "1e-12" in line


def test_a_colour_chart_the_adc_turns_black_names_the_bit_depth(chart_project, tmp_path, capsys):
    """A 1-bit ADC: 'ΔE: neutral 5 renders black; expose the chart' named no field (the chart was exposed)."""
    path = save_project(chart_project.updated(sensor=chart_project.sensor.updated(bit_depth=1)), tmp_path / "b1.json")
    assert main(["metrics", str(path)]) == 2
    line = _stderr_line(capsys)
    assert "sensor.bit_depth" in line and "neutral 5" in line and "raise bit_depth" in line


def test_a_lens_whose_semi_aperture_overflows_the_tracer_is_refused_by_name(tmp_path, capsys):
    """semi_aperture 1e308 (finite) ended in OverflowError, exit 3 (found by a fuzz of 209 lens files)."""
    import json

    from workbench.resource_dir import RESOURCES
    lens = json.loads((RESOURCES / "lenses" / "dgauss.50mm.json").read_text())
    lens["surfaces"][3]["semi_aperture"] = 1e308
    path = tmp_path / "huge.json"
    path.write_text(json.dumps(lens))
    assert main(["lens", "info", str(path)]) == 2
    line = _stderr_line(capsys)
    assert "huge.json" in line and "semi_aperture_mm=1e+308: must be > 0 and at most 100000 mm" in line
