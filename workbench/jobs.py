"""Long-job protocol (DESIGN.md §3): a job is a generator that yields Progress, checks a
CancelToken between steps, and returns its result. The command line drives it with a progress
bar, the GUI from a worker thread."""
from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Callable, Generator, TypeVar

T = TypeVar("T")


@dataclass(frozen=True)
class Progress:
    """done of total steps, and what is being done; preview: an optional partial result the
    window may show (e.g. a render's H×W×Nλ radiance so far), None when there is none; source:
    the job the step belongs to, when a runner of several jobs passes on their progress
    (workbench.compute.run_jobs with task_progress=True), else None."""

    done: float
    total: float
    message: str = ""
    preview: object = field(default=None, compare=False, repr=False)
    source: object = field(default=None, compare=False, repr=False)

    @property
    def fraction(self) -> float:
        return 0.0 if self.total <= 0 else min(1.0, self.done / self.total)


class JobCancelled(Exception):
    """Raised inside a job when its cancel token was set; the job has cleaned up."""


class CancelToken:
    """Thread-safe cancel flag shared between a job and whoever may stop it."""

    def __init__(self) -> None:
        self._event = threading.Event()

    def cancel(self) -> None:
        self._event.set()

    @property
    def cancelled(self) -> bool:
        return self._event.is_set()

    def is_set(self) -> bool:
        """threading.Event's spelling, so a token works wherever an Event is accepted."""
        return self._event.is_set()

    def check(self) -> None:
        """Raise JobCancelled if cancellation was asked for."""
        if self._event.is_set():
            raise JobCancelled("cancelled")


Job = Generator[Progress, None, T]


def run_job(job: Job, on_progress: Callable[[Progress], None] | None = None) -> T:
    """Drive a job to completion, passing each Progress to on_progress; return its result."""
    while True:
        try:
            progress = next(job)
        except StopIteration as stop:
            return stop.value
        if on_progress is not None:
            on_progress(progress)


def tqdm_progress(desc: str):
    """An on_progress callback that draws a tqdm bar on stderr; call .close() when done."""
    from tqdm import tqdm
    bar = tqdm(total=100, desc=desc, unit="%", leave=False,
               bar_format="{desc}: {percentage:3.0f}%|{bar}| {postfix}")

    def update(p: Progress) -> None:
        bar.n = round(100 * p.fraction)
        bar.set_postfix_str(p.message, refresh=False)
        bar.refresh()
    update.close = bar.close
    return update
