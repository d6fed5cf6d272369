"""Render cost of each scene type and scene feature (part of `workbench bench render`).

Every case renders the same city view through the camera's three channels (sensor film) with
one setting changed from the baseline (today's city: day, uniform sky, clear air, diffuse glass):
Perez sky, low sun (5°, Perez), overcast, fog (150 m visibility), dielectric glass, night (HPS
lamps + vehicle lights), procedural materials, clear-coat paint, and the same city built with
detailed assets (CityRecipe.asset_detail, the view unchanged; a case's optional 4th entry); and
the tunnel's exit view by day (its own city and pose: the city_tunnel sample's recipe and pose
mode, luminaires lit; a 4th entry that is a function). For each: the broadband noise constant c
from two independent seeds (σ = rms(a−b)/√2 relative to the mean, c = σ√spp), spp = (c/0.02)²
for 2 % broadband error, and the time of that frame extrapolated from two renders as
t = a + b·spp (warm; scene build and the first JIT trace excluded).
"""
from __future__ import annotations

import numpy as np

from workbench.bench.timing import timed

TARGET = 0.02


def tunnel_view():
    """(city, pose) of the tunnel case: a 150 m tunnel in 180 m blocks, the camera 20–60 m before
    the exit (the city_tunnel sample's city and pose mode)."""
    from workbench.scene.city import CityRecipe, PoseParams, TunnelParams, generate_city, sample_camera_poses
    city = generate_city(CityRecipe(seed=1, block_size_m=180.0, tunnel=TunnelParams(length_m=150.0)))
    return city, sample_camera_poses(city, PoseParams(mode="tunnel", tunnel_view="exit", seed=1), 1)[0]


def feature_cases():
    """(name, DaylightParams, WorldParams[, asset_detail or view]) of every benchmarked case,
    baseline first; a view is a function returning the case's own (city, pose)."""
    from workbench.render.params import DaylightParams, FogParams, WorldParams

    day = DaylightParams()
    return [("baseline (uniform sky)", day, WorldParams()),
            ("sky perez", day.updated(sky_model="perez"), WorldParams()),
            ("low sun 5 deg (perez)", day.updated(sun_elevation_deg=5.0, sky_model="perez"), WorldParams()),
            ("overcast", day.updated(sky_model="overcast"), WorldParams()),
            ("fog V=150 m", day, WorldParams(fog=FogParams(visibility_m=150.0, height_m=60.0, model="volumetric"))),
            ("glass dielectric", day, WorldParams(glass="dielectric")),
            ("night (HPS, vehicle lights)", day, WorldParams(lighting="night")),
            ("materials procedural", day, WorldParams(materials="procedural")),
            ("paint clearcoat", day, WorldParams(paint="clearcoat")),
            ("detailed assets", day, WorldParams(), "detailed"),
            ("detailed + clearcoat + glass", day, WorldParams(paint="clearcoat", glass="dielectric"), "detailed"),
            ("tunnel exit view (day, luminaires)", day, WorldParams(), tunnel_view)]


def _city_at(city, detail: str | None):
    """The city regenerated from its recipe at another asset detail (None: the city itself, or
    when it has no recipe, e.g. the demo scene)."""
    if detail is None or "recipe" not in city.meta:
        return city
    from workbench.scene.city.generate import generate_city
    from workbench.scene.city.recipe import CityRecipe
    return generate_city(CityRecipe.model_validate({**city.meta["recipe"], "asset_detail": detail}))


def feature_costs(city, pose, film, fov_deg: float, width: int, height: int, spps: tuple[int, int]) -> list[dict]:
    """One row per case (feature_cases) at width × height; spps = (low, high) timing renders."""
    from workbench.jobs import run_job
    from workbench.render.params import RenderParams
    from workbench.render.scene_builder import build_scene
    from workbench.render.spectral import render_loaded

    rows = []
    for name, daylight, world, *option in feature_cases():
        option = option[0] if option else None
        c_city, c_pose = option() if callable(option) else (_city_at(city, option), pose)
        scene = build_scene(c_city, c_pose, fov_deg, width, height, film, daylight, max_depth=6, world=world)[0]

        def render(spp, seed):
            p = RenderParams(spp=spp, chunk_spp=spp, preview_spp=spp, seed=seed)
            s, took = timed(lambda: run_job(render_loaded(scene, film, p, fov_deg=fov_deg)))
            return s.radiance_photons.astype(np.float64).sum(-1), took.wall_ms * 1e-3

        render(1, 7)                                             # warm-up (JIT trace)
        lo, t_lo = render(spps[0], 1)
        a, t_hi = render(spps[1], 2)
        b, _ = render(spps[1], 3)
        mean = 0.5 * (a.mean() + b.mean())
        c = float(np.sqrt(np.mean((a - b) ** 2) / 2) / mean * np.sqrt(spps[1])) if mean > 0 else float("nan")
        per_spp = (t_hi - t_lo) / (spps[1] - spps[0])
        per_spp = per_spp if per_spp > 0 else t_hi / spps[1]
        spp = int(np.ceil((c / TARGET) ** 2)) if np.isfinite(c) else None
        rows.append({"case": name, "res": f"{width}x{height}", "s_per_spp": round(per_spp, 4),
                     "c_broadband": round(c, 3), "spp_for_2pct": spp,
                     "s_per_frame_2pct": None if spp is None else round(max(t_hi - per_spp * spps[1], 0.0)
                                                                          + per_spp * spp, 1),
                     "mean_radiance_photons": float(f"{mean:.3g}")})
    base = rows[0]["s_per_frame_2pct"]
    for r in rows:
        r["x_baseline"] = None if not base or r["s_per_frame_2pct"] is None else round(r["s_per_frame_2pct"] / base, 2)
    return rows
