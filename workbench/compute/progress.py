"""Progress from inside a running job back to whoever runs it.

A job calls `report_progress(done, total)` as it goes (a frame: samples per pixel rendered so far);
the backend running it delivers `TaskProgress(job, done, total)` to the caller of
`run_jobs(..., task_progress=True)`. Outside such a run the call does nothing."""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable

_sink: Callable[[float, float], None] | None = None


@dataclass(frozen=True)
class TaskProgress:
    """`done` of `total` steps of a job that is still running."""

    job: object
    done: float
    total: float

    @property
    def fraction(self) -> float:
        return 0.0 if self.total <= 0 else min(1.0, self.done / self.total)


def report_progress(done: float, total: float) -> None:
    """Tell the runner of the current job how far it is (cheap; a no-op outside a reporting run)."""
    if _sink is not None:
        _sink(float(done), float(total))


@contextmanager
def reporting_to(sink: Callable[[float, float], None]):
    """Send report_progress calls made in the body to sink(done, total)."""
    global _sink
    previous, _sink = _sink, sink
    try:
        yield
    finally:
        _sink = previous
