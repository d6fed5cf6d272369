"""Render cost of each scene type and scene feature (part of `workbench bench render`, and alone as
`workbench bench render-features`).

Every case (feature_cases, one line each) renders a city view through the camera's three
channels (sensor film) with one thing changed from the baseline (today's city: day, uniform sky,
clear air, diffuse glass, uniform materials, simple assets): a sky model, a low sun, fog by either
model, night with each light selection or direct light only, glass, materials, paint, detailed assets, a tunnel
scene (its own city and pose). For each case and resolution: the broadband noise constant c
(relative RMS of the three channels' sum between two independent renders, c = σ√spp),
spp = (c/0.02)² for 2 % broadband error, and the process CPU time of that frame extrapolated from
two renders as t = a + b·spp (warm; scene build, label pass and the first JIT trace excluded).
CPU time, not wall time: on a shared machine other processes stretch wall time only; with
DRJIT_NUM_THREADS=1 it is the wall time of one idle core. The first resolution renders three
times (c from two equal-spp seeds); the others, for a bounded run time, twice (c from the two
timing renders of unequal spp: var(a − b) = σ²(1/n_a + 1/n_b)). Koschmieder fog adds its
per-frame fogging (source-profile render, path integrals, composite), timed warm, to every frame
(column fog_cpu_s), and its c is that of the fogged image.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.bench import BenchResult, register_bench
from workbench.bench.timing import timed

WL_RANGE_NM = (400.0, 700.0)                     # the render benches' camera: three Gaussian channels
QE_CENTRES_NM, QE_SIGMA_NM = (460.0, 540.0, 610.0), 35.0


def bench_qe(wl: np.ndarray) -> np.ndarray:
    """3 × len(wl) quantum efficiency of the render benches' camera."""
    return np.stack([np.exp(-0.5 * ((wl - c) / QE_SIGMA_NM) ** 2) for c in QE_CENTRES_NM])

TARGET = 0.02
BASELINE = "day baseline (uniform sky)"


@dataclass(frozen=True)
class FeatureCase:
    """A benchmarked case: updates to the baseline's DaylightParams, WorldParams, CityRecipe and
    PoseParams (an empty dict: the baseline's), and the longest light path (RenderParams.max_depth)."""

    name: str
    daylight: dict = field(default_factory=dict)
    world: dict = field(default_factory=dict)
    recipe: dict = field(default_factory=dict)
    pose: dict = field(default_factory=dict)
    max_depth: int = 6


def feature_cases() -> list[FeatureCase]:
    """Every benchmarked case, the baseline first."""
    from workbench.render.params import FogParams, NightParams
    from workbench.scene.city.recipe import TunnelParams

    fog = FogParams(visibility_m=150.0, height_m=60.0)
    return [FeatureCase(BASELINE),
            FeatureCase("sky perez", daylight={"sky_model": "perez"}),
            FeatureCase("sky perez + horizon field 3 km", daylight={"sky_model": "perez"},
                        recipe={"horizon_field_m": 3000.0}),
            FeatureCase("sky perez + field 3 km + skyline 250 m", daylight={"sky_model": "perez"},
                        recipe={"horizon_field_m": 3000.0, "skyline_distance_m": 250.0}),
            FeatureCase("low sun 5 deg (perez)", daylight={"sun_elevation_deg": 5.0, "sky_model": "perez"}),
            FeatureCase("overcast", daylight={"sky_model": "overcast"}),
            FeatureCase("fog V=150 m koschmieder", world={"fog": fog}),
            FeatureCase("fog V=150 m volumetric", world={"fog": fog.updated(model="volumetric")}),
            FeatureCase("night HPS, view light selection", world={"lighting": "night"}),
            FeatureCase("night HPS, flux light selection", world={"lighting": "night",
                                                                  "night": NightParams(light_selection="flux")}),
            FeatureCase("night HPS, shading light selection", world={"lighting": "night",
                                                                     "night": NightParams(light_selection="shading")}),
            FeatureCase("night HPS, view, direct light only (max_depth 2)", world={"lighting": "night"}, max_depth=2),
            FeatureCase("night HPS, flux, direct light only (max_depth 2)", max_depth=2,
                        world={"lighting": "night", "night": NightParams(light_selection="flux")}),
            FeatureCase("glass dielectric", world={"glass": "dielectric"}),
            FeatureCase("materials procedural", world={"materials": "procedural"}),
            FeatureCase("paint clearcoat", world={"paint": "clearcoat"}),
            FeatureCase("detailed assets", recipe={"asset_detail": "detailed"}),
            FeatureCase("detailed + clearcoat + glass", world={"paint": "clearcoat", "glass": "dielectric"},
                        recipe={"asset_detail": "detailed"}),
            FeatureCase("tunnel exit view (day, luminaires)", pose={"mode": "tunnel", "tunnel_view": "exit", "seed": 1},
                        recipe={"seed": 1, "block_size_m": 180.0, "tunnel": TunnelParams(length_m=150.0)}),
            FeatureCase("tunnel entrance view (day)", pose={"mode": "tunnel", "tunnel_view": "entrance", "seed": 1},
                        recipe={"seed": 1, "block_size_m": 180.0, "tunnel": TunnelParams(length_m=150.0)})]


