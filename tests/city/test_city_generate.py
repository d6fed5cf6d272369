"""generate_city: reproducible, placement rules hold over many seeds, clear errors."""

import numpy as np
import pytest
from pydantic import ValidationError

from workbench.scene.city import CLASS_IDS, CityRecipe, generate_city
from workbench.scene.city import geometry as g

VEHICLES = ("car", "bus", "truck")


def _arrays(city):
    return [(o.class_name, o.instance_id, m.material, m.vertices, m.faces)
            for o in city.objects for m in o.meshes]


def _same(a, b):
    return len(a) == len(b) and all(
        x[:3] == y[:3] and np.array_equal(x[3], y[3]) and np.array_equal(x[4], y[4])
        and x[3].dtype == y[3].dtype for x, y in zip(a, b))


def test_same_seed_identical_bit_for_bit():
    r = CityRecipe(seed=11, arrangement=3)
    assert _same(_arrays(generate_city(r)), _arrays(generate_city(r)))


def test_arrangement_moves_objects_not_buildings():
    a = generate_city(CityRecipe(seed=5, arrangement=0))
    b = generate_city(CityRecipe(seed=5, arrangement=1))
    pick = lambda c, cls: [o for o in c.objects if o.class_name == cls]
    assert _same(_arrays_of(pick(a, "building")), _arrays_of(pick(b, "building")))
    assert _same(_arrays_of(pick(a, "road")), _arrays_of(pick(b, "road")))
    pa = np.array([o.meta["position_m"] for o in pick(a, "car")])
    pb = np.array([o.meta["position_m"] for o in pick(b, "car")])
    assert pa.shape == pb.shape and not np.allclose(pa, pb)
    c = generate_city(CityRecipe(seed=6, arrangement=0))
    assert not _same(_arrays_of(pick(a, "building")), _arrays_of(pick(c, "building")))


def _arrays_of(objs):
    return [(o.class_name, 0, m.material, m.vertices, m.faces) for o in objs for m in o.meshes]


def test_counts_labels_and_finite():
    r = CityRecipe(seed=2)
    city = generate_city(r)
    count = lambda cls: sum(o.class_name == cls for o in city.objects)
    assert (count("car"), count("pedestrian"), count("bus"), count("truck")) == \
        (r.n_cars, r.n_pedestrians, r.n_buses, r.n_trucks)
    assert (count("tree"), count("lamp"), count("bench"), count("mailbox")) == \
        (r.n_trees, r.n_lamps, r.n_benches, r.n_mailboxes)
    assert count("building") >= 4 * r.blocks_x * r.blocks_y and count("road") == 1
    ids = [o.instance_id for o in city.objects]
    assert min(ids) > 0 and len(set(ids)) == len(ids)
    assert {o.class_name for o in city.objects} <= set(CLASS_IDS)
    x0, y0, x1, y1 = city.extent_m
    for o in city.objects:
        for m in o.meshes:
            assert m.material in city.materials
            assert m.vertices.dtype == np.float64 and m.faces.dtype == np.int32
            assert np.all(np.isfinite(m.vertices)) and m.faces.max() < len(m.vertices)
            assert np.all((m.vertices[:, 0] >= x0) & (m.vertices[:, 0] <= x1))
            assert np.all((m.vertices[:, 1] >= y0) & (m.vertices[:, 1] <= y1))
            assert m.vertices[:, 2].min() >= -1e-9
    heights = [o.meta["height_m"] for o in city.objects if o.class_name == "building"]
    assert r.building_height_min_m <= min(heights) and max(heights) <= r.building_height_max_m + 1e-9
    assert len({o.meta["facade"] for o in city.objects if o.class_name == "building"}) >= 3


@pytest.mark.parametrize("seed", range(12))
def test_placement_rules(seed):
    r = CityRecipe(seed=seed, arrangement=seed % 5, lanes_per_direction=1 + seed % 2,
                   n_cars=20, n_pedestrians=30)
    city = generate_city(r)
    layout = city.meta["layout"]
    lanes = layout.lanes
    ground = []
    for o in city.objects:
        if o.class_name in VEHICLES:
            fp = o.footprint_xy
            assert layout.on_road(fp).all(), "vehicle corner off the road"
            lane = lanes[o.meta["lane_index"]]
            s, off = lane.lane_coords(o.meta["position_m"][:2])
            assert abs(off[0]) <= lane.width_m / 2 and 0 < s[0] < lane.length_m   # centre in its lane
            assert g.rect_inside(fp, lane.segment_rect)
            dh = (o.meta["heading_deg"] - lane.heading_deg + 180) % 360 - 180
            assert abs(dh) <= 5.0                                  # along the road direction
            assert o.meta["position_m"][2] == 0.0
            if o.class_name in ("bus", "truck"):
                assert lane.rank == r.lanes_per_direction - 1     # kerb lane
            ground.append(fp)
        elif o.class_name == "pedestrian":
            p = o.meta["position_m"]
            assert layout.on_sidewalk(p[None, :2], tolerance_m=0.5).all()
            assert not layout.on_road(p[None, :2]).any()
            assert p[2] == pytest.approx(r.curb_height_m)
            ground.append(o.footprint_xy)
        elif o.class_name in ("tree", "lamp", "bench", "mailbox"):
            assert layout.on_sidewalk(o.footprint_xy, tolerance_m=1e-9).all()
            ground.append(o.footprint_xy)
    for i in range(len(ground)):
        for j in range(i + 1, len(ground)):
            assert not g.rects_overlap(ground[i], ground[j]), "footprints overlap"


@pytest.mark.parametrize("kwargs,match", [
    ({"block_size_m": -5}, "block_size_m"),
    ({"blocks_x": 0}, "blocks_x"),
    ({"blocks_y": 0}, "blocks_y"),
    ({"building_height_min_m": 50, "building_height_max_m": 20}, "building_height_min_m"),
    ({"block_size_m": 25, "sidewalk_width_m": 4}, "block_size_m"),
    ({"n_cars": -1}, "n_cars"),
    ({"colour": "red"}, "colour"),
])
def test_malformed_recipe(kwargs, match):
    with pytest.raises(ValidationError, match=match):
        CityRecipe(**kwargs)


def test_too_many_objects_to_place():
    with pytest.raises(ValueError, match=r"too many vehicles.*n_cars=1500"):
        generate_city(CityRecipe(n_cars=1500))
    with pytest.raises(ValueError, match="n_pedestrians=4000"):
        generate_city(CityRecipe(n_pedestrians=4000))
    with pytest.raises(TypeError, match="CityRecipe"):
        generate_city({"seed": 1})


def test_recipe_json_round_trip():
    from workbench.scene.city import PoseParams
    r = CityRecipe(seed=3, blocks_x=3, lanes_per_direction=2)
    assert CityRecipe.model_validate_json(r.model_dump_json()) == r
    p = PoseParams(mode="manual", manual_position_xy_m=(1.0, 2.0), pan_range_deg=(-3, 3))
    assert PoseParams.model_validate_json(p.model_dump_json()) == p
    assert r.street_width_m == 14.0 and r.pitch_m == 114.0
