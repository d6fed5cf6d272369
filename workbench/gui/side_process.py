"""The window's side process: one kept-alive, niced, one-thread worker process (spawned on first
use) for the Python-heavy jobs of its panels — camera metrics, the EMVA characterisation and their
charts — so their Python never holds the window's GIL. A worker thread calls run() and only waits.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures.process import BrokenProcessPool

SIDE_NICE = 10           # the window's threads first when the cores are busy
WARM_CHART_PX = (320, 240)

_POOL = None
_POOL_LOCK = threading.Lock()   # run() is called from several worker threads at once


def side_process():
    """The side process's executor (one worker, started on first use)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor
            _POOL = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=_start, initargs=(os.getpid(),))
        return _POOL


def _start(parent_pid: int) -> None:
    from workbench.compute.local import apply_thread_budget, exit_with_parent
    # not die_with_parent: Linux's parent-death signal follows the *thread* that started the
    # process, here a pool thread of the window that Qt retires after 30 s idle — which killed the
    # kept process and failed the next job with BrokenProcessPool
    exit_with_parent(parent_pid)
    apply_thread_budget(1)
    os.nice(SIDE_NICE)


def run(fn, *args, **kwargs):
    """fn(*args, **kwargs) in the side process (fn and its arguments picklable, Qt-free); blocks,
    so call it from a worker thread. A crashed process fails this job; the next starts a new one."""
    global _POOL
    pool = side_process()
    try:
        return pool.submit(fn, *args, **kwargs).result()
    except BrokenProcessPool:
        with _POOL_LOCK:
            if _POOL is pool:             # not one another thread has started since
                _POOL = None
        raise


def warm(project):
    """Start the side process now and measure `project` in it once, without waiting (the window
    calls this as it opens): the first measurement a user asks for then finds its imports,
    compiled kernels and caches loaded (a cold one took 13 s against 1.2–2.3 s warm). Returns the
    Future; its failure is only logged."""
    from workbench.metrics.charts import measure_and_draw
    future = side_process().submit(measure_and_draw, project, None, WARM_CHART_PX)
    future.add_done_callback(_log_failure)
    return future


def _log_failure(future) -> None:
    if not future.cancelled() and future.exception() is not None:
        import logging
        logging.getLogger(__name__).warning("warming the side process failed: %s", future.exception())


def shutdown() -> None:
    """Stop the side process (the window is closing)."""
    global _POOL
    with _POOL_LOCK:
        pool, _POOL = _POOL, None
    if pool is not None:
        pool.shutdown(wait=False, cancel_futures=True)
