"""The distant buildings (CityRecipe.skyline_distance_m) are labelled exactly where they are: a level
camera at the city's north edge looking out over the field sees, on each pixel, whatever an
independent numpy ray caster finds first along the pixel's centre ray — a skyline building's box
(slab test on the parts in its meta) or else the field (ray–plane z = 0) — and, on the building
pixels, at that distance (within 0.2 %; window panes stand 2 cm proud of the walls, so a ray may
meet one up to that far outside the box, which at grazing incidence is many centimetres earlier)."""
import numpy as np

from workbench.render.film import box_bands
from workbench.render.labels import render_labels
from workbench.render.params import DaylightParams
from workbench.render.scene_builder import build_scene
from workbench.scene.city import CameraPose, CityRecipe, generate_city
from workbench.scene.city.buildings import WINDOW_PROUD_M

from render_helpers import north_rays

W, H, HFOV_DEG, CAM_Z = 120, 40, 60.0, 1.5


def _slab_hits(origin, d, lo, hi):
    """Entry distance of each ray into the box lo…hi (inf where it misses)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - origin) / d, (hi - origin) / d
    near = np.nanmax(np.minimum(t0, t1), axis=-1)
    far = np.nanmin(np.maximum(t0, t1), axis=-1)
    return np.where((far >= near) & (near > 0), near, np.inf)


def test_skyline_pixels_are_labelled_at_their_depth(mi):
    recipe = CityRecipe(seed=2, blocks_x=1, blocks_y=1, n_cars=0, n_pedestrians=0, n_buses=0, n_trucks=0,
                        n_trees=0, n_lamps=0, n_benches=0, n_mailboxes=0, horizon_field_m=600.0,
                        skyline_distance_m=150.0)
    city = generate_city(recipe)
    x = 0.5 * (city.extent_m[0] + city.extent_m[2])
    edge_y = city.extent_m[3] - recipe.horizon_field_m
    pose = CameraPose(np.array([x, edge_y - 5.0, CAM_Z]), pan_deg=90.0, tilt_deg=0.0, roll_deg=0.0)
    scene, ids = build_scene(city, pose, HFOV_DEG, W, H, box_bands(400.0, 700.0, 2), DaylightParams(sky_model="perez"))
    labels = render_labels(scene, ids, W, H)

    d = north_rays(W, H, HFOV_DEG)
    best_t, best_t_panes = np.full((H, W), np.inf), np.full((H, W), np.inf)
    best_id = np.zeros((H, W), dtype=np.int64)
    proud = np.array([WINDOW_PROUD_M, WINDOW_PROUD_M, 0.0]) + 1e-3
    for o in city.objects:
        if o.meta.get("part") != "skyline":
            continue
        for lo, hi in o.meta["parts_m"]:
            t = _slab_hits(pose.position_m, d, np.array(lo), np.array(hi))
            closer = t < best_t
            best_t[closer], best_id[closer] = t[closer], o.instance_id
            best_t_panes = np.minimum(best_t_panes, _slab_hits(pose.position_m, d, np.array(lo) - proud,
                                                               np.array(hi) + proud))
    with np.errstate(divide="ignore"):
        t_ground = np.where(d[..., 2] < 0, -CAM_Z / d[..., 2], np.inf)
    building = best_t < t_ground
    assert 0.05 < building.mean() < 0.6                      # the view holds skyline buildings and field
    agree = labels.instance_id == np.where(building, best_id, labels.instance_id)
    assert (~agree[building]).mean() < 0.02                  # silhouette pixels may differ
    ok = building & agree
    depth = labels.depth_m[ok]
    assert (depth <= best_t[ok] * (1 + 2e-3) + 0.05).all()
    assert (depth >= best_t_panes[ok] * (1 - 2e-3) - 0.05).all()
    assert np.median(np.abs(depth - best_t[ok]) / best_t[ok]) < 1e-4
    ground_id = next(o.instance_id for o in city.objects if o.meta.get("part") == "margin")
    assert (labels.instance_id[~building & np.isfinite(t_ground)] == ground_id).mean() > 0.98
