"""`generate_city`: recipe → City (streets, sidewalks, markings, buildings, placed objects).

Independent random streams come from the seed: one for the buildings (seed only), one for the
placements (seed and arrangement) and one for the distant skyline (seed only), so changing the
arrangement moves the cars, people and street furniture but never a building.
"""
from __future__ import annotations

import numpy as np

from workbench.scene.city import geometry as g
from workbench.scene.city.catalog import build_asset
from workbench.scene.city.buildings import building_parts, plan_building, split_lot
from workbench.scene.city.layout import CityLayout, build_layout, marking_rects
from workbench.scene.city.materials import city_materials
from workbench.scene.city.placement import Placement, place_objects
from workbench.scene.city.recipe import CityRecipe
from workbench.scene.city.skyline import skyline_objects
from workbench.scene.city.tunnel import tunnel_object
from workbench.scene.city.types import City, CityObject, Mesh

MARKING_LIFT_M = 0.005    # paint sits this far above the asphalt (no coplanar faces)
_LAYOUT_STREAM, _PLACEMENT_STREAM, _SKYLINE_STREAM = 1, 2, 3


def _rect_polygon(r) -> np.ndarray:
    x0, y0, x1, y1 = r
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


def _slab(rects: np.ndarray, top_m: float) -> g.Part:
    """Raised slabs (boxes from 0 to top_m) or flat quads when there is no kerb."""
    if top_m < 1e-3:
        return g.ground_rects(rects, 0.0)
    r = np.atleast_2d(rects)
    lo = np.column_stack([r[:, 0], r[:, 1], np.zeros(len(r))])
    hi = np.column_stack([r[:, 2], r[:, 3], np.full(len(r), top_m)])
    return g.boxes(lo, hi)


def _mesh(part: g.Part, material: str) -> Mesh:
    return Mesh(part[0].astype(np.float64), part[1].astype(np.int32), material)


def _frame(inner_m: tuple[float, float, float, float], width_m: float) -> np.ndarray:
    """Four rectangles (N×4) that frame the rectangle inner_m (xmin, ymin, xmax, ymax) width_m wide."""
    x0, y0, x1, y1 = inner_m
    w = width_m
    return np.array([(x0 - w, y0 - w, x1 + w, y0), (x0 - w, y1, x1 + w, y1 + w),
                     (x0 - w, y0, x0, y1), (x1, y0, x1 + w, y1)])


def _static_objects(recipe: CityRecipe, layout: CityLayout, rng: np.random.Generator):
    """Road, ground, sidewalks, lots, markings and buildings; also the building part rectangles.

    Footprints: a lot's rectangle, a building's bounding rectangle (its parts are in
    meta['parts_m']); None for the road, sidewalk rings, markings and the outer ground."""
    objs: list[tuple[str, list[Mesh], np.ndarray | None, dict]] = []
    x0, y0, x1, y1 = layout.road_bounds
    objs.append(("road", [_mesh(g.ground_rects(layout.road_rects, 0.0), "asphalt")], None, {}))
    m, f = recipe.ground_margin_m, recipe.horizon_field_m
    outer = [_mesh(g.ground_rects(_frame((x0, y0, x1, y1), m), 0.0), "grass")] if m > 0 else []
    if f > 0:              # a camera 1.5 m up sees its edge 1.5 m / distance rad below the horizon
        outer.append(_mesh(g.ground_rects(_frame((x0 - m, y0 - m, x1 + m, y1 + m), f), 0.0), "grass"))
    if outer:
        objs.append(("ground", outer, None, {"part": "margin"}))
    curb = layout.curb_height_m
    building_rects = []
    buildings = []
    for b, lot in enumerate(layout.lots):
        strips = layout.sidewalk_rects[4 * b:4 * b + 4]
        objs.append(("sidewalk", [_mesh(_slab(strips, curb), "concrete")], None, {"block": b}))
        lot_material = "grass" if rng.random() < 0.4 else "concrete_dark"
        objs.append(("ground", [_mesh(_slab(lot[None], curb), lot_material)],
                     _rect_polygon(lot), {"block": b, "part": "lot"}))
        for parcel in split_lot(tuple(lot), rng):
            plan = plan_building(parcel, curb, recipe.building_height_min_m,
                                 recipe.building_height_max_m, rng)
            meshes = [_mesh(p, mat) for mat, p in building_parts(plan).items() if len(p[1])]
            lo = np.min([p[0] for p in plan.parts], axis=0)
            hi = np.max([p[1] for p in plan.parts], axis=0)
            building_rects += [_rect_polygon((a[0], a[1], c[0], c[1])) for a, c in plan.parts]
            buildings.append(("building", meshes, _rect_polygon((lo[0], lo[1], hi[0], hi[1])),
                              {"block": b, "facade": plan.facade, "style": plan.style,
                               "height_m": plan.height_m,
                               "parts_m": [tuple(map(tuple, p)) for p in plan.parts]}))
    for seg, white, yellow in marking_rects(layout, recipe.lanes_per_direction):
        meshes = [_mesh(g.ground_rects(r, MARKING_LIFT_M), mat)
                  for r, mat in ((white, "lane_white"), (yellow, "lane_yellow")) if len(r)]
        objs.append(("marking", meshes, None, {"segment_rect": seg}))
    return objs + buildings, building_rects


