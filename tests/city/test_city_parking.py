"""Cars parked at the kerb (CityRecipe.n_parked_cars), checked from the mesh vertices and the
street layout, not from the placement code's footprints:

- each parked car stands in a kerb lane, its body parallel to the lane within 0.5°, the side of
  its body nearest the kerb 0.25 m (± what the heading jitter and mirrors add) from the kerb
  line on the lane's right (right-hand traffic), inside its street segment;
- none stands under a tunnel's roof;
- the cars, people and furniture of the same recipe without parked cars are unchanged (parked
  cars are placed last), so adding them moves no other object;
- too many of them is refused with the field named.
"""
import numpy as np
import pytest

from workbench.scene.city import CityRecipe, TunnelParams, generate_city


def _parked(city):
    return [o for o in city.objects if o.meta.get("parked")]


@pytest.mark.parametrize("detail", ["simple", "detailed"])
def test_parked_cars_stand_at_the_kerb_along_the_lane(detail):
    city = generate_city(CityRecipe(seed=4, n_parked_cars=30, asset_detail=detail))
    lanes = {ln.index: ln for ln in city.meta["layout"].lanes}
    parked = _parked(city)
    assert len(parked) == 30 and all(o.class_name == "car" for o in parked)
    for o in parked:
        lane = lanes[o.meta["lane_index"]]
        assert lane.rank == city.meta["recipe"]["lanes_per_direction"] - 1           # the kerb lane
        v = np.vstack([m.vertices for m in o.meshes])
        body = v[v[:, 2] > 0.3]                                                      # above the wheels
        along, left = lane.lane_coords(body[:, :2])
        kerb_gap = left.min() + lane.width_m / 2                                     # kerb line at −w/2
        length = along.max() - along.min()
        assert 0.0 < kerb_gap < 0.25 + length * np.sin(np.radians(0.5)) + 0.05, kerb_gap
        h = (o.meta["heading_deg"] - lane.heading_deg + 180.0) % 360.0 - 180.0
        assert abs(h) <= 0.5
        x0, y0, x1, y1 = lane.segment_rect
        assert np.all((v[:, 0] >= x0 - 0.3) & (v[:, 0] <= x1 + 0.3) & (v[:, 1] >= y0 - 0.3) & (v[:, 1] <= y1 + 0.3))


def test_no_parked_car_under_a_tunnel_and_other_objects_unchanged():
    tunnel = TunnelParams(street_index=1, length_m=84.0)
    base = generate_city(CityRecipe(seed=5, tunnel=tunnel))
    city = generate_city(CityRecipe(seed=5, tunnel=tunnel, n_parked_cars=40))
    frame = city.objects[-1].meta["frame"]
    parked = _parked(city)
    assert len(parked) == 40
    for o in parked:
        v = np.vstack([m.vertices for m in o.meshes])
        under = (np.abs(v[:, 0] - frame.x_m) < frame.half_width_m) & (v[:, 1] > frame.y_south_m) & \
            (v[:, 1] < frame.y_north_m)
        assert not under.any()
    moved = [(a.class_name, b.class_name) for a, b in zip(base.objects[:-1], city.objects)
             if a.class_name != b.class_name or not all(np.array_equal(p.vertices, q.vertices)
                                                        for p, q in zip(a.meshes, b.meshes))]
    assert not moved


def test_too_many_parked_cars_is_refused_naming_the_field():
    with pytest.raises(ValueError, match="n_parked_cars=500"):
        generate_city(CityRecipe(seed=1, n_parked_cars=500))
