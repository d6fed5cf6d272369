"""Resumable data sets and the local job runner: a cancelled, damaged run resumes to the same
arrays as an uninterrupted one; storage error bounds; seeds; the process pool."""
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from labels_helpers import session_renderer, tiny_renderer

from workbench.compute.local import JobFailed, run_jobs
from workbench.errors import OutputPathError, ParameterError
from workbench.jobs import CancelToken, JobCancelled, run_job
from workbench.project import Project
from workbench.scene.city.recipe import PoseParams
from workbench.render.city_frame import FrameData, frame_optical_image, frame_seeds
from workbench.datasets.dataset import (FLOAT16_REL_ERROR, FRAME_FORMAT, dataset_fingerprint,
                                      decode_irradiance, encode_irradiance, frame_path, read_frame,
                                      run_dataset, write_frame)
from workbench.render.labels import Labels


def drive_until(gen, cancel=None, cancel_after_rendered=None):
    """Run a data-set job; set `cancel` once that many frames were rendered in this run."""
    rendered = 0
    while True:
        try:
            p = next(gen)
        except StopIteration as stop:
            return stop.value
        if p.message.startswith("frame "):
            rendered += 1
            if cancel_after_rendered is not None and rendered >= cancel_after_rendered:
                cancel.cancel()


def assert_same_frames(dir_a, dir_b, n):
    for i in range(n):
        with np.load(frame_path(dir_a, i)) as za, np.load(frame_path(dir_b, i)) as zb:
            assert set(za.files) == set(zb.files)
            for k in za.files:
                if k == "header_json":
                    ha, hb = json.loads(str(za[k])), json.loads(str(zb[k]))
                    assert ha == hb
                else:
                    a, b = za[k], zb[k]
                    assert a.dtype == b.dtype and a.shape == b.shape
                    assert a.tobytes() == b.tobytes(), f"frame {i} array {k} differs"


def test_frame_seeds_are_reproducible_and_distinct():
    assert frame_seeds(7, 3) == frame_seeds(7, 3)
    seeds = {frame_seeds(7, i) for i in range(50)} | {frame_seeds(8, i) for i in range(50)}
    assert len({(s.arrangement, s.pose, s.render) for s in seeds}) == 100
    with pytest.raises(ValueError, match="index"):
        frame_seeds(0, -1)


def test_float16_storage_error_bound():
    rng = np.random.default_rng(1)
    irr = (10.0 ** rng.uniform(10, 17, size=(20, 30, 5))).astype(np.float32)   # 10^7 : 1
    irr[0, 0, 0] = 0.0
    stored, scale = encode_irradiance(irr, "float16")
    assert stored.dtype == np.float16 and math.log2(scale).is_integer()
    assert 2 ** 14 < stored.max() <= 2 ** 15
    back = decode_irradiance(stored, scale)
    big = irr >= irr.max() * 2.0 ** -28
    assert np.all(np.abs(back[big] / irr[big] - 1) <= FLOAT16_REL_ERROR)
    assert np.all(np.abs(back[~big] - irr[~big]) <= 2.0 ** -25 * scale)
    exact, one = encode_irradiance(irr, "float32")
    assert one == 1.0 and np.array_equal(exact, irr)
    zeros, s0 = encode_irradiance(np.zeros((2, 2, 1)), "float16")
    assert s0 == 1.0 and not zeros.any()
    with pytest.raises(ValueError, match="NaN/Inf or negative"):
        encode_irradiance(np.full((1, 1, 1), np.nan), "float16")
    with pytest.raises(ValueError, match="allowed: float16, float32"):
        encode_irradiance(irr, "int8")