def _view(case: FeatureCase, cache: dict):
    """(city, pose) of a case, each generated once; the pose is drawn on the city at the simple
    asset detail, so that detailed assets are seen from the same view."""
    from workbench.scene.city.generate import generate_city
    from workbench.scene.city.poses import sample_camera_poses
    from workbench.scene.city.recipe import CityRecipe, PoseParams

    def city(recipe: dict):
        key = ("city", repr(sorted(recipe.items())))
        if key not in cache:
            cache[key] = generate_city(CityRecipe().updated(**recipe))
        return cache[key]
    simple = {k: v for k, v in case.recipe.items() if k != "asset_detail"}
    key = ("pose", repr(sorted(simple.items())), repr(sorted(case.pose.items())))
    if key not in cache:
        cache[key] = sample_camera_poses(city(simple), PoseParams().updated(**case.pose), 1)[0]
    return city(case.recipe), cache[key]


def _sig(x: float) -> float:
    """x to 3 significant figures (times span 10⁻⁴…10⁴ s)."""
    return float(f"{x:.3g}")


def _case_row(case: FeatureCase, city, pose, film, fov_deg: float, width: int, height: int,
              spps: tuple[int, int], seeds: int) -> dict:
    from workbench.jobs import run_job
    from workbench.render.koschmieder import koschmieder_fog
    from workbench.render.labels import render_labels
    from workbench.render.params import DaylightParams, RenderParams, WorldParams
    from workbench.render.scene_builder import build_scene
    from workbench.render.spectral import render_loaded

    daylight = DaylightParams().updated(**case.daylight)
    world = WorldParams().updated(**case.world)
    scene, ids = build_scene(city, pose, fov_deg, width, height, film, daylight, max_depth=case.max_depth,
                             world=world)
    fog, fog_s = None, 0.0
    if world.fog is not None and world.fog.model == "koschmieder":
        depth = render_labels(scene, ids, width, height).depth_m

        def fogging():
            return koschmieder_fog(scene, depth, city, pose.pan_deg, film, daylight, world, max_depth=case.max_depth)
        fogging()                                                # warm (JIT trace of its kernels)
        fog, took = timed(fogging)
        fog_s = took.cpu_ms * 1e-3

    def render(spp, seed):
        p = RenderParams(spp=spp, chunk_spp=spp, preview_spp=spp, seed=seed)
        s, took = timed(lambda: run_job(render_loaded(scene, film, p, fov_deg=fov_deg)))
        rad = s.radiance_photons.astype(np.float64)
        if fog is not None:
            rad, applied = timed(lambda: fog.apply(rad))
            return rad.sum(-1), (took.cpu_ms + applied.cpu_ms) * 1e-3
        return rad.sum(-1), took.cpu_ms * 1e-3

    render(1, 7)                                                 # warm-up (JIT trace)
    lo, t_lo = render(spps[0], 1)
    hi, t_hi = render(spps[1], 2)
    if seeds >= 3:
        other, _ = render(spps[1], 3)
        a, b, n_a, n_b = hi, other, spps[1], spps[1]
    else:
        a, b, n_a, n_b = lo, hi, spps[0], spps[1]
    mean = 0.5 * (a.mean() + b.mean())
    sigma1 = np.sqrt(np.mean((a - b) ** 2) / (1.0 / n_a + 1.0 / n_b))       # one-sample per-pixel RMS
    c = float(sigma1 / mean) if mean > 0 else float("nan")
    per_spp = (t_hi - t_lo) / (spps[1] - spps[0])
    per_spp = per_spp if per_spp > 0 else t_hi / spps[1]
    spp = int(np.ceil((c / TARGET) ** 2)) if np.isfinite(c) else None
    t = None if spp is None else max(t_hi - per_spp * spps[1], 0.0) + per_spp * spp + fog_s
    return {"case": case.name, "res": f"{width}x{height}", "cpu_s_per_spp": _sig(per_spp),
            "c_broadband": round(c, 3), "spp_for_2pct": spp, "fog_cpu_s": _sig(fog_s),
            "cpu_s_per_frame_2pct": None if t is None else _sig(t),
            "mean_radiance_photons": float(f"{mean:.3g}")}


