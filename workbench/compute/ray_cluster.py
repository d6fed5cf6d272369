"""The Ray backend of compute.run_jobs: one Ray task per job, results streamed back as they finish.

Each task reserves spec.cpus_per_task CPUs (also its thread budget), memory and GPUs. A task whose
worker process dies (killed, out of memory, node lost) is re-run by Ray up to spec.max_retries
times; an error the job raises itself (a bad project) is never retried and stops the run at once.
A result travels once, worker → object store → caller, and the caller writes files. Without an
address a private local cluster (no dashboard) is started for the run and shut down after it; with
'auto' or 'ray://…' an existing cluster is joined and left running; a process already connected
to Ray (ray.init was called) keeps its connection.
"""
from __future__ import annotations

import itertools
from typing import Callable, Generator, Iterable

from workbench.compute.local import JobFailed, apply_thread_budget
from workbench.compute.progress import reporting_to
from workbench.errors import WorkbenchError
from workbench.jobs import CancelToken, JobCancelled, Progress

POLL_S = 0.2                 # how often the driver checks the cancel token while waiting
QUEUE_PER_SLOT = 2           # tasks kept submitted per task slot of the cluster
INSTALL_HINT = "Ray is not installed: pip install 'camera-workbench[cluster]' (or: pip install ray)"


def import_ray():
    """The ray module, or a WorkbenchError saying how to install it."""
    try:
        import ray
    except ImportError as exc:
        raise WorkbenchError(INSTALL_HINT) from exc
    return ray


def _run_task(fn: Callable, job, threads: int, board=None, key: int = 0):
    """What a Ray worker runs: set the task's thread budget, then fn(job), its report_progress
    calls sent to the run's progress board (fire and forget)."""
    apply_thread_budget(threads)
    if board is None:
        return fn(job)
    with reporting_to(lambda done, total: board.report.remote(key, done, total)):
        return fn(job)


class _ProgressBoard:
    """A Ray actor holding the latest progress of each running task until the driver reads it."""

    def __init__(self) -> None:
        self.latest: dict[int, tuple[float, float]] = {}

    def report(self, key: int, done: float, total: float) -> None:
        self.latest[key] = (done, total)

    def drain(self) -> dict[int, tuple[float, float]]:
        latest, self.latest = self.latest, {}
        return latest


CONNECT_TIMEOUT_S = 10.0


def check_address(address: str) -> None:
    """Fail fast, naming the address, where Ray itself would retry for minutes: a host:port or
    ray://host:port that does not answer on TCP, or ray:// without Ray's client support."""
    import socket
    from workbench.errors import ParameterError
    if address == "auto":
        return
    target = address[len("ray://"):] if address.startswith("ray://") else address
    host, sep, port = target.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ParameterError("--address", address, "'auto', HOST:PORT of a cluster's head (GCS) or ray://HOST:PORT")
    if address.startswith("ray://"):
        try:
            import grpc  # noqa: F401  (ray[client]'s transport)
        except ImportError:
            raise ParameterError("--address", address, "a ray:// address needs Ray's client support: "
                                 "pip install 'ray[client]' (the cluster extra installs it)") from None
    try:
        socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise ParameterError("--address", address, f"a Ray cluster that answers: nothing at {host}:{port} "
                             f"({exc.strerror or type(exc).__name__} within {CONNECT_TIMEOUT_S:g} s); start one "
                             "with `ray start --head` or check the address") from None


def connect(spec) -> bool:
    """Join or start the cluster `spec` names; True when this call started (and so owns) it."""
    ray = import_ray()
    if ray.is_initialized():
        return False
    if spec.address is None:
        ray.init(num_cpus=spec.workers, include_dashboard=False, log_to_driver=False)
    else:
        check_address(spec.address)
        ray.init(address=spec.address, log_to_driver=False)
    return True


def task_slots(spec) -> int:
    """How many tasks of spec's size the cluster can run at once (at least 1)."""
    ray = import_ray()
    total = ray.cluster_resources()
    slots = int(total.get("CPU", 1) // spec.task_cpus)
    if spec.gpus_per_task:
        slots = min(slots, int(total.get("GPU", 0) // spec.gpus_per_task))
    return max(1, slots)


def run_jobs_ray(fn: Callable, jobs: Iterable, spec, cancel: CancelToken | None = None,
                 task_progress: bool = False) -> Generator[tuple[object, object] | Progress, None, None]:
    """compute.run_jobs on Ray (see the module docstring); jobs are submitted lazily. With
    task_progress, Progress items (source = the job) are yielded too, from a small progress actor (0 CPUs)."""
    ray = import_ray()
    owned = connect(spec)
    options = {"num_cpus": spec.task_cpus, "num_gpus": spec.gpus_per_task,
               "max_retries": spec.max_retries, "retry_exceptions": False}
    if spec.memory_mb_per_task:
        options["memory"] = int(spec.memory_mb_per_task * 2 ** 20)
    remote = ray.remote(_run_task).options(**options)
    board = None
    pending: dict = {}
    keys: dict = {}                          # progress key → ref of the running task
    counter = itertools.count()
    jobs = iter(jobs)
    try:
        if spec.gpus_per_task and not ray.cluster_resources().get("GPU"):
            raise JobFailed(f"gpus_per_task = {spec.gpus_per_task} but the Ray cluster has no GPU "
                            "(--gpus-per-task 0 runs the tasks on CPUs)")
        window = QUEUE_PER_SLOT * task_slots(spec)
        board = ray.remote(num_cpus=0)(_ProgressBoard).remote() if task_progress else None
        exhausted = False
        while True:
            while not exhausted and len(pending) < window and not (cancel and cancel.cancelled):
                job = next(jobs, _END)
                if job is _END:
                    exhausted = True
                else:
                    key = next(counter)
                    ref = remote.remote(fn, job, spec.threads_per_task, board, key)
                    pending[ref], keys[key] = (job, key), ref
            if cancel is not None and cancel.cancelled:
                raise JobCancelled("cancelled")
            if not pending:
                return
            done, _ = ray.wait(list(pending), num_returns=1, timeout=POLL_S)
            if board is not None:
                for key, (steps, total) in ray.get(board.drain.remote()).items():
                    if key in keys and keys[key] not in done:
                        yield Progress(steps, total, source=pending[keys[key]][0])
            for ref in done:
                job, key = pending.pop(ref)
                keys.pop(key)
                yield job, _result(ray, ref, job, spec)
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if board is not None:
            ray.kill(board)
        if owned:
            ray.shutdown()


def _result(ray, ref, job, spec):
    """ray.get(ref), with a failure turned into JobFailed naming the job and the last error."""
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as exc:            # the job raised: deterministic, not retried
        cause = exc.cause if isinstance(exc.cause, BaseException) else exc
        raise JobFailed.of(job, cause) from cause
    except ray.exceptions.UnserializableException as exc:  # the job raised an error that cannot travel
        raise JobFailed(f"job {job!r} failed with an error that could not be sent back: {exc}") from exc
    except ray.exceptions.RayError as exc:                # the worker, node or object was lost
        last = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise JobFailed(f"job {job!r} failed after {spec.max_retries} retries; last error: "
                        f"{type(exc).__name__}: {last}") from exc


_END = object()
