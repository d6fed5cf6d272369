"""Progress from inside a running job back to whoever runs it.

A job calls `report_progress(done, total)` as it goes (a frame: samples per pixel rendered so far);
the backend running it delivers `jobs.Progress(done, total, source=job)` to the caller of
`run_jobs(..., task_progress=True)`. Outside such a run the call does nothing. The sink is per
thread, so jobs run side by side in threads of one process report to their own runners."""
from __future__ import annotations

import threading
from contextlib import contextmanager
from typing import Callable

_local = threading.local()


def report_progress(done: float, total: float) -> None:
    """Tell the runner of the current job how far it is (cheap; a no-op outside a reporting run)."""
    sink = getattr(_local, "sink", None)
    if sink is not None:
        sink(float(done), float(total))


@contextmanager
def reporting_to(sink: Callable[[float, float], None]):
    """Send report_progress calls made in the body (on this thread) to sink(done, total)."""
    previous = getattr(_local, "sink", None)
    _local.sink = sink
    try:
        yield
    finally:
        _local.sink = previous
