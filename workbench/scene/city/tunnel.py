"""A straight road tunnel over one street segment (CityRecipe.tunnel, TunnelParams).

Cross-section (the street runs along +Y at x = c): the carriageway and both sidewalks lie
inside; a side wall of wall_thickness_m stands on each outer sidewalk edge (into the building lot,
where buildings keep ≥ 1 m back), a roof slab spans both walls from clearance_m above the road
up by roof_thickness_m. The slab's end faces are the portals' head walls. Luminaire housings
hang under the roof over the centre line, end to end as a continuous line by default
(TunnelParams); the centres of their glowing lenses (horizontal rectangles facing down, just
under each housing) are in the object's meta for render/lamps.py.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError
from workbench.scene.city import geometry as g
from workbench.scene.city.layout import CityLayout
from workbench.scene.city.recipe import CityRecipe
from workbench.scene.city.types import Mesh

HOUSING_ACROSS_M, HOUSING_TALL_M = 0.5, 0.15
HOUSING_MARGIN_M = 0.05               # housing beyond its lens at each end (at most half the gap)
LENS_HALF_WIDTH_M = 0.2               # lens 0.4 m across; its length is TunnelParams.luminaire_length_m
LENS_BELOW_HOUSING_M = 0.005


@dataclass(frozen=True)
class TunnelFrame:
    """Where a recipe's tunnel is: centre line x (m), portal y (south, north), inner half-width
    (centre line to a wall's inner face), road level z and the soffit height (m)."""

    x_m: float
    y_south_m: float
    y_north_m: float
    half_width_m: float
    road_z_m: float
    soffit_z_m: float

    def inside(self, xy: np.ndarray) -> np.ndarray:
        """True for points (N×2) under the roof, between the walls."""
        p = np.atleast_2d(xy)
        return ((np.abs(p[:, 0] - self.x_m) < self.half_width_m) &
                (p[:, 1] > self.y_south_m) & (p[:, 1] < self.y_north_m))


def tunnel_frame(recipe: CityRecipe, layout: CityLayout) -> TunnelFrame:
    """The frame of recipe.tunnel (which must be set), centred on its street segment."""
    t = recipe.tunnel
    if t is None:
        raise InvalidValueError("the recipe has no tunnel (CityRecipe.tunnel is None)")
    x = t.street_index * recipe.pitch_m
    y_mid = (t.segment_index + 0.5) * recipe.pitch_m
    half = layout.street_width_m / 2 + layout.sidewalk_width_m
    return TunnelFrame(float(x), float(y_mid - t.length_m / 2), float(y_mid + t.length_m / 2),
                       float(half), 0.0, float(t.clearance_m))


def luminaire_points(recipe: CityRecipe, frame: TunnelFrame) -> np.ndarray:
    """Lens centres (N×3, m) of the luminaires: one row over the centre line, spaced
    luminaire_spacing_m and centred along the tunnel."""
    t = recipe.tunnel
    n = max(1, int(np.floor(t.length_m / t.luminaire_spacing_m)))
    y = (frame.y_south_m + frame.y_north_m) / 2 + t.luminaire_spacing_m * (np.arange(n) - (n - 1) / 2)
    z = frame.soffit_z_m - HOUSING_TALL_M - LENS_BELOW_HOUSING_M
    return np.column_stack([np.full(n, frame.x_m), y, np.full(n, z)])


def tunnel_object(recipe: CityRecipe, layout: CityLayout) -> tuple[list[Mesh], np.ndarray, dict]:
    """(meshes, ground footprint 4×2, meta) of the recipe's tunnel. meta: 'frame' (TunnelFrame),
    'luminaires_m' (N×3 lens centres), 'lens_half_size_m', 'luminaire_kind', 'luminaire_flux_lm'."""
    t = recipe.tunnel
    f = tunnel_frame(recipe, layout)
    w, top = t.wall_thickness_m, f.soffit_z_m + t.roof_thickness_m
    x0, x1 = f.x_m - f.half_width_m, f.x_m + f.half_width_m
    shell = g.boxes(np.array([[x0 - w, f.y_south_m, 0.0], [x1, f.y_south_m, 0.0],
                              [x0 - w, f.y_south_m, f.soffit_z_m]]),
                    np.array([[x0, f.y_north_m, f.soffit_z_m], [x1 + w, f.y_north_m, f.soffit_z_m],
                              [x1 + w, f.y_north_m, top]]))
    pts = luminaire_points(recipe, f)
    a, h = HOUSING_ACROSS_M, HOUSING_TALL_M
    b = t.luminaire_length_m + 2 * min(HOUSING_MARGIN_M, (t.luminaire_spacing_m - t.luminaire_length_m) / 2)
    bottom = pts[:, 2] + LENS_BELOW_HOUSING_M
    housing = g.boxes(np.column_stack([pts[:, 0] - a / 2, pts[:, 1] - b / 2, bottom]),
                      np.column_stack([pts[:, 0] + a / 2, pts[:, 1] + b / 2, bottom + h]))
    meshes = [Mesh(v.astype(np.float64), fc.astype(np.int32), mat)
              for (v, fc), mat in ((shell, "concrete"), (housing, "metal_dark"))]
    footprint = np.array([[x0 - w, f.y_south_m], [x1 + w, f.y_south_m], [x1 + w, f.y_north_m],
                          [x0 - w, f.y_north_m]])
    meta = {"frame": f, "luminaires_m": pts, "lens_half_size_m": (LENS_HALF_WIDTH_M, t.luminaire_length_m / 2),
            "luminaire_kind": t.luminaire_kind, "luminaire_flux_lm": t.luminaire_flux_lm, "length_m": t.length_m}
    return meshes, footprint, meta
