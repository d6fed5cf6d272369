"""Camera poses: in a lane at 1.5 m, pan/tilt/roll within the paper's ranges, seeded, clear of
vehicles; manual poses; the forward/right/up basis."""
import numpy as np
import pytest
from pydantic import ValidationError

from workbench.scene.city import (CameraPose, CityRecipe, PoseParams, generate_city, pose_basis,
                                  sample_camera_poses)
from workbench.scene.city import geometry as g
from workbench.scene.city.poses import EGO_CAMERA_AHEAD_M, EGO_LENGTH_M, EGO_WIDTH_M


@pytest.fixture(scope="module")
def city():
    return generate_city(CityRecipe(seed=4, n_cars=40))


def test_random_poses_in_range_and_on_road(city):
    pp = PoseParams()
    poses = sample_camera_poses(city, pp, 60, seed=7)
    layout = city.meta["layout"]
    vehicles = [o.footprint_xy for o in city.objects if o.class_name in ("car", "bus", "truck")]
    for p in poses:
        assert p.position_m[2] == 1.5
        assert layout.on_road(p.position_m[None, :2]).all()
        lane = layout.lanes[p.meta["lane_index"]]
        s, off = lane.lane_coords(p.position_m[None, :2])
        assert abs(off[0]) <= pp.lateral_jitter_m + 1e-9 and 0 < s[0] < lane.length_m
        dpan = (p.pan_deg - lane.heading_deg + 180) % 360 - 180
        assert -10 <= dpan <= 10 and dpan == pytest.approx(p.meta["pan_offset_deg"])
        assert -5 <= p.tilt_deg <= 5 and -5 <= p.roll_deg <= 5
        h = np.radians(lane.heading_deg)
        ego = g.oriented_rect(p.position_m[:2] - EGO_CAMERA_AHEAD_M * np.array([np.cos(h), np.sin(h)]),
                              EGO_LENGTH_M, EGO_WIDTH_M, lane.heading_deg)
        assert not any(g.rects_overlap(ego, v) for v in vehicles)
    pans = np.array([p.meta["pan_offset_deg"] for p in poses])
    assert pans.min() < -5 and pans.max() > 5                      # spans the range
    assert len({p.meta["lane_heading_deg"] for p in poses}) == 4     # all four directions


def test_seeded(city):
    a = sample_camera_poses(city, PoseParams(), 5, seed=3)
    b = sample_camera_poses(city, PoseParams(seed=3), 5)
    c = sample_camera_poses(city, PoseParams(), 5, seed=4)
    key = lambda ps: [(tuple(p.position_m), p.pan_deg, p.tilt_deg, p.roll_deg) for p in ps]
    assert key(a) == key(b) and key(a) != key(c)


def test_custom_ranges_and_height(city):
    pp = PoseParams(height_m=2.5, pan_range_deg=(0, 0), tilt_range_deg=(-1, -1), roll_range_deg=(2, 2))
    for p in sample_camera_poses(city, pp, 10, seed=1):
        assert p.position_m[2] == 2.5 and p.pan_deg % 90 == pytest.approx(0.0)
        assert p.tilt_deg == -1 and p.roll_deg == 2


def test_manual_pose(city):
    pp = PoseParams(mode="manual", manual_position_xy_m=(10.0, 1.75), manual_pan_deg=370 - 360,
                    manual_tilt_deg=-3.0, manual_roll_deg=1.0)
    (p,) = sample_camera_poses(city, pp)
    assert np.allclose(p.position_m, [10.0, 1.75, 1.5]) and (p.pan_deg, p.tilt_deg, p.roll_deg) == (10, -3, 1)
    with pytest.raises(ValueError, match="outside the city extent"):
        sample_camera_poses(city, PoseParams(mode="manual", manual_position_xy_m=(1e4, 0)))