def _to_world(p: Placement) -> np.ndarray:
    h = np.radians(p.heading_deg)
    t = np.eye(4)
    t[:2, :2] = [[np.cos(h), -np.sin(h)], [np.sin(h), np.cos(h)]]
    t[:3, 3] = p.position_m
    return t


def _placed_object(p: Placement) -> tuple[str, list[Mesh], np.ndarray, dict]:
    asset = build_asset(p.class_name, p.variant, p.detail)
    meshes = [Mesh(g.place(m.vertices, p.heading_deg, p.position_m), m.faces, m.material)
              for m in asset.meshes(p.paint)]
    meta = {"variant": p.variant, "detail": p.detail, "position_m": p.position_m.copy(), "heading_deg": p.heading_deg,
            "size_m": (asset.length_m, asset.width_m, asset.height_m), "paint": p.paint,
            "lane_index": p.lane_index, "parked": p.parked, "to_world": _to_world(p)}
    return p.class_name, meshes, p.footprint_xy, meta


def generate_city(recipe: CityRecipe) -> City:
    """Build the city of a recipe; the same recipe always gives the same arrays, bit for bit."""
    if not isinstance(recipe, CityRecipe):
        raise TypeError(f"generate_city needs a CityRecipe, got {type(recipe).__name__}")
    layout = build_layout(recipe)
    rng_layout = np.random.default_rng([recipe.seed, _LAYOUT_STREAM])
    rng_place = np.random.default_rng([recipe.seed, _PLACEMENT_STREAM, recipe.arrangement])
    static, building_rects = _static_objects(recipe, layout, rng_layout)
    tunnel = []
    if recipe.tunnel is not None:          # last, so a tunnel moves no other object's instance id
        meshes, footprint, meta = tunnel_object(recipe, layout)
        tunnel = [("tunnel", meshes, footprint, meta)]
        building_rects = building_rects + [footprint]    # keeps tree canopies and lamp arms out
    placed = [_placed_object(p) for p in place_objects(recipe, layout, building_rects, rng_place)]
    skyline = []
    if recipe.skyline_distance_m > 0:      # last of all, for the same reason as the tunnel
        skyline = skyline_objects(recipe, layout.road_bounds,
                                  np.random.default_rng([recipe.seed, _SKYLINE_STREAM]))
    objects = [CityObject(cls, i + 1, meshes, fp, meta)
               for i, (cls, meshes, fp, meta) in enumerate(static + placed + tunnel + skyline)]
    x0, y0, x1, y1 = layout.road_bounds
    m = recipe.ground_margin_m + recipe.horizon_field_m
    return City(objects, city_materials(), recipe.seed, (x0 - m, y0 - m, x1 + m, y1 + m),
                meta={"recipe": recipe.model_dump(), "arrangement": recipe.arrangement,
                      "layout": layout})
