"""Timing for benchmarks: medians of wall-clock and process CPU time after a warm-up call."""
from __future__ import annotations

import statistics
import time
from typing import Callable


def median_times_ms(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """(median wall ms, median process-CPU ms, all threads) of `repeats` calls after one warm-up.

    CPU time is the robust figure on a shared machine: other processes stretch wall time only."""
    fn()
    wall, cpu = [], []
    for _ in range(max(1, repeats)):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    return 1e3 * statistics.median(wall), 1e3 * statistics.median(cpu)
