"""compute.run_jobs on this machine: the spec is checked, and each worker gets its thread budget."""
import math

import pytest
from compute_helpers import thread_budget

from workbench.compute import ComputeSpec, run_jobs
from workbench.errors import ParameterError


def test_every_worker_gets_its_thread_budget():
    (_, budget), = run_jobs(thread_budget, [0], ComputeSpec(workers=1, cpus_per_task=1))
    assert budget == (1, "1", 1)


def test_local_spec_runs_jobs_and_bad_specs_name_the_field():
    assert dict(run_jobs(math.factorial, [3, 4], ComputeSpec(workers=0))) == {3: 6, 4: 24}
    for kwargs, field in (({"backend": "slurm"}, "backend"), ({"workers": -1}, "workers"),
                          ({"address": "auto"}, "address"), ({"cpus_per_task": float("nan")}, "cpus_per_task"),
                          ({"backend": "ray", "gpus_per_task": -1}, "gpus_per_task"),
                          ({"backend": "ray", "address": "nowhere"}, "address"),
                          ({"max_retries": 1000}, "max_retries"), ({"workers": True}, "workers")):
        with pytest.raises(ParameterError, match=field):
            ComputeSpec(**kwargs)
    assert ComputeSpec(backend="ray").task_cpus == 1.0 and ComputeSpec(workers=1).task_cpus >= 1


@pytest.mark.slow
def test_a_pool_worker_killed_mid_frame_is_retried_in_a_fresh_pool(tmp_path, markers):
    from compute_helpers import crash_once_renderer, die

    from workbench.compute import JobFailed
    from workbench.jobs import run_job
    from workbench.project import Project
    from workbench.datasets.dataset import run_dataset
    result = run_job(run_dataset(Project(seed=31), 3, tmp_path, compute=ComputeSpec(workers=2, cpus_per_task=1),
                                 renderer=crash_once_renderer))
    assert sorted(result.rendered) == [0, 1, 2]                        # none missing, none twice
    assert len(list(markers.glob("crash-31-1.*"))) == 2
    with pytest.raises(JobFailed, match=r"job 7 failed after 1 retries; last error: its worker process died"):
        list(run_jobs(die, [7], ComputeSpec(workers=1, max_retries=1)))


def test_budget_cores_are_the_cores_within_the_thread_budget(monkeypatch):
    """The window's render worker and the pixel threads size themselves by it."""
    import os

    from workbench.compute.pixel_threads import BLOCKS, budget_cores, thread_count
    cores = len(os.sched_getaffinity(0))
    monkeypatch.delenv("WORKBENCH_THREADS", raising=False)
    assert budget_cores() == cores and thread_count() == min(BLOCKS, cores)
    monkeypatch.setenv("WORKBENCH_THREADS", "1")
    assert budget_cores() == 1 and thread_count() == 1
    monkeypatch.setenv("WORKBENCH_THREADS", "64")
    assert budget_cores() == cores


def test_row_blocks_run_in_order_and_on_the_calling_thread_when_the_pool_is_busy(monkeypatch):
    import threading

    from workbench.compute import pixel_threads as pt
    monkeypatch.setattr(pt, "thread_count", lambda: 2)
    where = {}

    def block(i, rows):
        where[i] = threading.current_thread().name
        return i, rows.start, rows.stop
    serial = [(i, b.start, b.stop) for i, b in enumerate(pt.row_blocks(480))]
    assert pt.map_row_blocks(block, 480, 480 * 640) == serial
    # Every pool thread busy: the blocks run on the calling thread instead of waiting for them.
    release = threading.Event()
    busy = [pt._executor().submit(release.wait, 10) for _ in range(pt.BLOCKS)]
    try:
        where.clear()
        out = []
        caller = threading.Thread(target=lambda: out.append(pt.map_row_blocks(block, 480, 480 * 640)), name="caller")
        caller.start()
        caller.join(5)
        assert out == [serial] and set(where.values()) == {"caller"}
    finally:
        release.set()
        for job in busy:
            job.result()


@pytest.mark.parametrize("failing", range(4))
def test_an_error_in_any_row_block_reaches_the_caller_after_every_thread_is_done(monkeypatch, failing):
    import threading
    import time

    from workbench.compute import pixel_threads as pt
    monkeypatch.setattr(pt, "thread_count", lambda: 2)
    running = set()

    def block(i, rows):
        running.add(threading.current_thread().name)
        time.sleep(0.005)
        running.discard(threading.current_thread().name)
        if i == failing:
            raise ValueError(f"block {i}")
        return i
    with pytest.raises(ValueError, match=f"block {failing}"):
        pt.map_row_blocks(block, 480, 480 * 640)
    assert not running                        # no block still running once the caller has the error


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="no CPU affinity here")
def test_pool_threads_are_kept_off_the_calling_threads_core():
    import os
    import threading

    from workbench.compute import pixel_threads as pt
    cores = os.sched_getaffinity(0)
    if len(cores) < 2 or pt._sched_getcpu is None:
        pytest.skip("needs two cores and sched_getcpu")
    pt._executor().submit(lambda: None).result()          # at least one pool thread exists
    core = min(cores)
    seen = []

    def caller():
        os.sched_setaffinity(0, {core})                     # this thread only
        pt.keep_helpers_off_this_core()
        seen.extend(os.sched_getaffinity(tid) for tid, _ in list(pt._helpers))
    thread = threading.Thread(target=caller)
    thread.start()
    thread.join(5)
    assert seen and all(mask == cores - {core} for mask in seen)


def test_pool_workers_leave_ctrl_c_to_the_driver():
    """Ctrl-C reaches the terminal's whole process group: a worker interrupted inside a native loop
    (Dr.Jit) reported it as a failed job ('job frame 4 failed', exit 1) instead of a cancel."""
    from compute_helpers import sigint_ignored

    from workbench.compute.local import run_jobs
    assert [ignored for _, ignored in run_jobs(sigint_ignored, [0, 1], workers=1)] == [True, True]
