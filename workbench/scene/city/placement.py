"""Placement of movable objects and street furniture, with no interpenetration.

Rules (after isetauto's placeObjects, the paper's generator): vehicles ride in lanes along the
travel direction (cars with a small heading jitter, buses and trucks in the kerb lane); parked
cars stand in the kerb lane, aligned with it, their side PARKED_KERB_GAP_M from the kerb, with
gaps as short as PARKED_GAP_M (never in a tunnel, placed last so that they move no
other object); people
stand anywhere on sidewalks with a uniformly random heading (detailed cyclists ride along the
sidewalk strip, either way, ± 5°); trees, lamps and mailboxes stand
near the kerb, benches near the building line, facing the street. Every object has ground
footprints (oriented rectangles) and, for trees and lamps, overhead footprints (canopy, arm);
a candidate overlapping anything in the same layer is rejected and resampled (SAT test).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError
from workbench.scene.city import geometry as g
from workbench.scene.city.catalog import build_asset, variant_names
from workbench.scene.city.layout import LANE_END_CLEARANCE_M, CityLayout
from workbench.scene.city.materials import BUS_PAINTS, CAR_PAINTS
from workbench.scene.city.people import CYCLISTS
from workbench.scene.city.recipe import CityRecipe

MAX_TRIES = 200
CYCLIST_HEADING_JITTER_DEG = 5.0
VEHICLE_GAP_M = 0.8          # bumper-to-bumper / side clearance between vehicles
CAR_HEADING_JITTER_DEG = 4.0
HEAVY_HEADING_JITTER_DEG = 1.5
PARKED_KERB_GAP_M = 0.25     # kerb to the parked car's side (m)
PARKED_GAP_M = 0.5           # bumper to bumper between parked cars (m)
PARKED_HEADING_JITTER_DEG = 0.5  # parked cars stand almost square to the kerb (deg)
RENYI_PARKING = 0.7476       # jamming density of random sequential parking in 1-D (Rényi 1958)


@dataclass
class Placement:
    """One placed object: class, variant, ground position (m), heading (deg) and footprint."""

    class_name: str
    variant: str
    position_m: np.ndarray       # x, y, z of the footprint centre on the ground it stands on
    heading_deg: float
    footprint_xy: np.ndarray     # 4×2
    paint: str | None = None
    lane_index: int | None = None
    detail: str = "simple"       # CityRecipe.asset_detail the variant was drawn at
    parked: bool = False         # a car parked at the kerb (else moving, or not a vehicle)


class Occupancy:
    """Oriented rectangles already taken, per layer ('ground', 'overhead')."""

    def __init__(self):
        self._rects: dict[str, list[np.ndarray]] = {}
        self._circles: dict[str, np.ndarray] = {}

    def add(self, rect: np.ndarray, layer: str) -> None:
        self._rects.setdefault(layer, []).append(rect)
        c = np.append(rect.mean(0), np.linalg.norm(rect - rect.mean(0), axis=1).max())
        self._circles[layer] = np.vstack([self._circles.get(layer, np.zeros((0, 3))), c])

    def free(self, rect: np.ndarray, layer: str, margin_m: float = 0.0) -> bool:
        circles = self._circles.get(layer)
        if circles is None or len(circles) == 0:
            return True
        c = rect.mean(0)
        r = np.linalg.norm(rect - c, axis=1).max()
        near = np.nonzero(np.hypot(*(circles[:, :2] - c).T) < circles[:, 2] + r + margin_m)[0]
        return not any(g.rects_overlap(rect, self._rects[layer][i], margin_m) for i in near)


def _fail(what: str, k: int, n: int, field: str, hint: str) -> ValueError:
    return ValueError(f"could not place {what} {k + 1} of {n} without overlap after {MAX_TRIES} "
                      f"tries; lower {field}={n} or {hint}")


def _curb_spot(layout: CityLayout, rng, inset_m: float):
    """Random point on a sidewalk strip at inset_m from the kerb; heading faces the street."""
    b = layout.blocks[int(rng.integers(len(layout.blocks)))]
    side = int(rng.integers(4))              # 0 south, 1 north, 2 west, 3 east kerb
    x0, y0, x1, y1 = b
    if side < 2:
        x = rng.uniform(x0 + 2.0, x1 - 2.0)
        return np.array([x, y0 + inset_m if side == 0 else y1 - inset_m]), (270.0, 90.0)[side]
    y = rng.uniform(y0 + 2.0, y1 - 2.0)
    return np.array([x0 + inset_m if side == 2 else x1 - inset_m, y]), (180.0, 0.0)[side - 2]


def _place_furniture(kind: str, n: int, field: str, inset_m, layout: CityLayout, occ: Occupancy,
                     rng, z_m: float, detail: str) -> list[Placement]:
    names = variant_names(kind, detail)
    out = []
    for k in range(n):
        variant = names[int(rng.integers(len(names)))]
        a = build_asset(kind, variant, detail)
        for _ in range(MAX_TRIES):
            xy, heading = _curb_spot(layout, rng, inset_m(a))
            ground, overhead = _furniture_rects(kind, a, xy, heading)
            if occ.free(ground, "ground", 0.3) and \
                    (overhead is None or occ.free(overhead, "overhead", 0.3)):
                break
        else:
            raise _fail(kind, k, n, field, "enlarge the city (blocks_x, blocks_y, block_size_m)")
        occ.add(ground, "ground")
        if overhead is not None:
            occ.add(overhead, "overhead")
        out.append(Placement(kind, variant, np.array([xy[0], xy[1], z_m]), heading, ground, detail=detail))
    return out


def _furniture_rects(kind: str, a, xy, heading):
    if kind == "tree":        # tree pit on the ground, canopy overhead
        return (g.oriented_rect(xy, 1.0, 1.0, heading),
                g.oriented_rect(xy, a.length_m, a.width_m, heading))
    if kind == "lamp":        # base on the ground; arm reaching over the street overhead
        h = np.radians(heading)
        mid = xy + np.array([np.cos(h), np.sin(h)]) * (a.length_m / 2 - 0.1)
        return g.oriented_rect(xy, 0.4, 0.4, heading), g.oriented_rect(mid, a.length_m, 0.5, heading)
    return g.oriented_rect(xy, a.length_m, a.width_m, heading), None


def _place_vehicles(kind: str, n: int, field: str, lanes, occ: Occupancy, rng, paints,
                    jitter_deg: float, detail: str, gap_m: float = VEHICLE_GAP_M,
                    kerb_gap_m: float | None = None) -> list[Placement]:
    """Vehicles in `lanes`, along the travel direction ± jitter_deg, inside their segment, gap_m
    clear of others; with kerb_gap_m, parked: their side kerb_gap_m from the kerb on the lane's
    right (right-hand traffic), instead of anywhere across the lane."""
    if n and not lanes:
        raise InvalidValueError(f"{field}={n} but no street segment has a lane for it (parked cars need a kerb lane "
                         f"outside a tunnel); set {field}=0 or add blocks")
    names = variant_names(kind, detail)
    weights = np.array(list(paints.values())) if isinstance(paints, dict) else None
    paint_names = list(paints)
    lengths = np.array([ln.length_m for ln in lanes]) - 2 * LANE_END_CLEARANCE_M
    if n and lengths.max() <= 0:
        raise InvalidValueError(f"street segments are too short to hold a {kind}: {field}={n}")
    prob = np.clip(lengths, 0, None) / np.clip(lengths, 0, None).sum()
    out = []
    for k in range(n):
        variant = names[int(rng.integers(len(names)))]
        a = build_asset(kind, variant, detail)
        paint = paint_names[int(rng.choice(len(paint_names), p=weights / weights.sum()))] \
            if weights is not None else paint_names[int(rng.integers(len(paint_names)))]
        for _ in range(MAX_TRIES):
            lane = lanes[int(rng.choice(len(lanes), p=prob))]
            s = rng.uniform(LANE_END_CLEARANCE_M + a.length_m / 2,
                            lane.length_m - LANE_END_CLEARANCE_M - a.length_m / 2)
            if kerb_gap_m is None:
                slack = max(0.0, (lane.width_m - a.width_m) / 2 - 0.15)
                offset = rng.uniform(-0.5, 0.5) * slack
            else:
                offset = -(lane.width_m / 2 - kerb_gap_m - a.width_m / 2)
            xy = lane.point(s, offset)
            heading = (lane.heading_deg + rng.uniform(-jitter_deg, jitter_deg)) % 360.0
            rect = g.oriented_rect(xy, a.length_m, a.width_m, heading)
            if g.rect_inside(rect, lane.segment_rect) and occ.free(rect, "ground", gap_m):
                break
        else:
            raise _fail(kind, k, n, field, "enlarge the city (blocks_x, blocks_y, lanes_per_direction)")
        occ.add(rect, "ground")
        out.append(Placement(kind, variant, np.array([xy[0], xy[1], 0.0]), heading, rect, paint,
                             lane.index, detail, parked=kerb_gap_m is not None))
    return out


def _place_pedestrians(n: int, layout: CityLayout, occ: Occupancy, rng, z_m: float,
                       detail: str) -> list[Placement]:
    names = variant_names("pedestrian", detail)
    strips = layout.sidewalk_rects
    area = (strips[:, 2] - strips[:, 0]) * (strips[:, 3] - strips[:, 1])
    out = []
    for k in range(n):
        variant = names[int(rng.integers(len(names)))]
        a = build_asset("pedestrian", variant, detail)
        r = 0.5 * max(a.length_m, a.width_m)
        for _ in range(MAX_TRIES):
            x0, y0, x1, y1 = strips[int(rng.choice(len(strips), p=area / area.sum()))]
            xy = np.array([rng.uniform(x0 + r, x1 - r), rng.uniform(y0 + r, y1 - r)])
            if variant in CYCLISTS:           # ride along the strip, either way
                along = 0.0 if x1 - x0 >= y1 - y0 else 90.0
                heading = float(along + 180.0 * rng.integers(2) +
                                rng.uniform(-CYCLIST_HEADING_JITTER_DEG, CYCLIST_HEADING_JITTER_DEG)) % 360.0
            else:
                heading = float(rng.uniform(0.0, 360.0))
            rect = g.oriented_rect(xy, a.length_m, a.width_m, heading)
            if occ.free(rect, "ground", 0.15):
                break
        else:
            raise _fail("pedestrian", k, n, "n_pedestrians", "enlarge the city")
        occ.add(rect, "ground")
        out.append(Placement("pedestrian", variant, np.array([xy[0], xy[1], z_m]), heading, rect,
                             detail=detail))
    return out


def check_capacity(recipe: CityRecipe, layout: CityLayout) -> None:
    """Refuse counts that cannot fit, before trying (lanes: Rényi's parking limit; sidewalks:
    30 % of their area at ~1 m² a person, 1.5 m² a tree or lamp, 2 m² a bench or mailbox)."""
    lane_len = sum(max(0.0, ln.length_m - 2 * LANE_END_CLEARANCE_M) for ln in layout.lanes)
    need = (recipe.n_cars * (4.6 + VEHICLE_GAP_M) + recipe.n_buses * (12.1 + VEHICLE_GAP_M)
            + recipe.n_trucks * (7.9 + VEHICLE_GAP_M) + recipe.n_parked_cars * (4.6 + PARKED_GAP_M))
    if need > RENYI_PARKING * lane_len:
        raise InvalidValueError(
            f"too many vehicles for the streets: n_cars={recipe.n_cars}, n_parked_cars={recipe.n_parked_cars}, "
            f"n_buses={recipe.n_buses}, "
            f"n_trucks={recipe.n_trucks} need ~{need:.0f} m of lane but random parking fills at most "
            f"{RENYI_PARKING * lane_len:.0f} m of the {lane_len:.0f} m available; lower the counts or "
            "enlarge the city (blocks_x, blocks_y, lanes_per_direction)")
    s = layout.sidewalk_rects
    walk_area = float(((s[:, 2] - s[:, 0]) * (s[:, 3] - s[:, 1])).sum())
    used = recipe.n_pedestrians * 1.0 + (recipe.n_trees + recipe.n_lamps) * 1.5 + \
        (recipe.n_benches + recipe.n_mailboxes) * 2.0
    if used > 0.3 * walk_area:
        raise InvalidValueError(
            f"too many pedestrians and street furniture for {walk_area:.0f} m² of sidewalk: "
            f"n_pedestrians={recipe.n_pedestrians}, n_trees={recipe.n_trees}, n_lamps={recipe.n_lamps}, "
            f"n_benches={recipe.n_benches}, n_mailboxes={recipe.n_mailboxes}; lower them or "
            "enlarge the city")


def place_objects(recipe: CityRecipe, layout: CityLayout, building_rects: list[np.ndarray],
                  rng: np.random.Generator) -> list[Placement]:
    """Every movable object and piece of street furniture of one arrangement."""
    check_capacity(recipe, layout)
    occ = Occupancy()
    for rect in building_rects:
        occ.add(rect, "overhead")
    kerb = tuple(ln for ln in layout.lanes if ln.rank == recipe.lanes_per_direction - 1)
    parking = tuple(ln for ln in kerb             # not under a tunnel's roof (its footprint is overhead)
                    if occ.free(_box_corners(ln.segment_rect), "overhead"))
    z, d = layout.curb_height_m, recipe.asset_detail
    out = _place_furniture("tree", recipe.n_trees, "n_trees", lambda a: 0.9, layout, occ, rng, z, d)
    out += _place_furniture("lamp", recipe.n_lamps, "n_lamps", lambda a: 0.5, layout, occ, rng, z, d)
    out += _place_furniture("mailbox", recipe.n_mailboxes, "n_mailboxes", lambda a: 0.7, layout, occ, rng, z, d)
    out += _place_furniture("bench", recipe.n_benches, "n_benches",
                            lambda a: layout.sidewalk_width_m - 0.5 - a.length_m / 2, layout, occ, rng, z, d)
    out += _place_vehicles("bus", recipe.n_buses, "n_buses", kerb, occ, rng,
                           BUS_PAINTS, HEAVY_HEADING_JITTER_DEG, d)
    out += _place_vehicles("truck", recipe.n_trucks, "n_trucks", kerb, occ, rng,
                           CAR_PAINTS, HEAVY_HEADING_JITTER_DEG, d)
    out += _place_vehicles("car", recipe.n_cars, "n_cars", layout.lanes, occ, rng,
                           CAR_PAINTS, CAR_HEADING_JITTER_DEG, d)
    out += _place_pedestrians(recipe.n_pedestrians, layout, occ, rng, z, d)
    out += _place_vehicles("car", recipe.n_parked_cars, "n_parked_cars", parking, occ, rng, CAR_PAINTS,
                           PARKED_HEADING_JITTER_DEG, d, PARKED_GAP_M, PARKED_KERB_GAP_M)
    return out


def _box_corners(box_xy) -> np.ndarray:
    """Corners (4×2) of an axis-aligned box (xmin, ymin, xmax, ymax)."""
    x0, y0, x1, y1 = box_xy
    return g.oriented_rect(np.array([(x0 + x1) / 2, (y0 + y1) / 2]), x1 - x0, y1 - y0, 0.0)
