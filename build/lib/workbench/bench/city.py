"""`workbench bench city`: time to generate a city and to sample camera poses, by city size."""
from __future__ import annotations

from workbench.bench import BenchResult, register_bench
from workbench.bench.timing import median_times_ms


@register_bench("city", help="procedural city generation and pose sampling time")
def bench_city(args) -> BenchResult:
    from workbench.scene.city import CityRecipe, PoseParams, generate_city, sample_camera_poses
    quick = getattr(args, "quick", False)
    sizes = (1, 2) if quick else (1, 2, 4, 8)
    repeats = 3 if quick else 5
    rows = []
    for n in sizes:
        recipe = CityRecipe(seed=1, blocks_x=n, blocks_y=n)
        wall_ms, cpu_ms = median_times_ms(lambda: generate_city(recipe), repeats)
        city = generate_city(recipe)
        meshes = [m for o in city.objects for m in o.meshes]
        pose_ms, _ = median_times_ms(lambda: sample_camera_poses(city, PoseParams(), 10, 0), repeats)
        rows.append({"blocks": f"{n}x{n}", "objects": len(city.objects), "meshes": len(meshes),
                     "triangles": sum(len(m.faces) for m in meshes), "generate_ms": wall_ms,
                     "generate_cpu_ms": cpu_ms, "pose_ms": pose_ms / 10})
    return BenchResult("bench city: generation time by city size (median, warm asset cache)", rows,
                       ["pose_ms = one random pose (mean of 10)"])
