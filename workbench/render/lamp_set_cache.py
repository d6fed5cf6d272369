"""Importance-cached candidates of the lamp set (render/lamp_set.py): each cell and side of its grid
lists first the lamps that carry a real share of the visible direct light at shading points of a
cheap pre-pass of this camera, then the lamps its bound ranks highest.

The grid ranks a cell's lamps by a bound of their light over the whole 8 m cube, blind to
occlusion and to where surfaces are: in city_night frame 1 a cell's list for surfaces facing −x was
led by two head-lights inside the cell aimed away from every surface in it (the bound of a lamp
inside the cube is its peak at 1 m) and filled with street lamps 190 m off, while the low beam 73 m
away that lights that cell's low surfaces was no candidate: it was found only through the global
share, and its samples were worth up to ~3,500× the points' mean. Here, after the scene loads, the
pre-pass traces camera rays on a grid (at most PREPASS_POINTS) and one diffuse bounce from each hit,
and at every point weighs each lamp's direct light — the emitter's own w_k(x) (cone, texture bound,
1/r²) with the point's true cos θ and a shadow ray — in each 40-nm band. A lamp whose share of
some point's light in some band reaches SHARE_FLOOR is ranked, in its (cell, side) list, by the
largest such share, ahead of the bound's ranking, which fills the remaining slots. A (cell, side)
no pre-pass point reached keeps the bound's list. Every lamp keeps its global share, so the cache
changes which lamps a point samples well, never the expected image (the lamp set's tests).

In the manner of importance caching for many lights (Georgiev et al. 2012), with the grid's bound
(a light tree's kind of bound, as in PBRT-v4) where no point is. city_night frame 1 at EV 0
(188×120, 121 spp against 1,024, pixels beyond 5σ away from saturated lamp faces): 166 without the
cache, 43 with the ranking, 36 with the visible fractions too; the pre-pass (6,819 points, 92
lamps) took 0.8–1.2 CPU-s beside 10–15 for the render (measured 2026-11-28, under load).
"""
from __future__ import annotations

import numpy as np

from workbench.render import lamp_set, spot_pattern
from workbench.render.lamps import camera_grid_hits

PREPASS_POINTS = 96 * 72       # camera rays of the pre-pass (each also bounces once)
SHARE_FLOOR = 1e-3             # a lamp's share of a point's light (in some band) that earns it a ranked slot
VISIBLE_FLOOR = 0.1            # a slot's weight factor when no pre-pass point of its cell-side sees the lamp
POINT_CHUNK = 512              # points weighed at once (memory: chunk × lamps × bands)


def lamp_set_of(mi_scene):
    """The scene's lamp-set emitter (the Python object), or None."""
    return next((e for e in mi_scene.emitters() if hasattr(e, "set_key")), None)


