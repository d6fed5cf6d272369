"""Labels of detailed (jointed) pedestrians: every segment's mesh carries the person's instance id,
and each person's amodal box is the pinhole projection of its vertices within ±1 px.

Oracle: an independent numpy pinhole (the pose's forward/right/up basis, focal length from the
horizontal field of view) applied to the world vertices of the city's meshes."""
import numpy as np

from workbench.render.variants import import_mitsuba
from workbench.scene.city import CityRecipe, PoseParams, generate_city, pose_basis, sample_camera_poses

W, H, FOV_DEG = 128, 96, 40.0
F_PX = (W / 2) / np.tan(np.radians(FOV_DEG / 2))


def _projected_box(vertices, pose):
    """(x, y, w, h) of the pixels whose centres fall inside the projected vertex extent, or None
    when the object is behind the camera or crosses the image border."""
    fwd, right, up = pose_basis(pose)
    d = vertices - np.asarray(pose.position_m)
    z = d @ fwd
    if z.min() <= 0.1:
        return None
    u = W / 2 + F_PX * (d @ right) / z
    v = H / 2 - F_PX * (d @ up) / z
    c0, c1 = int(np.ceil(u.min() - 0.5)), int(np.floor(u.max() - 0.5))
    r0, r1 = int(np.ceil(v.min() - 0.5)), int(np.floor(v.max() - 0.5))
    if c0 < 1 or r0 < 1 or c1 > W - 2 or r1 > H - 2:
        return None
    return c0, r0, c1 - c0 + 1, r1 - r0 + 1


def test_detailed_people_boxes_project_within_one_pixel():
    import_mitsuba("llvm_ad_spectral")
    from workbench.render.film import box_bands
    from workbench.render.labels import render_labels
    from workbench.render.params import DaylightParams
    from workbench.render.scene_builder import build_scene

    city = generate_city(CityRecipe(blocks_x=1, blocks_y=1, asset_detail="detailed", n_pedestrians=40,
                                    n_cars=4, n_trees=4, n_lamps=4, n_benches=2, n_mailboxes=0))
    people = {o.instance_id: o for o in city.objects if o.class_name == "pedestrian"}
    poses = sample_camera_poses(city, PoseParams(mode="target", target_classes=("pedestrian",),
                                                 target_distance_range_m=(5.0, 9.0), roll_range_deg=(0, 0)),
                                n=4, seed=3)
    checked = 0
    for pose in poses:
        scene, table = build_scene(city, pose, FOV_DEG, W, H, box_bands(400.0, 700.0, 1),
                                   DaylightParams(), max_depth=1)
        assert all(table[f"pedestrian_{i}_{k}"].instance_id == i
                   for i, o in people.items() for k in range(len(o.meshes)))
        labels = render_labels(scene, table, W, H)
        for obj in labels.objects:
            if obj.class_name != "pedestrian":
                continue
            verts = np.concatenate([m.vertices for m in people[obj.instance_id].meshes])
            box = _projected_box(verts, pose)
            if box is None or box[2] < 4:
                continue
            assert np.abs(np.subtract(obj.amodal_bbox_xywh, box)).max() <= 1, (obj, box)
            checked += 1
    assert checked >= 3
