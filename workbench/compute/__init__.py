"""Where work runs: `run_jobs(fn, jobs, spec)` yields (job, result) as jobs finish, on this machine
(local.py: in-process or a spawned process pool) or on a Ray cluster (ray_cluster.py).

Jobs are picklable plain data and fn a module-level function, so a backend only moves them; results
come back to the caller, which alone writes files (atomically), so every backend obeys the same
resume rules."""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Callable, Generator, Iterable, TypeVar

from workbench.compute.local import JobFailed, apply_thread_budget
from workbench.compute.progress import report_progress
from workbench.errors import ParameterError
from workbench.jobs import CancelToken, Progress

J = TypeVar("J")
R = TypeVar("R")
BACKENDS = ("local", "ray")

__all__ = ["BACKENDS", "ComputeSpec", "JobFailed", "apply_thread_budget", "report_progress",
           "run_jobs"]


@dataclass(frozen=True)
class ComputeSpec:
    """Where jobs run and what each may use.

    backend: 'local' (this machine) or 'ray'. workers: local processes (0 = in this process); for
    Ray without an address, the CPUs of the local cluster started for the run. address (Ray only):
    None starts a local cluster, 'auto' joins the one `ray start --head` runs here, 'ray://host:10001'
    a remote one. cpus_per_task / memory_mb_per_task / gpus_per_task: what each task reserves on
    Ray; cpus_per_task is also every task's thread budget (None: 1 on Ray, this machine's CPUs
    shared out among the local workers). max_retries: how often a
    task whose worker died is re-run (errors the job raises itself are never retried).
    max_tasks_per_child: recycle a local worker process after that many jobs."""

    backend: str = "local"
    workers: int = 1
    address: str | None = None
    cpus_per_task: float | None = None
    memory_mb_per_task: float | None = None
    gpus_per_task: float = 0.0
    max_retries: int = 3
    max_tasks_per_child: int | None = None

    def __post_init__(self) -> None:
        if self.backend not in BACKENDS:
            raise ParameterError("backend", self.backend, f"one of {', '.join(BACKENDS)}")
        if isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 0:
            raise ParameterError("workers", self.workers, "an integer ≥ 0 (0 = in this process)")
        if self.backend == "ray" and self.workers < 1 and self.address is None:
            raise ParameterError("workers", self.workers, "≥ 1 when Ray starts a local cluster")
        if self.address is not None and self.backend != "ray":
            raise ParameterError("address", self.address, "only with backend 'ray'")
        if self.address is not None and not (self.address == "auto" or self.address.startswith("ray://")
                                             or ":" in self.address):
            raise ParameterError("address", self.address, "'auto', 'ray://host:port' or 'host:port'")
        for name, low in (("cpus_per_task", 0.0), ("gpus_per_task", -1e-12)):
            value = getattr(self, name)
            if value is None and name == "cpus_per_task":
                continue
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value) and value > low):
                raise ParameterError(name, value, "a finite number " + ("> 0" if low == 0 else "≥ 0"))
        if self.memory_mb_per_task is not None and not (math.isfinite(self.memory_mb_per_task)
                                                        and self.memory_mb_per_task > 0):
            raise ParameterError("memory_mb_per_task", self.memory_mb_per_task, "a finite number > 0 or None")
        if not isinstance(self.max_retries, int) or not 0 <= self.max_retries <= 100:
            raise ParameterError("max_retries", self.max_retries, "an integer from 0 to 100")

    @property
    def task_cpus(self) -> float:
        """CPUs each task reserves (and its thread budget, rounded up)."""
        if self.cpus_per_task is not None:
            return self.cpus_per_task
        if self.backend == "ray":
            return 1.0
        return float(max(1, (os.cpu_count() or 1) // max(1, self.workers)))

    @property
    def threads_per_task(self) -> int:
        return max(1, math.ceil(self.task_cpus))


def run_jobs(fn: Callable[[J], R], jobs: Iterable[J], spec: ComputeSpec | None = None,
             cancel: CancelToken | None = None, task_progress: bool = False
             ) -> Generator[tuple[J, R] | Progress, None, None]:
    """Run fn(job) for every job where `spec` says; yield (job, result) in completion order.

    A job that raises stops the run with JobFailed naming the job (pending jobs are dropped); a
    job whose worker died is retried up to spec.max_retries times, then JobFailed. cancel
    is checked between jobs (JobCancelled). task_progress=True also yields Progress(done, total,
    source=job) items as running jobs call compute.progress.report_progress (process pool and Ray)."""
    spec = spec or ComputeSpec()
    if spec.backend == "ray":
        from workbench.compute.ray_cluster import run_jobs_ray
        return run_jobs_ray(fn, jobs, spec, cancel, task_progress)
    from workbench.compute.local import run_jobs as run_local
    return run_local(fn, jobs, spec.workers, cancel, max_tasks_per_child=spec.max_tasks_per_child,
                     threads_per_worker=spec.threads_per_task if spec.workers else None,
                     task_progress=task_progress, max_retries=spec.max_retries)
