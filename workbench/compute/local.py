"""Run a list of independent jobs on this machine: in-process, or in a pool of spawned processes.

The job API is what any backend scales out: a picklable module-level function `fn(job)` and a
list (or lazy iterable) of picklable jobs (plain data). compute.ray_cluster offers the same generator.
Pool workers die with the process that started them (Linux: PR_SET_PDEATHSIG), so a `kill -9` of
the driver leaves no worker rendering on.
"""
from __future__ import annotations

import concurrent.futures as cf
import ctypes
import itertools
import multiprocessing
import os
import signal
import sys
from concurrent.futures.process import BrokenProcessPool
from queue import Empty
from typing import Callable, Generator, Iterable, TypeVar

from workbench.compute.progress import reporting_to
from workbench.errors import InvalidValueError, WorkbenchError
from workbench.jobs import CancelToken, JobCancelled, Progress

J = TypeVar("J")
R = TypeVar("R")

POLL_S = 0.2          # how often a waiting pool checks the cancel token
PR_SET_PDEATHSIG = 1  # linux/prctl.h
THREAD_ENV_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS")
THREAD_BUDGET_ENV = "WORKBENCH_THREADS"      # read by render.variants (Dr.Jit) in this process


class JobFailed(WorkbenchError, RuntimeError):
    """A job raised (or its worker died more often than allowed); the message names the job and the
    last error, the original error is the __cause__. `is_bug`: the job raised an error no check
    made (not a WorkbenchError or OSError), which the command line reports as an internal error."""

    is_bug = False

    @classmethod
    def of(cls, job, exc: BaseException) -> "JobFailed":
        """The failure of `job` by `exc`: its message, with the error's type where it is a bug."""
        bug = not isinstance(exc, (WorkbenchError, OSError))
        failed = cls(f"job {job!r} failed: " + (f"{type(exc).__name__}: {exc}" if bug else str(exc)))
        failed.is_bug = bug
        return failed


def apply_thread_budget(threads: int | None) -> None:
    """Limit this process to `threads` threads in OpenMP/BLAS, torch and Dr.Jit (set before they start)."""
    if not threads:
        return
    for name in (*THREAD_ENV_VARS, THREAD_BUDGET_ENV):
        os.environ[name] = str(threads)
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(threads)
    if "drjit" in sys.modules:
        sys.modules["drjit"].set_thread_count(threads)