def test_cancelled_and_damaged_run_resumes_to_the_uninterrupted_result(tmp_path):
    project = Project(seed=5)
    n = 4
    full = drive_until(run_dataset(project, n, tmp_path / "a", workers=0, renderer=tiny_renderer))
    assert full.rendered == [0, 1, 2, 3] and full.reused == []

    out = tmp_path / "b"
    cancel = CancelToken()
    with pytest.raises(JobCancelled):
        drive_until(run_dataset(project, n, out, workers=0, cancel=cancel, renderer=tiny_renderer),
                    cancel, cancel_after_rendered=2)
    assert not (out / "manifest.json").exists() and not (out / "coco.json").exists()
    assert frame_path(out, 1).exists() and not frame_path(out, 2).exists()
    # Damage: a half-written temporary file and a truncated "complete" frame.
    half = frame_path(out, 2).with_name(".frame_000002.npz.4242.tmp")
    half.write_bytes(b"PK\x03\x04 half a zip")
    raw = frame_path(out, 1).read_bytes()
    frame_path(out, 1).write_bytes(raw[: len(raw) // 2])

    resumed = drive_until(run_dataset(project, n, out, workers=0, renderer=tiny_renderer))
    assert resumed.reused == [0] and sorted(resumed.rendered) == [1, 2, 3]
    assert not half.exists() and not list((out / "frames").glob(".*.tmp"))
    assert_same_frames(tmp_path / "a", out, n)
    assert json.loads((out / "coco.json").read_text()) == json.loads((tmp_path / "a" / "coco.json").read_text())

    again = drive_until(run_dataset(project, n, out, workers=0, renderer=tiny_renderer))
    assert again.reused == [0, 1, 2, 3] and again.rendered == []
    man = json.loads((out / "manifest.json").read_text())
    assert [f["index"] for f in man["frames"]] == [0, 1, 2, 3]
    assert man["frames"][2]["seeds"]["render"] == frame_seeds(5, 2).render
    assert man["project"]["seed"] == 5 and man["code_version"]
    # The frames differ from each other (arrangement and pose seeds are used).
    f0, _ = read_frame(frame_path(out, 0))
    f1, _ = read_frame(frame_path(out, 1))
    assert f0.meta["shift_m"] != f1.meta["shift_m"]
    assert not np.array_equal(f0.labels.instance_id, f1.labels.instance_id)
    assert {o.class_name for o in f0.labels.objects} >= {"car", "pedestrian"}
    assert np.isfinite(f0.irradiance_photons).all() and f0.irradiance_photons.max() > 0


def test_out_dir_of_another_project_is_refused(tmp_path):
    drive_until(run_dataset(Project(seed=1), 1, tmp_path, workers=0, renderer=tiny_renderer))
    with pytest.raises(OutputPathError, match=r"different project or settings \(seed\)"):
        run_job(run_dataset(Project(seed=2), 1, tmp_path, workers=0, renderer=tiny_renderer))
    spec_path = tmp_path / "dataset_spec.json"
    spec = json.loads(spec_path.read_text())
    spec["fingerprint"] = "0" * 64                       # same settings, frames of an older renderer
    spec_path.write_text(json.dumps(spec))
    with pytest.raises(OutputPathError, match="same settings by an earlier version of the frame renderer"):
        run_job(run_dataset(Project(seed=1), 1, tmp_path, workers=0, renderer=tiny_renderer))
    with pytest.raises(ParameterError, match="frames: an integer"):
        run_job(run_dataset(Project(), 0, tmp_path / "x", renderer=tiny_renderer))


def test_run_jobs_in_process_and_errors():
    assert sorted(r for _, r in run_jobs(math.factorial, [3, 4, 5], workers=0)) == [6, 24, 120]
    with pytest.raises(JobFailed, match="job -1 failed"):
        list(run_jobs(math.factorial, [2, -1], workers=0))
    with pytest.raises(ValueError, match="workers"):
        list(run_jobs(math.factorial, [1], workers=-1))
    cancel = CancelToken()
    cancel.cancel()
    with pytest.raises(JobCancelled):
        list(run_jobs(math.factorial, [1], workers=0, cancel=cancel))


def test_run_jobs_process_pool():
    results = dict(run_jobs(math.factorial, range(8), workers=2))
    assert results == {i: math.factorial(i) for i in range(8)}
    with pytest.raises(JobFailed, match="job -3 failed"):
        list(run_jobs(math.factorial, [1, -3, 2], workers=2))
    cancel = CancelToken()
    got = []
    with pytest.raises(JobCancelled):
        for job, res in run_jobs(math.factorial, range(100), workers=1, cancel=cancel):
            got.append(job)
            cancel.cancel()
    assert 0 < len(got) < 100


@pytest.mark.slow
def test_process_pool_dataset_matches_in_process(tmp_path):
    project = Project(seed=9)
    drive_until(run_dataset(project, 2, tmp_path / "serial", workers=0, renderer=tiny_renderer))
    pooled = drive_until(run_dataset(project, 2, tmp_path / "pool", workers=2, renderer=tiny_renderer))
    assert sorted(pooled.rendered) == [0, 1]
    assert_same_frames(tmp_path / "serial", tmp_path / "pool", 2)



def test_fingerprint_ignores_settings_that_do_not_change_frames():
    base = Project(seed=1)
    fp = ds_fingerprint(base)
    experiment = base.experiment.model_copy(update={"ev_biases": [0.0, 1.0]})
    assert ds_fingerprint(base.model_copy(update={"name": "other", "experiment": experiment})) == fp
    sensor = base.sensor.model_copy(update={"read_noise_V": 0.002})
    assert ds_fingerprint(base.model_copy(update={"sensor": sensor})) == fp
    assert ds_fingerprint(base.model_copy(update={"seed": 2})) != fp
    sensor = base.sensor.model_copy(update={"cols": base.sensor.cols + 2})
    assert ds_fingerprint(base.model_copy(update={"sensor": sensor})) != fp


def ds_fingerprint(project):
    return dataset_fingerprint(project, "float16", tiny_renderer)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 12.0), st.floats(-30.0, 30.0))