def test_a_manual_camera_inside_a_building_is_refused_saying_where(city):
    """A camera dropped inside a building rendered a black frame and nothing said why."""
    from workbench.scene.city.poses import building_at
    building = next(o for o in city.objects if o.class_name == "building" and o.footprint_xy is not None)
    x, y = np.asarray(building.footprint_xy, dtype=float).mean(axis=0)
    assert building_at(city, x, y) is building
    with pytest.raises(ValueError, match="inside a building .*put it on a street"):
        sample_camera_poses(city, PoseParams(mode="manual", manual_position_xy_m=(float(x), float(y))))
    layout = city.meta["layout"]
    on_road = next(p for p in sample_camera_poses(city, PoseParams(), 20, seed=3))
    assert layout.on_road(on_road.position_m[None, :2]).all()
    assert building_at(city, *on_road.position_m[:2]) is None      # a street spot is free


@pytest.mark.parametrize("kwargs,match", [
    ({"mode": "manual"}, "manual_position_xy_m"),
    ({"pan_range_deg": (10, -10)}, "pan_range_deg"),
    ({"tilt_range_deg": (-100, 0)}, "tilt_range_deg"),
    ({"height_m": -1.5}, "height_m"),
    ({"mode": "orbit"}, "mode"),
])
def test_bad_pose_params(kwargs, match):
    with pytest.raises(ValidationError, match=match):
        PoseParams(**kwargs)


def test_bad_n_and_missing_layout(city):
    with pytest.raises(ValueError, match="n \\(number of poses\\)"):
        sample_camera_poses(city, PoseParams(), 0)
    from workbench.scene.city import City
    bare = City([], {}, 0, (0, 0, 1, 1))
    with pytest.raises(ValueError, match="meta\\['layout'\\]"):
        sample_camera_poses(bare, PoseParams(), 1)


def test_pose_basis():
    p = CameraPose(np.zeros(3), 30.0, 4.0, 0.0)
    f, r, u = pose_basis(p)
    assert np.allclose(np.stack([f, r, u]) @ np.stack([f, r, u]).T, np.eye(3))
    assert np.allclose(np.cross(r, u), -f)        # camera looks along −(right × up)
    assert u[2] > 0 and abs(r[2]) < 1e-12          # no roll: horizon level
    f2, r2, u2 = pose_basis(CameraPose(np.zeros(3), 30.0, 4.0, 90.0))
    assert np.allclose(f2, f) and np.allclose(u2, r) and np.allclose(r2, -u)


def test_target_mode(city):
    pp = PoseParams(mode="target", target_classes=("car", "pedestrian"))
    layout = city.meta["layout"]
    by_id = {o.instance_id: o for o in city.objects}
    poses = sample_camera_poses(city, pp, 25, seed=9)
    for p in poses:
        t = by_id[p.meta["target_instance_id"]]
        assert t.class_name in ("car", "pedestrian")
        d = np.hypot(*(t.meta["position_m"][:2] - p.position_m[:2]))
        assert 8.0 - 1e-6 <= d <= 12.0 + 1e-6 and d == pytest.approx(p.meta["target_distance_m"])
        bearing = np.degrees(np.arctan2(*(t.meta["position_m"][:2] - p.position_m[:2])[::-1]))
        assert abs((p.pan_deg - bearing + 180) % 360 - 180) <= 10 + 1e-9
        assert abs((bearing - p.meta["lane_heading_deg"] + 180) % 360 - 180) <= 45 + 1e-9
        assert layout.on_road(p.position_m[None, :2]).all() and p.position_m[2] == 1.5
    assert len({p.meta["target_instance_id"] for p in poses}) > 5


def test_target_mode_errors(city):
    with pytest.raises(ValidationError, match="target_classes"):
        PoseParams(mode="target", target_classes=("unicorn",))
    with pytest.raises(ValidationError, match="target_distance_range_m"):
        PoseParams(mode="target", target_distance_range_m=(5.0, 1.0))
    empty = generate_city(CityRecipe(seed=1, n_buses=0))
    with pytest.raises(ValueError, match="no objects of target_classes"):
        sample_camera_poses(empty, PoseParams(mode="target", target_classes=("bus",)), 1)