def feature_costs(film, fov_deg: float, resolutions, spps, cases: list[FeatureCase] | None = None) -> list[dict]:
    """Rows of every case (feature_cases) at each resolution (w, h) with its (low, high) timing spp;
    the first resolution renders three seeds, the others two (module docstring). x_baseline: the
    frame time over the baseline's at the same resolution."""
    cases = feature_cases() if cases is None else cases
    views: dict = {}
    rows = []
    for k, ((w, h), lo_hi) in enumerate(zip(resolutions, spps)):
        for case in cases:
            city, pose = _view(case, views)
            rows.append(_case_row(case, city, pose, film, fov_deg, w, h, lo_hi, 3 if k == 0 else 2))
    for r in rows:
        base = next(b["cpu_s_per_frame_2pct"] for b in rows if b["case"] == cases[0].name and b["res"] == r["res"])
        t = r["cpu_s_per_frame_2pct"]
        r["x_baseline"] = None if not base or t is None else _sig(t / base)
    return rows


def bench_camera_film():
    """The render bench's camera film (three Gaussian channels) and horizontal field of view (deg)."""
    from workbench.render.film import sensor_channels

    qe_wl = np.arange(WL_RANGE_NM[0], WL_RANGE_NM[1] + 1e-9, 5.0)
    return sensor_channels(qe_wl, bench_qe(qe_wl), ["B", "G", "R"]), 44.0


def feature_plan(quick: bool) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """(resolutions, (low, high) timing spp per resolution): 320×240 and 640×480, or in --quick
    48×36 and 96×72."""
    if quick:
        return [(48, 36), (96, 72)], [(2, 8), (2, 4)]
    return [(320, 240), (640, 480)], [(8, 64), (4, 16)]


@register_bench("render-features", help="render cost of every scene type and feature at 2 % error "
                                        "(also part of 'render')")
def bench_render_features(args) -> BenchResult:
    from workbench.render.variants import select_variant

    variant = select_variant()
    film, fov = bench_camera_film()
    resolutions, spps = feature_plan(bool(getattr(args, "quick", False)))
    rows = feature_costs(film, fov, resolutions, spps)
    return BenchResult("render cost per scene type and feature at 2 % broadband error", rows,
                       feature_notes(variant, resolutions, spps), {"features_2pct": rows})


def feature_notes(variant: str, resolutions, spps) -> list[str]:
    """What the feature rows mean (for the table's notes)."""
    import os
    return [f"variant {variant}; {os.cpu_count()} CPU threads (DRJIT_NUM_THREADS={os.environ.get('DRJIT_NUM_THREADS')}"
            f"); load average {os.getloadavg()[0]:.2f} at the end; resolutions "
            + ", ".join(f"{w}x{h} timed at {a}/{b} spp" for (w, h), (a, b) in zip(resolutions, spps))
            + f"; c from 3 renders at {resolutions[0][0]}x{resolutions[0][1]}, 2 elsewhere; "
            "cpu_s_per_frame_2pct = a + b·spp_for_2pct (process CPU seconds, + fog_cpu_s: Koschmieder's "
            "per-frame fogging); scene build, label pass and view light weights excluded; x_baseline per "
            "resolution."]
