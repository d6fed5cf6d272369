"""The tunnel (scene/city/tunnel.py): where its walls, roof and luminaires are, that it moves no
other object, keeps street furniture out from under its roof, and tunnel camera poses."""
import numpy as np
import pytest

from workbench.scene.city import CityRecipe, PoseParams, TunnelParams, generate_city, sample_camera_poses

RECIPE = CityRecipe(seed=2, block_size_m=120.0, tunnel=TunnelParams(street_index=1, segment_index=1,
                                                                     length_m=100.0))


@pytest.fixture(scope="module")
def city():
    return generate_city(RECIPE)


def _tunnel(city):
    (t,) = [o for o in city.objects if o.class_name == "tunnel"]
    return t


def test_geometry_over_its_street_segment(city):
    t = _tunnel(city)
    pitch = RECIPE.pitch_m                                   # 120 + 7 m
    x, y_mid = 1 * pitch, 1.5 * pitch
    half = RECIPE.street_width_m / 2 + RECIPE.sidewalk_width_m
    v = np.concatenate([m.vertices for m in t.meshes])
    assert v[:, 0].min() == pytest.approx(x - half - 0.5) and v[:, 0].max() == pytest.approx(x + half + 0.5)
    assert v[:, 1].min() == pytest.approx(y_mid - 50.0) and v[:, 1].max() == pytest.approx(y_mid + 50.0)
    assert v[:, 2].min() == 0.0 and v[:, 2].max() == pytest.approx(5.0 + 1.0)
    lum = t.meta["luminaires_m"]
    assert len(lum) == 62 and np.allclose(np.diff(lum[:, 1]), 1.6) and np.allclose(lum[:, 0], x)   # 100 m / 1.6 m
    assert t.meta["lens_half_size_m"] == (0.2, 0.75)
    assert lum[:, 1].mean() == pytest.approx(y_mid) and np.all(lum[:, 2] < 5.0 - 0.15)
    # nothing but people, vehicles, benches and mailboxes under the roof; walls clear of buildings
    f = t.meta["frame"]
    for o in city.objects:
        if o.class_name in ("tree", "lamp"):
            assert not f.inside(o.footprint_xy).any(), o.class_name
        if o.class_name == "building":
            lo = np.min([p[0] for p in o.meta["parts_m"]], axis=0)
            hi = np.max([p[1] for p in o.meta["parts_m"]], axis=0)
            assert hi[0] <= x - half - 0.5 or lo[0] >= x + half + 0.5 or hi[1] <= f.y_south_m or \
                lo[1] >= f.y_north_m


def test_tunnel_is_the_last_object_and_moves_nothing_else(city):
    plain = generate_city(RECIPE.updated(tunnel=None))
    assert city.objects[-1].class_name == "tunnel" and city.objects[-1].instance_id == len(city.objects)
    same = [(o.class_name, o.instance_id) for o in plain.objects if o.class_name not in
            ("tree", "lamp", "bench", "mailbox", "pedestrian", "car", "bus", "truck")]
    assert same == [(o.class_name, o.instance_id) for o in city.objects[:len(same)]]


def test_recipe_refuses_a_tunnel_that_does_not_fit():
    with pytest.raises(ValueError, match="does not fit"):
        CityRecipe(tunnel=TunnelParams(length_m=95.0))       # 100 m blocks − 2 × 4 m sidewalks
    with pytest.raises(ValueError, match="street_index"):
        CityRecipe(tunnel=TunnelParams(street_index=3))
    with pytest.raises(ValueError, match="luminaire_length_m=2.0 exceeds luminaire_spacing_m=1.6"):
        TunnelParams(luminaire_length_m=2.0)


@pytest.mark.parametrize("view", ["exit", "entrance"])
def test_tunnel_poses(city, view):
    f = _tunnel(city).meta["frame"]
    poses = sample_camera_poses(city, PoseParams(mode="tunnel", tunnel_view=view,
                                                 tunnel_distance_range_m=(10.0, 30.0), seed=4), n=12)
    for p in poses:
        inside = bool(f.inside(p.position_m[None, :2])[0])
        assert inside == (view == "exit")
        north = abs(p.meta["lane_heading_deg"] - 90.0) < 1e-9
        portal = f.y_north_m if north == (view == "exit") else f.y_south_m
        assert abs(portal - p.position_m[1]) == pytest.approx(p.meta["portal_distance_m"])
        assert 10.0 <= p.meta["portal_distance_m"] <= 30.0
        assert abs(((p.pan_deg - p.meta["lane_heading_deg"]) + 180) % 360 - 180) <= 10.0


def test_tunnel_pose_needs_a_tunnel():
    with pytest.raises(ValueError, match="needs a city with a tunnel"):
        sample_camera_poses(generate_city(CityRecipe(n_cars=0)), PoseParams(mode="tunnel"))