def die_with_parent(parent_pid: int) -> None:
    """Ask Linux to SIGKILL this process when its parent dies; exit now if it already has."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    if os.getppid() != parent_pid:          # the parent died before prctl took effect
        os._exit(1)


def exit_with_parent(parent_pid: int, interval_s: float = 0.5) -> None:
    """Exit this process once its parent process has gone (a daemon thread polls for it). For a
    process kept beyond the life of the thread that started it, where die_with_parent's signal
    (sent when that thread ends) would kill it early; it needs the GIL now and then to notice."""
    import threading
    import time

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(interval_s)
        os._exit(1)
    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


_progress_queue = None          # in a pool worker: where report_progress sends (key, done, total)


def _worker_init(parent_pid: int, threads: int | None, progress_queue=None) -> None:
    """A pool worker's set-up. It ignores SIGINT: Ctrl-C in a terminal reaches the whole process
    group, and a worker interrupted inside a native library (Dr.Jit's loop) reported the cancel as
    a failed job ('job frame 4 failed: RuntimeError …', exit 1); the driver alone takes it, lets the
    jobs in flight finish unrecorded and stops (a second Ctrl-C does not wait; its workers die with it)."""
    global _progress_queue
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent_pid)
    apply_thread_budget(threads)
    _progress_queue = progress_queue


def _run_reporting(fn, key: int, job):
    """fn(job) in a pool worker, its report_progress calls sent to the driver as (key, done, total)."""
    with reporting_to(lambda done, total: _progress_queue.put((key, done, total))):
        return fn(job)


def run_jobs(fn: Callable[[J], R], jobs: Iterable[J], workers: int = 1,
             cancel: CancelToken | None = None, *, max_tasks_per_child: int | None = None,
             threads_per_worker: int | None = None, task_progress: bool = False,
             max_retries: int = 3) -> Generator[tuple[J, R] | Progress, None, None]:
    """Run fn(job) for every job; yield (job, result) as each one finishes (completion order).

    workers = 0 runs the jobs here, one after another (no pickling; for debugging and tests).
    workers ≥ 1 runs them in that many processes started with 'spawn' (each imports what fn needs
    itself, e.g. mitsuba; no state is inherited by forking); fn must be a module-level function
    and jobs picklable. Jobs are drawn from `jobs` lazily (at most 2 × workers ahead).
    max_tasks_per_child recycles a worker process after that many jobs (to bound slow leaks in
    native libraries); threads_per_worker is each worker's thread budget (OpenMP, torch, Dr.Jit).
    cancel is checked between jobs: once set, no further job starts, jobs already running are
    waited for (their results are not yielded) and JobCancelled is raised.
    A job that raises stops the run (pending jobs are dropped) with JobFailed naming the job. When
    a worker process dies, the jobs in flight are re-run in a fresh pool, each at most max_retries
    times, then JobFailed names the job and the last error. task_progress=True (pool only) also yields Progress(done, total, source=job) as running jobs call
    compute.progress.report_progress.
    """
    if not isinstance(workers, int) or workers < 0:
        raise InvalidValueError(f"workers must be an integer ≥ 0 (0 = in this process), got {workers!r}")
    if max_tasks_per_child is not None and max_tasks_per_child < 1:
        raise InvalidValueError(f"max_tasks_per_child must be ≥ 1 or None, got {max_tasks_per_child}")
    if workers == 0:
        for job in jobs:
            if cancel is not None:
                cancel.check()
            try:
                result = fn(job)
            except Exception as exc:
                raise JobFailed.of(job, exc) from exc
            yield job, result
        return
    yield from _run_pool(fn, iter(jobs), workers, cancel, max_tasks_per_child, threads_per_worker,
                         task_progress, max_retries)


def _run_pool(fn, jobs, workers, cancel, max_tasks_per_child, threads, task_progress, max_retries):
    context = multiprocessing.get_context("spawn")
    queue = context.Queue() if task_progress else None

    def new_pool():
        return cf.ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                      max_tasks_per_child=max_tasks_per_child,
                                      initializer=_worker_init, initargs=(os.getpid(), threads, queue))
    pool = new_pool()
    pending: dict[cf.Future, int] = {}        # future → key of the job it runs
    keys: dict[int, object] = {}              # running (or to be re-run) jobs by key
    deaths: dict[int, int] = {}               # key → how often a worker died running it
    retry: list[int] = []
    counter = itertools.count()

    def submit(key):
        call = (_run_reporting, fn, key, keys[key]) if queue is not None else (fn, keys[key])
        pending[pool.submit(*call)] = key
    try:
        exhausted = False
        while True:
            while (retry or not exhausted) and len(pending) < 2 * workers and not (cancel and cancel.cancelled):
                if retry:
                    submit(retry.pop(0))
                    continue
                job = next(jobs, _END)
                if job is _END:
                    exhausted = True
                else:
                    key = next(counter)
                    keys[key] = job
                    submit(key)
            if cancel is not None and cancel.cancelled:
                raise JobCancelled("cancelled")
            if not pending:
                return
            done, _ = cf.wait(pending, timeout=POLL_S, return_when=cf.FIRST_COMPLETED)
            if queue is not None:
                yield from _drain(queue, keys)
            broken = None
            for fut in done:
                key = pending.pop(fut)
                try:
                    result = fut.result()
                except BrokenProcessPool as exc:      # a worker died (killed, out of memory, crash)
                    broken = exc
                    retry.append(key)
                    continue
                except Exception as exc:
                    raise JobFailed.of(keys[key], exc) from exc
                yield keys.pop(key), result
            if broken is not None:
                # Every job in flight went down with the pool: each counts one death, then a fresh pool.
                retry += list(pending.values())
                pending.clear()
                for key in retry:
                    deaths[key] = deaths.get(key, 0) + 1
                    if deaths[key] > max_retries:
                        raise JobFailed(f"job {keys[key]!r} failed after {max_retries} retries; last error: "
                                        f"its worker process died ({broken})") from broken
                pool.shutdown(wait=True, cancel_futures=True)
                pool = new_pool()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        if queue is not None:
            queue.close()


def _drain(queue, keys: dict):
    """Progress (source = the job) for every report waiting in the queue from a job still running."""
    while True:
        try:
            key, done, total = queue.get_nowait()
        except Empty:
            return
        if key in keys:
            yield Progress(done, total, source=keys[key])


_END = object()
