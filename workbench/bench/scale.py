"""`workbench bench scale`: data-set throughput against worker count, local processes and Ray.

The same small set of real city frames (the city sample project at 320×240) is rendered with 1 and
2 workers on each backend, every run into a fresh folder. Reported per run: wall time (start-up
included), frames per hour, render seconds per frame as the workers measured them, and core-minutes
per frame (render seconds × the CPUs each task reserved). Ray's overhead per task is measured two
ways on the warm cluster: the round trip of an empty task, and — for the 1-worker Ray run — the
gap between consecutive finished frames minus their render time (scheduling, transfer through the
object store, the driver's write)."""
from __future__ import annotations

import os
import statistics
import tempfile
import time

from workbench.bench import BenchResult, register_bench

WIDTH, HEIGHT = 320, 240
WORKER_COUNTS = (1, 2)


def _project(spp: int):
    from workbench.project import load_project
    p = load_project("city_paper_camera")
    sensor = p.sensor.model_copy(update={"rows": HEIGHT, "cols": WIDTH})
    render = p.render.model_copy(update={"spp": spp, "target_rel_error": None, "shot_noise_ratio": None})
    return p.model_copy(update={"sensor": sensor, "render": render})


def _run(project, frames: int, spec) -> dict:
    """Render `frames` frames with `spec` into a temporary folder; timings of the run."""
    from workbench.datasets.dataset import run_dataset
    with tempfile.TemporaryDirectory(prefix="wb-bench-scale-") as out:
        t0 = time.perf_counter()
        finished, render_s = [], []
        for p in run_dataset(project, frames, out, compute=spec):
            if p.message.startswith("frame "):
                finished.append(time.perf_counter() - t0)
                render_s.append(float(p.message.rsplit(",", 1)[1].split()[0]))
        wall = time.perf_counter() - t0
    return {"wall_s": wall, "finished_s": finished, "render_s": render_s}


def _empty_task_ms(n: int) -> float:
    """Median round trip of an empty Ray task on the running cluster (ms)."""
    import ray

    @ray.remote(num_cpus=1)
    def empty():
        return None
    ray.get(empty.remote())
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        ray.get(empty.remote())
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


@register_bench("scale", help="data-set frames per hour vs workers, local and Ray; Ray's overhead per task")
def bench_scale(args) -> BenchResult:
    from workbench.compute import ComputeSpec
    from workbench.compute.ray_cluster import import_ray
    quick = getattr(args, "quick", False)
    spp, frames = (4, 2) if quick else (16, 4)
    project = _project(spp)
    rows, extra = [], {"width": WIDTH, "height": HEIGHT, "spp": spp, "frames_per_run": frames,
                       "cpu_count": os.cpu_count()}
    for backend in ("local", "ray"):
        for workers in WORKER_COUNTS:
            spec = ComputeSpec(backend=backend, workers=workers, cpus_per_task=1.0)
            if backend == "ray":
                ray = import_ray()
                ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                         object_store_memory=200 * 2 ** 20)
            try:
                r = _run(project, frames, spec)
                if backend == "ray" and workers == 1:
                    extra["ray_empty_task_ms"] = round(_empty_task_ms(20), 2)
                    gaps = [b - a for a, b in zip(r["finished_s"], r["finished_s"][1:])]
                    per_task = [g - s for g, s in zip(gaps, r["render_s"][1:])]
                    extra["ray_overhead_per_frame_s"] = round(statistics.median(per_task), 3) if per_task else None
            finally:
                if backend == "ray":
                    ray.shutdown()
            mean_render = statistics.mean(r["render_s"])
            rows.append({"backend": backend, "workers": workers, "frames": frames,
                         "wall_s": round(r["wall_s"], 1), "frames_per_hour": round(3600 * frames / r["wall_s"], 1),
                         "render_s_per_frame": round(mean_render, 2),
                         "core_min_per_frame": round(mean_render * spec.task_cpus / 60, 3)})
    render_1 = next(row["render_s_per_frame"] for row in rows if row["backend"] == "ray" and row["workers"] == 1)
    extra["ray_overhead_pct_of_frame"] = {
        "empty_task": round(100 * extra["ray_empty_task_ms"] / 1e3 / render_1, 2),
        "between_frames": (None if extra.get("ray_overhead_per_frame_s") is None
                           else round(100 * extra["ray_overhead_per_frame_s"] / render_1, 2))}
    notes = [f"city_paper_camera at {WIDTH}x{HEIGHT}, {spp} spp, {frames} frames per run, 1 CPU per task; "
             "wall time includes starting the pool or the Ray cluster and each worker's first Mitsuba import",
             f"Ray overhead per task: empty-task round trip {extra['ray_empty_task_ms']} ms; between "
             f"consecutive frames {extra.get('ray_overhead_per_frame_s')} s beyond their render time "
             f"(empty task {extra['ray_overhead_pct_of_frame']['empty_task']} %, between frames "
             f"{extra['ray_overhead_pct_of_frame']['between_frames']} % of a {render_1} s frame; goal < 5 %)",
             f"{os.cpu_count()} CPUs on this machine; on a shared machine wall times vary run to run"]
    return BenchResult("data-set throughput vs workers: local processes and Ray", rows, notes, extra)
