"""Camera poses as in the paper: a plane height_m above the road, in a lane, panned about the
lane direction (−10…10°), tilted and rolled (−5…5°); aimed at a target object from ~10 m
(isetauto's camera generator); before a tunnel portal (exit or entrance view); or one pose set
by hand.

Angles follow `CameraPose`: pan = yaw about +Z from +X, tilt = pitch up, roll = right-handed
rotation about the viewing direction (positive roll leans the camera's up vector to its right).
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError
from workbench.scene.city import geometry as g
from workbench.scene.city.layout import LANE_END_CLEARANCE_M, CityLayout
from workbench.scene.city.recipe import PoseParams
from workbench.scene.city.tunnel import TunnelFrame
from workbench.scene.city.types import CameraPose, City

EGO_LENGTH_M, EGO_WIDTH_M = 4.6, 1.9   # the camera rides in a car this size …
EGO_CAMERA_AHEAD_M = 1.0               # … mounted this far ahead of the car's centre
EGO_CLEARANCE_M = 1.0
MAX_TRIES = 2000
VEHICLES = ("car", "bus", "truck")


def _layout(city: City) -> CityLayout:
    layout = city.meta.get("layout")
    if not isinstance(layout, CityLayout):
        raise InvalidValueError("city.meta['layout'] is missing: camera poses need a city made by generate_city")
    return layout


def pose_basis(pose: CameraPose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit (forward, right, up) vectors of a pose in world coordinates (Z up)."""
    f = pose.forward()
    right = np.cross(f, [0.0, 0.0, 1.0])
    n = np.linalg.norm(right)
    right = np.array([np.sin(np.radians(pose.pan_deg)), -np.cos(np.radians(pose.pan_deg)), 0.0]) \
        if n < 1e-9 else right / n
    up = np.cross(right, f)
    r = np.radians(pose.roll_deg)
    right_r = right * np.cos(r) - up * np.sin(r)
    up_r = up * np.cos(r) + right * np.sin(r)
    return f, right_r, up_r


def _wrap(angle_deg: float) -> float:
    return float((angle_deg + 180.0) % 360.0 - 180.0)


def _ego_clear(xy: np.ndarray, heading_deg: float, vehicles: list[np.ndarray]) -> bool:
    h = np.radians(heading_deg)
    ego = g.oriented_rect(xy - EGO_CAMERA_AHEAD_M * np.array([np.cos(h), np.sin(h)]),
                          EGO_LENGTH_M, EGO_WIDTH_M, heading_deg)
    return not any(g.rects_overlap(ego, v, EGO_CLEARANCE_M) for v in vehicles)


def building_at(city: City, x: float, y: float):
    """The building whose ground footprint holds the point (x, y) m, or None."""
    from matplotlib.path import Path
    for obj in city.objects:
        if obj.class_name == "building" and obj.footprint_xy is not None and len(obj.footprint_xy) >= 3 \
                and Path(np.asarray(obj.footprint_xy, dtype=float)).contains_point((x, y)):
            return obj
    return None


def check_camera_spot(city: City, x: float, y: float) -> None:
    """InvalidValueError when a camera at (x, y) m would stand outside the city or inside a
    building (its frame would be black), saying where the free space is."""
    x0, y0, x1, y1 = city.extent_m
    if not (x0 <= x <= x1 and y0 <= y <= y1):
        raise InvalidValueError(f"manual_position_xy_m=({x}, {y}) lies outside the city extent "
                                f"x {x0:.1f}…{x1:.1f}, y {y0:.1f}…{y1:.1f} m")
    inside = building_at(city, x, y)
    if inside is not None:
        fx, fy = np.asarray(inside.footprint_xy, dtype=float).T
        raise InvalidValueError(f"manual_position_xy_m=({x:.2f}, {y:.2f}) is inside a building (footprint x "
                                f"{fx.min():.1f}…{fx.max():.1f}, y {fy.min():.1f}…{fy.max():.1f} m): the camera "
                                "would see only its walls; put it on a street or a sidewalk")


def _manual(city: City, pp: PoseParams, n: int) -> list[CameraPose]:
    x, y = pp.manual_position_xy_m
    check_camera_spot(city, x, y)
    return [CameraPose(np.array([x, y, pp.height_m]), _wrap(pp.manual_pan_deg), pp.manual_tilt_deg,
                       pp.manual_roll_deg, meta={"mode": "manual"}) for _ in range(n)]


def _random_spot(lanes, lengths, pp: PoseParams, rng, vehicles):
    """A lane spot clear of vehicles: (lane, xy, pan_deg, meta) or None."""
    lane = lanes[int(rng.choice(len(lanes), p=lengths / lengths.sum()))]
    s = rng.uniform(LANE_END_CLEARANCE_M, lane.length_m - LANE_END_CLEARANCE_M)
    xy = lane.point(s, rng.uniform(-1.0, 1.0) * pp.lateral_jitter_m)
    if not _ego_clear(xy, lane.heading_deg, vehicles):
        return None
    pan_offset = float(rng.uniform(*pp.pan_range_deg))
    return lane, xy, lane.heading_deg + pan_offset, {"pan_offset_deg": pan_offset}


