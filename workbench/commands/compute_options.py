"""Command-line options that say where many jobs run (--backend, --address, per-task resources)."""
from __future__ import annotations


def add_compute_options(p) -> None:
    """--backend, --address and per-task resources (shared by every command that runs many jobs)."""
    g = p.add_argument_group("where the jobs run")
    g.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local processes (default) or a Ray cluster")
    g.add_argument("--address", default=None,
                   help="Ray cluster: 'auto' (the one `ray start --head` runs here) or ray://host:10001; "
                        "default: start a local one for this run")
    g.add_argument("--cpus-per-task", type=float, default=None,
                   help="CPUs each task reserves and its thread budget (default: 1 on Ray, this "
                        "machine's CPUs shared among the local workers)")
    g.add_argument("--memory-mb-per-task", type=float, default=None, help="memory each Ray task reserves (MiB)")
    g.add_argument("--gpus-per-task", type=float, default=None,
                   help="GPUs each Ray task reserves (default 0; experiments with the paper profile: 1)")
    g.add_argument("--max-retries", type=int, default=3,
                   help="re-runs of a task whose worker died (default 3); errors are not retried")


def compute_spec(args, gpus_per_task: float = 0.0, max_tasks_per_child: int | None = None):
    """The ComputeSpec the compute options of `args` describe (gpus_per_task: the default when
    --gpus-per-task is not given)."""
    from workbench.compute import ComputeSpec
    gpus = gpus_per_task if args.gpus_per_task is None else args.gpus_per_task
    return ComputeSpec(backend=args.backend, workers=args.workers, address=args.address,
                       cpus_per_task=args.cpus_per_task, memory_mb_per_task=args.memory_mb_per_task,
                       gpus_per_task=gpus if args.backend == "ray" else 0.0, max_retries=args.max_retries,
                       max_tasks_per_child=max_tasks_per_child if args.backend == "local" and args.workers else None)
