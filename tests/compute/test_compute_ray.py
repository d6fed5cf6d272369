"""The Ray backend on a real local cluster (2 CPUs): the same bytes as the local backend, a worker
killed mid-frame is retried, a bad project fails fast naming the field, a killed driver resumes."""
import hashlib
import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from compute_helpers import (bad_project_renderer, crash_once_renderer, progress_renderer, slow_renderer,
                             thread_budget, tiny_renderer)

from workbench.compute import ComputeSpec, JobFailed, run_jobs
from workbench.errors import ParameterError
from workbench.jobs import run_job
from workbench.project import Project
from workbench.datasets.dataset import FRAMES_DIR, frame_path, run_dataset

N = 3
RAY = ComputeSpec(backend="ray")


def frame_digests(out, n):
    return [hashlib.sha256(frame_path(out, i).read_bytes()).hexdigest() for i in range(n)]


def frame_contents(out, n):
    """Every array of every frame as bytes, the header without the fingerprint (which names the
    renderer function, so differs between the test renderers that draw the same frames)."""
    frames = []
    for i in range(n):
        with np.load(frame_path(out, i)) as z:
            arrays = {k: z[k].tobytes() for k in z.files if k != "header_json"}
            head = json.loads(str(z["header_json"]))
        head.pop("fingerprint")
        frames.append((arrays, head))
    return frames