def _target_spot(lanes, targets, pp: PoseParams, rng, vehicles):
    """A lane spot at the wanted distance behind a random target (a class drawn uniformly, then
    one of its objects), the target ahead within max_target_bearing_deg: or None."""
    classes = sorted({o.class_name for o in targets})
    cls = classes[int(rng.integers(len(classes)))]          # classes equally likely
    of_class = [o for o in targets if o.class_name == cls]
    t = of_class[int(rng.integers(len(of_class)))]
    p = np.asarray(t.meta["position_m"][:2], dtype=np.float64)
    d = rng.uniform(*pp.target_distance_range_m)
    jitter = rng.uniform(-1.0, 1.0) * pp.lateral_jitter_m
    options = []
    for lane in lanes:
        s_t, off = lane.lane_coords(p)
        rel = off[0] - jitter
        if abs(rel) >= d:
            continue
        ahead = np.sqrt(d * d - rel * rel)
        s = s_t[0] - ahead
        bearing = np.degrees(np.arctan2(rel, ahead))
        if LANE_END_CLEARANCE_M <= s <= lane.length_m - LANE_END_CLEARANCE_M and \
                abs(bearing) <= pp.max_target_bearing_deg:
            options.append((lane, s))
    if not options:
        return None
    lane, s = options[int(rng.integers(len(options)))]
    xy = lane.point(s, jitter)
    if not _ego_clear(xy, lane.heading_deg, vehicles):
        return None
    bearing = float(np.degrees(np.arctan2(p[1] - xy[1], p[0] - xy[0])))
    pan_offset = float(rng.uniform(*pp.pan_range_deg))
    return lane, xy, bearing + pan_offset, {
        "pan_offset_deg": pan_offset, "target_instance_id": t.instance_id,
        "target_class": t.class_name, "target_distance_m": float(np.hypot(*(p - xy)))}


def _tunnel_spot(layout: CityLayout, frame: TunnelFrame, pp: PoseParams, rng, vehicles):
    """A spot in a lane of the tunnel's street, the wanted distance before the portal ahead
    (inside the tunnel for the exit view, outside on the road for the entrance view): or None."""
    lanes = [ln for ln in layout.lanes if ln.heading_deg in (90.0, 270.0) and abs(
        (ln.segment_rect[0] + ln.segment_rect[2]) / 2 - frame.x_m) < 1e-6]
    lane = lanes[int(rng.integers(len(lanes)))]
    north = lane.heading_deg == 90.0
    d = rng.uniform(*pp.tunnel_distance_range_m)
    exit_view = pp.tunnel_view == "exit"
    portal = frame.y_north_m if north == exit_view else frame.y_south_m
    y = portal - d if north else portal + d
    x = lane.start_xy[0] + rng.uniform(-1.0, 1.0) * pp.lateral_jitter_m
    xy = np.array([x, y])
    if bool(frame.inside(xy)[0]) != exit_view or not layout.on_road(xy)[0] or \
            not _ego_clear(xy, lane.heading_deg, vehicles):
        return None
    pan_offset = float(rng.uniform(*pp.pan_range_deg))
    return lane, xy, lane.heading_deg + pan_offset, {
        "pan_offset_deg": pan_offset, "tunnel_view": pp.tunnel_view, "portal_distance_m": float(d)}


def _tunnel_frame(city: City) -> TunnelFrame:
    frames = [o.meta["frame"] for o in city.objects if o.class_name == "tunnel"]
    if not frames:
        raise InvalidValueError("mode='tunnel' needs a city with a tunnel (set CityRecipe.tunnel)")
    return frames[0]


def sample_camera_poses(city: City, pose_params: PoseParams, n: int = 1,
                        seed: int | None = None) -> list[CameraPose]:
    """n camera poses (random and target modes: seeded by `seed`, default pose_params.seed).

    Random and target poses stand in a lane, at least LANE_END_CLEARANCE_M from intersections,
    with an ego car of 4.6 m × 1.9 m around the camera that clears every placed vehicle by 1 m.
    meta records the mode, lane, lane heading and pan offset (and the target in 'target' mode)."""
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise InvalidValueError(f"n (number of poses) must be an integer >= 1, got {n!r}")
    pp = pose_params
    if pp.mode == "manual":
        return _manual(city, pp, n)
    layout = _layout(city)
    rng = np.random.default_rng(pp.seed if seed is None else seed)
    lanes = [ln for ln in layout.lanes if ln.length_m > 2 * LANE_END_CLEARANCE_M]
    if not lanes:
        raise InvalidValueError("no street segment is long enough to hold a camera")
    lengths = np.array([ln.length_m - 2 * LANE_END_CLEARANCE_M for ln in lanes])
    vehicles = [o.footprint_xy for o in city.objects if o.class_name in VEHICLES]
    targets = [o for o in city.objects if o.class_name in pp.target_classes and "position_m" in o.meta]
    if pp.mode == "target" and not targets:
        raise InvalidValueError(f"mode='target' but the city has no objects of target_classes="
                         f"{pp.target_classes}")
    poses = []
    frame = _tunnel_frame(city) if pp.mode == "tunnel" else None
    for k in range(n):
        for _ in range(MAX_TRIES):
            if pp.mode == "tunnel":
                spot = _tunnel_spot(layout, frame, pp, rng, vehicles)
            elif pp.mode == "target":
                spot = _target_spot(lanes, targets, pp, rng, vehicles)
            else:
                spot = _random_spot(lanes, lengths, pp, rng, vehicles)
            if spot is not None:
                break
        else:
            raise InvalidValueError(f"could not find a free spot in a lane for camera pose {k + 1} of {n} "
                             f"after {MAX_TRIES} tries (mode '{pp.mode}'); the lanes are full of "
                             "vehicles (lower n_cars) or no target is reachable (widen "
                             "target_distance_range_m or max_target_bearing_deg) or, for tunnel poses, "
                             "tunnel_distance_range_m does not fit the tunnel or the road before it")
        lane, xy, pan, extra = spot
        poses.append(CameraPose(
            np.array([xy[0], xy[1], pp.height_m]), _wrap(pan),
            float(rng.uniform(*pp.tilt_range_deg)), float(rng.uniform(*pp.roll_range_deg)),
            meta={"mode": pp.mode, "lane_index": lane.index, "lane_heading_deg": lane.heading_deg,
                  **extra}))
    return poses