def prepass_points(mi_scene, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(points P×3 in m, their geometric normals P×3 as the emitter sees them) of the pre-pass: camera
    rays through a grid of at most PREPASS_POINTS pixel positions, and one cosine-distributed
    bounce from each hit; front faces only (the city's surfaces are one-sided)."""
    import drjit as dr
    import mitsuba as mi

    ray, first = camera_grid_hits(mi_scene, PREPASS_POINTS)
    rng = np.random.default_rng(seed)
    count = dr.width(first.p)
    u = mi.Point2f(*(mi.Float(rng.random(count).astype(np.float32)) for _ in range(2)))
    n = dr.select(dr.dot(first.n, ray.d) > 0, -first.n, first.n)
    out = first.spawn_ray(mi.Frame3f(n).to_world(mi.warp.square_to_cosine_hemisphere(u)))
    bounce = mi_scene.ray_intersect(out, first.is_valid())
    points, normals = [], []
    for si, d in ((first, ray.d), (bounce, out.d)):       # front faces only: a back face is not shaded
        hit = np.array(si.is_valid() & (dr.dot(si.n, d) < 0), dtype=bool)
        for out_list, v in ((points, si.p), (normals, si.n)):
            out_list.append(np.stack([np.array(c, dtype=np.float64) for c in (v.x, v.y, v.z)], -1)[hit])
    return np.concatenate(points), np.concatenate(normals)


def direct_light(mi_scene, arrays: dict, points_m: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unshadowed, visible), each points × lamps in 1/m²: each lamp's w_k(x) without its intensity
    (cone × texture bound × cos θ / r², r in m; 0 behind the surface), and that times its
    visibility from the point (a shadow ray leaving 1 mm off the surface)."""
    import mitsuba as mi

    unshadowed = np.zeros((len(points_m), len(arrays["pos"])))
    for a in range(0, len(points_m), POINT_CHUNK):
        p, nrm = points_m[a:a + POINT_CHUNK], normals[a:a + POINT_CHUNK]
        v = arrays["pos"][None] - p[:, None]                                    # points × lamps × 3
        r2 = np.maximum((v * v).sum(-1), 1e-8)
        u = v / np.sqrt(r2)[..., None]
        cos_l = -(u * arrays["axis"][None]).sum(-1)
        cone = np.clip((cos_l - arrays["cos_cut"]) / (arrays["cos_beam"] - arrays["cos_cut"]), 0.0, 1.0)
        for sl in np.unique(arrays["slot"][arrays["slot"] > 0]):
            k = np.flatnonzero(arrays["slot"] == sl)
            local = np.stack([-(u[:, k] * arrays[c][k][None]).sum(-1) for c in ("left", "up", "axis")], -1)
            cone[:, k] *= spot_pattern.coarse_bound(arrays["pyramids"][sl], arrays["texture_cut_deg"][sl],
                                                    local, np.zeros(local.shape[:-1]))
        unshadowed[a:a + POINT_CHUNK] = cone * np.maximum((u * nrm[:, None]).sum(-1), 0.0) / r2
    visible = unshadowed.copy()
    i, k = np.nonzero(unshadowed > 0)
    if len(i):
        start = points_m[i] + 1e-3 * normals[i]
        to = arrays["pos"][k] - start
        dist = np.linalg.norm(to, axis=1)
        d = to / dist[:, None]
        shadow = mi.Ray3f(mi.Point3f(*start.T.astype(np.float32)), mi.Vector3f(*d.T.astype(np.float32)))
        shadow.maxt = mi.Float((dist * (1 - 1e-4) - 1e-3).astype(np.float32))
        blocked = np.array(mi_scene.ray_test(shadow), dtype=bool)
        visible[i[blocked], k[blocked]] = 0.0
    return unshadowed, visible


def ranked_candidates(arrays: dict, points_m: np.ndarray, normals: np.ndarray, unshadowed: np.ndarray,
                      visible: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(candidates, slot weights, cell-sides re-ranked) of the grid: per (cell, side) the pre-pass
    lamps (share ≥ SHARE_FLOOR of some point's visible light, in some band) by their largest share,
    then the grid's own list; each slot's weight VISIBLE_FLOOR + (1 − VISIBLE_FLOOR) × the lamp's
    visible fraction of its light over the cell-side's points (1 for a lamp that reaches none)."""
    grid = arrays["grid"]
    slots = lamp_set.CANDIDATES
    cand = grid["candidates"].reshape(-1, slots).astype(np.int64)
    valid = grid["valid"].reshape(-1, slots).astype(np.float64)
    group = lamp_set.cell_side(grid, points_m, normals)
    intensity = lamp_set.band_intensity(arrays)
    score = np.zeros((len(cand), len(arrays["pos"])))
    for a in range(0, len(points_m), POINT_CHUNK):
        lit = visible[a:a + POINT_CHUNK, :, None] * intensity[None]               # points × lamps × bands
        share = (lit / np.maximum(lit.sum(1, keepdims=True), 1e-300)).max(-1)
        np.maximum.at(score, group[a:a + POINT_CHUNK], share)
    reach = np.zeros_like(score)
    seen = np.zeros_like(score)
    np.add.at(reach, group, unshadowed)
    np.add.at(seen, group, visible)
    fraction = np.where(reach > 0, seen / np.where(reach > 0, reach, 1.0), 1.0)
    changed = 0
    for g in np.unique(group):
        ranked = np.flatnonzero(score[g] >= SHARE_FLOOR)
        ranked = ranked[np.argsort(-score[g, ranked], kind="stable")][:slots]
        taken = set(ranked.tolist())
        rest = [k for k, ok in zip(cand[g], valid[g]) if ok > 0 and k not in taken]
        merged = np.r_[ranked, np.array(rest, dtype=np.int64)][:slots]
        cand[g] = np.r_[merged, np.zeros(slots - len(merged), dtype=np.int64)]
        valid[g] = np.r_[VISIBLE_FLOOR + (1.0 - VISIBLE_FLOOR) * fraction[g, merged], np.zeros(slots - len(merged))]
        changed += 1
    return cand.astype(np.uint32).ravel(), valid.astype(np.float32).ravel(), changed


def cache_candidates(mi_scene, seed: int = 0) -> dict | None:
    """Re-rank the loaded scene's lamp-set candidates for its camera (module docstring), in place;
    None if the scene has no lamp set, else counts: pre-pass points, cell-sides re-ranked."""
    import mitsuba as mi

    emitter = lamp_set_of(mi_scene)
    if emitter is None:
        return None
    arrays = lamp_set._SETS[emitter.set_key]
    points, normals = prepass_points(mi_scene, seed)
    unshadowed, visible = direct_light(mi_scene, arrays, points, normals)
    cand, valid, changed = ranked_candidates(arrays, points, normals, unshadowed, visible)
    emitter.candidates = mi.UInt32(cand)
    emitter.valid = mi.Float(valid)
    return {"points": int(len(points)), "cell_sides": changed}