def messages(job):
    """Drive a data-set job; return (result, progress messages)."""
    seen = []
    result = run_job(job, lambda p: seen.append(p.message))
    return result, seen


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The 3-frame set rendered in this process (local backend, no pool)."""
    out = tmp_path_factory.mktemp("reference")
    run_job(run_dataset(Project(seed=21), N, out, workers=0, renderer=tiny_renderer))
    return out


def test_ray_backend_writes_the_same_bytes_as_the_local_backend(ray_cluster, reference, tmp_path):
    result, seen = messages(run_dataset(Project(seed=21), N, tmp_path, compute=RAY,
                                        renderer=tiny_renderer))
    assert sorted(result.rendered) == list(range(N)) and result.reused == []
    assert sum(m.startswith("frame ") for m in seen) == N          # streamed, one per finished frame
    assert frame_digests(tmp_path, N) == frame_digests(reference, N)
    assert (tmp_path / "coco.json").read_bytes() == (reference / "coco.json").read_bytes()
    assert not list((tmp_path / FRAMES_DIR).glob(".*"))


def test_worker_killed_mid_frame_is_retried_and_the_set_completes(ray_cluster, reference, tmp_path,
                                                                     markers):
    result = run_job(run_dataset(Project(seed=21), N, tmp_path, compute=RAY,
                                 renderer=crash_once_renderer))
    assert sorted(result.rendered) == list(range(N))                   # none missing, none twice
    assert len(list(markers.glob("crash-21-1.*"))) == 2                # killed once, then retried
    assert frame_contents(tmp_path, N) == frame_contents(reference, N)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert [f["index"] for f in manifest["frames"]] == list(range(N))


def test_bad_project_fails_fast_naming_the_field(ray_cluster, tmp_path, markers):
    t0 = time.monotonic()
    with pytest.raises(ParameterError, match=r"scene\.kind"):                  # not a city: refused up front
        run_job(run_dataset(Project(seed=3), 2, tmp_path / "real", compute=RAY))
    assert time.monotonic() - t0 < 30 and not (tmp_path / "real").exists()
    with pytest.raises(JobFailed, match="render.band_count"):
        run_job(run_dataset(Project(seed=4), 2, tmp_path / "counted", compute=RAY,
                            renderer=bad_project_renderer))
    attempts = list(markers.glob("bad-4-*"))
    assert 1 <= len(attempts) <= 2 and len({a.name.split(".")[0] for a in attempts}) == len(attempts)
    assert not (tmp_path / "counted" / "manifest.json").exists()


def test_worker_that_always_dies_gives_up_after_the_retries(ray_cluster):
    with pytest.raises(JobFailed, match=r"job 3 failed after 1 retries; last error: \w+"):
        list(run_jobs(_die, [3], ComputeSpec(backend="ray", max_retries=1)))


def _die(job):
    os.kill(os.getpid(), signal.SIGKILL)


def test_ray_run_jobs_streams_results_and_checks_its_options(ray_cluster):
    got = dict(run_jobs(math.factorial, range(6), RAY))
    assert got == {i: math.factorial(i) for i in range(6)}
    (_, budget), = run_jobs(thread_budget, [0], ComputeSpec(backend="ray", cpus_per_task=1))
    assert budget == (1, "1", 1)                     # Dr.Jit, OpenMP and torch keep to the task's CPUs
    with pytest.raises(JobFailed, match="has no GPU"):
        list(run_jobs(math.factorial, [1], ComputeSpec(backend="ray", gpus_per_task=1)))


@pytest.mark.slow
def test_driver_killed_mid_run_resumes_from_disk(ray_cluster, reference, tmp_path):
    """A second driver joins the cluster, is SIGKILLed after its first frame, and a rerun finishes."""
    address = ray_cluster.get_runtime_context().gcs_address
    out = tmp_path / "killed"
    script = ("import os\n"
              "from compute_helpers import slow_renderer\n"
              "from workbench.compute import ComputeSpec\n"
              "from workbench.project import Project\n"
              "from workbench.datasets.dataset import run_dataset\n"
              f"job = run_dataset(Project(seed=21), {N}, {str(out)!r}, renderer=slow_renderer,\n"
              f"                  compute=ComputeSpec(backend='ray', address={address!r}))\n"
              "for p in job:\n"
              "    print(p.message, flush=True)\n")
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    for line in proc.stdout:
        if line.startswith("frame "):
            proc.kill()
            break
    proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL and not (out / "manifest.json").exists()
    written = sorted(p.name for p in (out / FRAMES_DIR).glob("frame_*.npz"))
    assert 1 <= len(written) < N
    result = run_job(run_dataset(Project(seed=21), N, out, compute=RAY, renderer=slow_renderer))
    assert len(result.reused) == len(written) and sorted(result.reused + result.rendered) == list(range(N))
    assert frame_contents(out, N) == frame_contents(reference, N)


@pytest.mark.parametrize("backend", [pytest.param("local", marks=pytest.mark.slow), "ray"])
def test_frames_in_flight_report_their_progress(backend, tmp_path, request):
    if backend == "ray":
        request.getfixturevalue("ray_cluster")
    spec = ComputeSpec(backend=backend, workers=1)
    seen, seen_flag = [], tmp_path / "part-way-seen"

    def on_progress(p):
        seen.append(p)
        if p.message.startswith("rendering frame") and 0 < p.done % 1:
            seen_flag.touch()                  # the renderer may finish now (progress_renderer)
    project = Project(seed=8, description=str(seen_flag))
    result = run_job(run_dataset(project, 2, tmp_path / "set", compute=spec, renderer=progress_renderer),
                     on_progress)
    assert sorted(result.rendered) == [0, 1]
    live = [p for p in seen if p.message.startswith("rendering frame")]
    assert live and any(0 < p.done % 1 for p in live)                # a frame part-way counts part-way
    done = [p.done for p in seen if not p.message.startswith("checked")]
    assert done == sorted(done) and done[-1] == 2


@pytest.mark.slow
def test_experiment_runs_as_ray_tasks_with_the_in_process_results(ray_cluster, tmp_path):
    """Each training run is one Ray task; the mAPs equal those of the same runs in this process."""
    from dataclasses import replace

    from workbench.detect.synthetic import make_synthetic_dataset, synthetic_project
    from workbench.experiments.detection import PROFILES, run_experiment
    tiny = replace(PROFILES["quick"], name="tiny", image_hw=(48, 64), epochs={"mobile": 1}, crop_hw=None,
                   batch_size=4, curve_points=1)
    make_synthetic_dataset(tmp_path / "data", frames=14)
    project = synthetic_project()
    runs = {}
    for name, spec in (("here", ComputeSpec(workers=0)), ("ray", ComputeSpec(backend="ray", cpus_per_task=1))):
        result = run_job(run_experiment("isp", project, tmp_path / "data", tmp_path / name, seeds=1,
                                        profile_override=tiny, compute=spec))
        assert len(result.trained) == 3
        doc = json.loads((tmp_path / name / "results.json").read_text())
        runs[name] = {r["key"]: [t["map"] for t in r["tests"]] for r in doc["runs"]}
    assert runs["ray"] == runs["here"]
