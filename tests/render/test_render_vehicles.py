"""Detailed vehicles in the renderer: every new mesh belongs to its object, so the label pass
still gives exact boxes (an independent pinhole projection of the vertices, ±1 px) with
see-through glass and clear-coat paint on; the frame renders finite."""
import numpy as np
import pytest

from workbench.render.demo_scene import plane_mesh
from workbench.render.film import box_bands
from workbench.render.labels import render_labels
from workbench.render.params import DaylightParams, WorldParams
from workbench.render.scene_builder import build_scene, camera_to_world
from workbench.scene.city import build_asset, city_materials
from workbench.scene.city import geometry as g
from workbench.scene.city.types import CameraPose, City, CityObject, Mesh

W, H, FOV_DEG = 64, 48, 50.0


def _placed(cls, variant, inst, heading_deg, xy, paint):
    meshes = [Mesh(g.place(m.vertices, heading_deg, np.array([*xy, 0.0])), m.faces, m.material)
              for m in build_asset(cls, variant, "detailed").meshes(paint)]
    return CityObject(cls, inst, meshes)


def _expected_box(obj, pose):
    origin, target, up = camera_to_world(pose)
    fwd = target - origin
    right = np.cross(fwd, up)
    f_px = (W / 2) / np.tan(np.radians(FOV_DEG / 2))
    d = np.concatenate([m.vertices for m in obj.meshes]) - origin
    u = W / 2 + f_px * (d @ right) / (d @ fwd)
    v = H / 2 - f_px * (d @ up) / (d @ fwd)
    c0, c1 = int(np.ceil(u.min() - 0.5)), int(np.floor(u.max() - 0.5))
    r0, r1 = int(np.ceil(v.min() - 0.5)), int(np.floor(v.max() - 0.5))
    c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, W - 1), min(r1, H - 1)     # truncated at the border
    return c0, r0, c1 - c0 + 1, r1 - r0 + 1


@pytest.mark.parametrize("world", [WorldParams(), WorldParams(glass="dielectric", paint="clearcoat")])
def test_detailed_vehicle_boxes_are_exact(mi, world):
    objs = [CityObject("ground", 1, [plane_mesh(300.0, 0.0, "asphalt")]),
            _placed("car", "suv_mid", 2, 30.0, (11.0, -1.5), "paint_red"),
            _placed("truck", "box_truck_7m", 3, 180.0, (26.0, 5.0), "paint_blue"),
            _placed("car", "pickup", 4, 200.0, (9.0, 4.0), "paint_white")]
    city = City(objs, city_materials(), seed=0, extent_m=(-50, -50, 50, 50))
    pose = CameraPose(np.array([0.0, 0.0, 1.4]), pan_deg=5.0, tilt_deg=-2.0, roll_deg=0.0)
    film = box_bands(400.0, 1000.0, 2)
    scene, ids = build_scene(city, pose, FOV_DEG, W, H, film, DaylightParams(), max_depth=3, world=world)
    labels = render_labels(scene, ids, W, H)
    got = {o.instance_id: o for o in labels.objects}
    for obj in objs[1:]:
        want = _expected_box(obj, pose)
        assert np.all(np.abs(np.subtract(got[obj.instance_id].amodal_bbox_xywh, want)) <= 1), obj.instance_id
    assert got[2].occlusion == 0.0 and got[2].bbox_xywh == got[2].amodal_bbox_xywh
    img = np.array(mi.render(scene, spp=2, seed=1))
    assert np.isfinite(img).all() and img.max() > 0
