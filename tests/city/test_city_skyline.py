"""Distant buildings on the horizon field (CityRecipe.skyline_distance_m), checked from the mesh
vertices and the road bounds, not from the skyline code's parcels:

- every skyline building stands in the ring skyline_distance_m … + SKYLINE_DEPTH_M beyond the grass
  margin, on the ground (z from 0), inside the field, no taller than the recipe allows;
- no two skyline buildings overlap, and seen from the city's centre they fill most of the horizon;
- switching the skyline on moves no other object and no instance id; the arrangement (which moves
  cars and people) never moves the skyline;
- a skyline beyond the field is refused with both fields named.
"""
import numpy as np
import pytest
from pydantic import ValidationError

from workbench.scene.city import CityRecipe, generate_city
from workbench.scene.city.recipe import SKYLINE_DEPTH_M

DISTANCE_M = 250.0


def _recipe(**kw):
    return CityRecipe(seed=6, horizon_field_m=1000.0, skyline_distance_m=DISTANCE_M, **kw)


def _skyline(city):
    return [o for o in city.objects if o.meta.get("part") == "skyline"]


def _bounds(obj):
    v = np.concatenate([m.vertices for m in obj.meshes])
    return v.min(axis=0), v.max(axis=0)


def test_skyline_buildings_stand_in_the_ring_on_the_field():
    recipe = _recipe()
    city = generate_city(recipe)
    x0, y0, x1, y1 = city.meta["layout"].road_bounds
    inner = recipe.ground_margin_m + DISTANCE_M
    sky = _skyline(city)
    assert len(sky) > 20 and all(o.class_name == "building" for o in sky)
    window = 0.03                                   # window panes stand 2 cm proud of a facade
    for o in sky:
        lo, hi = _bounds(o)
        assert lo[2] == 0.0 and hi[2] <= recipe.building_height_max_m + 1e-9
        # outside the inner rectangle on at least one side, inside the outer one on all
        outside_inner = (hi[0] <= x0 - inner + window or lo[0] >= x1 + inner - window
                         or hi[1] <= y0 - inner + window or lo[1] >= y1 + inner - window)
        assert outside_inner, (lo, hi)
        outer = inner + SKYLINE_DEPTH_M + window
        assert lo[0] >= x0 - outer and hi[0] <= x1 + outer and lo[1] >= y0 - outer and hi[1] <= y1 + outer
        assert city.extent_m[0] < lo[0] and hi[0] < city.extent_m[2]       # on the field
        assert city.extent_m[1] < lo[1] and hi[1] < city.extent_m[3]


def test_skyline_buildings_do_not_overlap_and_fill_most_of_the_horizon():
    city = generate_city(_recipe())
    boxes = [_bounds(o) for o in _skyline(city)]
    for i, (lo_a, hi_a) in enumerate(boxes):
        for lo_b, hi_b in boxes[i + 1:]:
            overlap = np.minimum(hi_a[:2], hi_b[:2]) - np.maximum(lo_a[:2], lo_b[:2])
            assert (overlap <= 0).any()
    x0, y0, x1, y1 = city.meta["layout"].road_bounds
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    covered = np.zeros(3600, dtype=bool)            # 0.1° azimuth bins
    for lo, hi in boxes:
        corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]) - centre
        az = np.degrees(np.arctan2(corners[:, 1], corners[:, 0]))
        if az.max() - az.min() > 180:               # straddles ±180°: unwrap
            az = np.where(az < 0, az + 360, az)
        bins = np.arange(int(np.floor(az.min() * 10)), int(np.ceil(az.max() * 10))) % 3600
        covered[bins] = True
    assert covered.mean() > 0.5


def test_switching_it_on_moves_nothing_else_and_the_arrangement_never_moves_it():
    off = generate_city(_recipe().updated(skyline_distance_m=0.0))
    on = generate_city(_recipe())
    n = len(off.objects)
    assert not _skyline(off) and len(on.objects) > n
    for a, b in zip(off.objects, on.objects[:n]):
        assert (a.class_name, a.instance_id) == (b.class_name, b.instance_id)
        assert all(np.array_equal(ma.vertices, mb.vertices) for ma, mb in zip(a.meshes, b.meshes))
    assert all(o.meta.get("part") == "skyline" for o in on.objects[n:])
    moved = generate_city(_recipe(arrangement=5))
    for a, b in zip(_skyline(on), _skyline(moved)):
        assert all(np.array_equal(ma.vertices, mb.vertices) for ma, mb in zip(a.meshes, b.meshes))


def test_a_skyline_beyond_the_field_is_refused_naming_both_fields():
    with pytest.raises(ValidationError, match="horizon_field_m >= 310.*skyline_distance_m"):
        CityRecipe(horizon_field_m=300.0, skyline_distance_m=250.0)
    with pytest.raises(ValidationError, match="horizon_field_m"):
        CityRecipe(skyline_distance_m=250.0)