def test_float16_storage_bound_holds_for_any_range(seed, decades, log10_peak):
    rng = np.random.default_rng(seed)
    irr = (10.0 ** (log10_peak - rng.uniform(0, decades, size=(6, 7, 3)))).astype(np.float32)
    irr[rng.random(irr.shape) < 0.1] = 0.0
    stored, scale = encode_irradiance(irr, "float16")
    back = decode_irradiance(stored, scale)
    assert np.isfinite(back).all() and back.dtype == np.float32
    big = irr >= irr.max() * 2.0 ** -28
    assert np.all(np.abs(back[big] - irr[big]) <= FLOAT16_REL_ERROR * irr[big])
    assert np.all(np.abs(back[~big] - irr[~big]) <= 2.0 ** -25 * scale)


@pytest.mark.slow
def test_run_killed_with_sigkill_resumes_to_the_same_frames(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    here = Path(__file__).resolve().parent
    script = (f"import sys; sys.path.insert(0, {str(here)!r})\n"
              "from labels_helpers import session_renderer, tiny_renderer\n"
              "from workbench.project import Project\n"
              "from workbench.datasets.dataset import run_dataset\n"
              f"for p in run_dataset(Project(seed=5), 4, {str(tmp_path / 'k')!r}, workers=0,\n"
              "                      renderer=tiny_renderer):\n"
              "    print(p.message, flush=True)\n")
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    rendered = 0
    for line in proc.stdout:
        rendered += line.startswith("frame ")
        if rendered == 2:
            proc.kill()                      # SIGKILL: no cleanup code runs
            break
    proc.wait(timeout=60)
    assert proc.returncode != 0 and not (tmp_path / "k" / "manifest.json").exists()
    resumed = drive_until(run_dataset(Project(seed=5), 4, tmp_path / "k", workers=0,
                                      renderer=tiny_renderer))
    assert len(resumed.reused) >= 2
    drive_until(run_dataset(Project(seed=5), 4, tmp_path / "ref", workers=0, renderer=tiny_renderer))
    assert_same_frames(tmp_path / "ref", tmp_path / "k", 4)


def test_stored_frame_becomes_an_optical_image(tmp_path):
    h, w = 3, 4
    labels = Labels(np.ones((h, w), np.float32), np.ones((h, w), np.float32),
                    np.zeros((h, w), np.int32), np.zeros((h, w), np.int32), [], {})
    irr = np.full((h, w, 2), 1e15, np.float32)
    meta = {"sample_spacing_m": 3e-6, "focal_length_m": 2.4e-3, "f_number": 4.0}
    write_frame(tmp_path / "f.npz", FrameData(irr, np.array([500.0, 600.0]), labels, meta),
                {"format": FRAME_FORMAT, "index": 0}, "float32")
    oi = frame_optical_image(read_frame(tmp_path / "f.npz")[0])
    assert oi.shape == (h, w) and oi.sample_spacing_m == 3e-6 and oi.f_number == 4.0
    np.testing.assert_array_equal(oi.irradiance_photons, irr)
    with pytest.raises(ValueError, match="lacks"):
        frame_optical_image(FrameData(irr, np.array([500.0, 600.0]), labels, {}))


def test_frames_of_a_city_share_its_arrangement_and_nothing_else():
    seeds = [frame_seeds(7, i, 3) for i in range(9)]
    assert [s.city for s in seeds] == [0, 0, 0, 1, 1, 1, 2, 2, 2]
    for c in range(3):
        group = seeds[3 * c:3 * c + 3]
        assert len({s.arrangement for s in group}) == 1
        assert len({s.pose for s in group}) == 3 and len({s.render for s in group}) == 3
        assert group[0].arrangement == frame_seeds(7, 3 * c).arrangement     # its first frame's
    assert len({s.arrangement for s in seeds}) == 3
    assert [frame_seeds(7, i, 3).pose for i in range(9)] == [frame_seeds(7, i).pose for i in range(9)]
    with pytest.raises(ValueError, match="poses_per_arrangement"):
        frame_seeds(0, 0, 0)


def test_a_city_job_renders_its_frames_through_one_session(tmp_path):
    project = Project(seed=3, pose=PoseParams(poses_per_arrangement=3))
    result = drive_until(run_dataset(project, 7, tmp_path, workers=0, renderer=session_renderer))
    assert sorted(result.rendered) == list(range(7))
    heads = [read_frame(frame_path(tmp_path, i), irradiance=False)[1] for i in range(7)]
    sessions = [h["meta"]["session"] for h in heads]
    assert sessions[0] == sessions[1] == sessions[2] != sessions[3]
    assert sessions[3] == sessions[4] == sessions[5] != sessions[6]
    assert [h["seeds"]["city"] for h in heads] == [0, 0, 0, 1, 1, 1, 2]
    assert [h["meta"]["frame_in_session"] for h in heads] == [0, 1, 2, 0, 1, 2, 0]
    frame_path(tmp_path, 4).unlink()                          # a resumed city renders only what is missing
    again = drive_until(run_dataset(project, 7, tmp_path, workers=0, renderer=session_renderer))
    assert again.rendered == [4]
    assert read_frame(frame_path(tmp_path, 4), irradiance=False)[1]["meta"]["frame_in_session"] == 0
