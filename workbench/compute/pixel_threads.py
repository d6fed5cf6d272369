"""Row blocks of a frame run in threads, for compiled per-pixel kernels that release the GIL.

A frame is always cut into the same BLOCKS row blocks, so a result never depends on how many
threads ran them (the sensor seeds its noise per block); large frames run their blocks in a few
threads of this process, at most the thread budget (WORKBENCH_THREADS, see compute.local) or the
cores this process may use. The threads take the blocks one at a time as they come free, the
calling thread among them: a helper that waits for a core (a busy machine) leaves its share to
the others instead of holding them up at the end.

Before each frame the pool threads are kept off the calling thread's core (CPU affinity): left
to itself the scheduler on this project's 2-core VM often woke a helper on the caller's core,
where the two ran by turns for the ~1 ms of a block while the other core idled.
"""
from __future__ import annotations

import ctypes
import itertools
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache
from typing import Callable, TypeVar

from workbench.compute.local import THREAD_BUDGET_ENV

R = TypeVar("R")

BLOCKS = 4
"""Row blocks per frame: fixed, so results do not depend on the number of threads; more blocks
than threads, so that a thread that starts late takes fewer of them."""
PARALLEL_MIN_PIXELS = 1 << 16
"""Frames smaller than this run their blocks one after the other on the calling thread."""

_pool: ThreadPoolExecutor | None = None
_pool_pid = -1
_pool_lock = threading.Lock()
_helpers: list[tuple[int, set[int]]] = []   # the pool's threads: (native id, cores allowed at start)


def _libc_sched_getcpu() -> Callable[[], int] | None:
    """glibc's sched_getcpu (the core the calling thread runs on), or None where there is none."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    try:
        fn = ctypes.CDLL(None).sched_getcpu
    except (OSError, AttributeError):
        return None
    fn.restype = ctypes.c_int
    fn.argtypes = []
    return fn


_sched_getcpu = _libc_sched_getcpu()


def budget_cores() -> int:
    """The cores this process may use (CPU affinity), at most the thread budget where one is set."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    try:
        budget = int(os.environ.get(THREAD_BUDGET_ENV, "0"))
    except ValueError:
        budget = 0
    return max(1, min(cores, budget) if budget > 0 else cores)


def thread_count() -> int:
    """Threads a frame may use: BLOCKS, or fewer where the budget or the CPU affinity is smaller."""
    return min(BLOCKS, budget_cores())


def _executor() -> ThreadPoolExecutor:
    """The worker threads, created on first use and again in a forked child (whose copy of the
    pool has no threads)."""
    global _pool, _pool_pid
    with _pool_lock:
        if _pool is None or _pool_pid != os.getpid():
            _helpers.clear()
            _pool = ThreadPoolExecutor(max_workers=BLOCKS, thread_name_prefix="pixels",
                                       initializer=_register_helper)
            _pool_pid = os.getpid()
        return _pool


def _register_helper() -> None:
    cores = os.sched_getaffinity(0) if _sched_getcpu is not None else set()
    with _pool_lock:
        _helpers.append((threading.get_native_id(), cores))


def keep_helpers_off_this_core() -> None:
    """Let each pool thread run on the cores it started with but the one this thread runs on now
    (no change where the platform cannot say which core, or a pool thread has no other)."""
    cpu = -1 if _sched_getcpu is None else _sched_getcpu()
    if cpu < 0:
        return
    with _pool_lock:
        helpers = list(_helpers)
    for tid, cores in helpers:
        others = cores - {cpu}
        if not others:
            continue
        try:
            os.sched_setaffinity(tid, others)
        except OSError:                  # a thread that has ended, or a core taken away meanwhile
            pass


def row_blocks(rows: int) -> list[slice]:
    """The BLOCKS row ranges of a frame of `rows` rows (some empty when rows < BLOCKS)."""
    return list(_row_blocks(rows))


@lru_cache(maxsize=64)
def _row_blocks(rows: int) -> tuple[slice, ...]:
    return tuple(slice(rows * i // BLOCKS, rows * (i + 1) // BLOCKS) for i in range(BLOCKS))


def map_row_blocks(fn: Callable[[int, slice], R], rows: int, pixels: int) -> list[R]:
    """[fn(i, block i) for each row block], in threads when the frame has `pixels` ≥
    PARALLEL_MIN_PIXELS and more than one thread is allowed. fn must release the GIL to gain.

    The calling thread and thread_count() − 1 pool threads each take the next block not yet
    taken until none is left; a pool thread that has not started by then (every pool thread
    busy, or no core free) is not waited for."""
    blocks = row_blocks(rows)
    threads = thread_count()
    if pixels < PARALLEL_MIN_PIXELS or threads == 1:
        return [fn(i, block) for i, block in enumerate(blocks)]
    results: list = [None] * len(blocks)
    claims = itertools.count()                  # its next() is atomic: each block is taken once

    def take_blocks() -> None:
        while (i := next(claims)) < len(blocks):
            results[i] = fn(i, blocks[i])
    executor = _executor()
    keep_helpers_off_this_core()
    helpers = [executor.submit(take_blocks) for _ in range(threads - 1)]
    try:
        take_blocks()
    finally:
        for helper in helpers:
            if not helper.cancel():
                helper.result()
    return results
