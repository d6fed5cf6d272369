"""Distant city blocks on the horizon field (CityRecipe.skyline_distance_m): one ring of buildings
that far beyond the grass margin, so a view down a street that leaves the city ends in buildings
rather than an empty field.

The ring runs along the four sides of the rectangle `inner` (the margin's outer edge pushed out by
the distance), SKYLINE_DEPTH_M deep. Along each side, parcels of SKYLINE_FRONTAGE_M alternate with
gaps of SKYLINE_GAP_M; each parcel gets a building from buildings.plan_building (facade, windows,
box/L/tower) with the recipe's height range. The north and south rows span the corners; the east
and west rows fill between them, so no two parcels overlap. Drawn from their own random stream and
added after every other object, so switching the skyline on moves no other object or instance id.
"""
from __future__ import annotations

import numpy as np

from workbench.scene.city.buildings import building_parts, plan_building
from workbench.scene.city.recipe import SKYLINE_DEPTH_M, CityRecipe
from workbench.scene.city.types import Mesh

SKYLINE_FRONTAGE_M = (25.0, 70.0)     # a parcel's length along the ring (m)
SKYLINE_GAP_M = (8.0, 30.0)           # the open ground between neighbouring parcels (m)
SKYLINE_MIN_DEPTH_FRACTION = 0.5      # a parcel is 50–100 % of the ring's depth, from its inner edge


def _row(a0: float, a1: float, rng: np.random.Generator) -> list[tuple[float, float]]:
    """Intervals along one side from a0 to a1: parcels separated by random gaps."""
    out, a = [], a0 + rng.uniform(*SKYLINE_GAP_M) / 2
    while True:
        length = rng.uniform(*SKYLINE_FRONTAGE_M)
        if a + length > a1:
            break
        out.append((a, a + length))
        a += length + rng.uniform(*SKYLINE_GAP_M)
    return out


def skyline_parcels(inner: tuple[float, float, float, float], rng: np.random.Generator) -> list[tuple]:
    """Parcels (xmin, ymin, xmax, ymax) of the ring just outside `inner`, SKYLINE_DEPTH_M deep."""
    x0, y0, x1, y1 = inner
    d = SKYLINE_DEPTH_M
    parcels = []
    for side in ("south", "north", "west", "east"):
        span = (x0 - d, x1 + d) if side in ("south", "north") else (y0, y1)
        for a, b in _row(*span, rng):
            depth = d * rng.uniform(SKYLINE_MIN_DEPTH_FRACTION, 1.0)
            parcels.append({"south": (a, y0 - depth, b, y0), "north": (a, y1, b, y1 + depth),
                            "west": (x0 - depth, a, x0, b), "east": (x1, a, x1 + depth, b)}[side])
    return parcels


def skyline_objects(recipe: CityRecipe, road_bounds: tuple, rng: np.random.Generator) -> list[tuple]:
    """(class, meshes, footprint, meta) of each skyline building, outside the city's grass margin."""
    rx0, ry0, rx1, ry1 = road_bounds
    out = recipe.ground_margin_m + recipe.skyline_distance_m
    objs = []
    for parcel in skyline_parcels((rx0 - out, ry0 - out, rx1 + out, ry1 + out), rng):
        plan = plan_building(parcel, 0.0, recipe.building_height_min_m, recipe.building_height_max_m, rng)
        meshes = [Mesh(v.astype(np.float64), f.astype(np.int32), mat)
                  for mat, (v, f) in building_parts(plan).items() if len(f)]
        lo = np.min([p[0] for p in plan.parts], axis=0)
        hi = np.max([p[1] for p in plan.parts], axis=0)
        footprint = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
        objs.append(("building", meshes, footprint,
                     {"part": "skyline", "facade": plan.facade, "style": plan.style, "height_m": plan.height_m,
                      "parts_m": [tuple(map(tuple, p)) for p in plan.parts]}))
    return objs
