"""The benchmarks' one timing helper: wall-clock (time.perf_counter) and process CPU time
(time.process_time, all threads) of calls, medians after a warm-up or a single timed call."""
from __future__ import annotations

import statistics
import time
from typing import Callable, NamedTuple, TypeVar

T = TypeVar("T")


class Times(NamedTuple):
    """Wall-clock and process CPU time (ms). CPU time is the robust figure on a shared machine:
    other processes stretch wall time only."""

    wall_ms: float
    cpu_ms: float


def timed(fn: Callable[[], T]) -> tuple[T, Times]:
    """(fn(), its Times) for one call: for work too slow to repeat (renders, ray-traced references)."""
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    cpu = time.process_time() - c0
    return out, Times(1e3 * (time.perf_counter() - w0), 1e3 * cpu)


def median_times_ms(fn: Callable[[], object], repeats: int) -> Times:
    """Median Times of `repeats` calls after one warm-up call."""
    fn()
    runs = [timed(fn)[1] for _ in range(max(1, repeats))]
    return Times(statistics.median(t.wall_ms for t in runs), statistics.median(t.cpu_ms for t in runs))


def best_wall_ms(fns: dict[str, Callable[[], object]], repeats: int) -> dict[str, float]:
    """Best wall time (ms) of each call after one warm-up each, the calls interleaved so that load
    from other processes hits them alike (the warm-up pays any JIT compilation)."""
    for fn in fns.values():
        fn()
    best = dict.fromkeys(fns, float("inf"))
    for _ in range(max(1, repeats)):
        for name, fn in fns.items():
            best[name] = min(best[name], timed(fn)[1].wall_ms)
    return best
