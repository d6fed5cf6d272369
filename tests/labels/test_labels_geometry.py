"""Label pass against pinhole-camera maths: boxes, depth, occlusion, truncation, COCO export.

Oracle: an independent numpy pinhole camera (pixel-centre rays, plane intersections) for tiny
scenes of camera-facing rectangles; closed-form projected areas for the occlusion fraction."""
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.render.variants import import_mitsuba

mi = import_mitsuba("llvm_ad_spectral")

from workbench.render.labels import (  # noqa: E402
    BACKGROUND_DEPTH_M, labels_from_arrays, labels_to_coco, render_labels)

W, H, FOV_DEG = 64, 48, 40.0
F_PX = (W / 2) / np.tan(np.radians(FOV_DEG / 2))      # focal length in pixels
CLASSES = {"car": 1, "pedestrian": 2, "bus": 3}


@pytest.fixture(autouse=True)
def _jit_variant():
    """Other test modules may switch the variant; these scenes are built in the LLVM one."""
    import_mitsuba("llvm_ad_spectral")


def rect(center, half_x, half_z):
    """A camera-facing rectangle (normal −y) centred at `center`, half sizes along x and z (m)."""
    t = (mi.ScalarTransform4f().translate(list(center)).rotate([1, 0, 0], 90)
         .scale([half_x, half_z, 1.0]))
    return {"type": "rectangle", "to_world": t}


def make_scene(shapes: dict, width=W, height=H):
    d = {"type": "scene",
         "sensor": {"type": "perspective", "fov": FOV_DEG, "fov_axis": "x",
                    "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 1, 0],
                                                               up=[0, 0, 1]),
                    "film": {"type": "hdrfilm", "width": width, "height": height}}}
    d.update(shapes)
    return mi.load_dict(d)


def project(x, y, z):
    """Continuous image coordinates (u right, v down; pixel (r, c) spans [c, c+1]×[r, r+1])."""
    return W / 2 + F_PX * x / y, H / 2 - F_PX * z / y


def rect_mask(center, half_x, half_z):
    """Pixels whose centre ray meets the rectangle (independent pinhole oracle)."""
    cx, cy, cz = center
    c = np.arange(W) + 0.5
    r = np.arange(H) + 0.5
    x_at = (c - W / 2) / F_PX * cy              # ray hits plane y = cy at x = d_x/d_y · cy
    z_at = (H / 2 - r) / F_PX * cy
    return (np.abs(z_at - cz)[:, None] <= half_z) & (np.abs(x_at - cx)[None, :] <= half_x)


def expected_box(center, half_x, half_z):
    cx, cy, cz = center
    u0, v0 = project(cx - half_x, cy, cz + half_z)
    u1, v1 = project(cx + half_x, cy, cz - half_z)
    c0, c1 = int(np.ceil(u0 - 0.5)), int(np.floor(u1 - 0.5))
    r0, r1 = int(np.ceil(v0 - 0.5)), int(np.floor(v1 - 0.5))
    c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, W - 1), min(r1, H - 1)
    return c0, r0, c1 - c0 + 1, r1 - r0 + 1


def by_id(labels, inst):
    return next(o for o in labels.objects if o.instance_id == inst)


def test_box_projects_to_pinhole_rectangle_and_depths():
    center, hx, hz = (1.0, 10.0, 0.5), 1.0, 0.6
    scene = make_scene({"a": rect(center, hx, hz)})
    lab = render_labels(scene, {"a": (7, "car")}, W, H, class_ids=CLASSES)
    obj = by_id(lab, 7)
    assert obj.class_name == "car" and obj.class_id == 1
    assert np.all(np.abs(np.subtract(obj.bbox_xywh, expected_box(center, hx, hz))) <= 1)
    mask = lab.instance_id == 7
    oracle = rect_mask(center, hx, hz)
    assert abs(int(mask.sum()) - int(oracle.sum())) <= 2 and (mask ^ oracle).sum() <= 2
    # The box is the one pycocotools computes from the same mask.
    from pycocotools import mask as mask_utils
    rle = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
    assert tuple(mask_utils.toBbox(rle).astype(int)) == obj.bbox_xywh
    # Planar depth is the plane's distance; ray depth is y / cos(angle to the axis).
    np.testing.assert_allclose(lab.planar_depth_m[mask], 10.0, rtol=1e-4)
    rr, cc = np.nonzero(mask)
    ray_len = np.sqrt(((cc + 0.5 - W / 2) / F_PX) ** 2 + ((H / 2 - rr - 0.5) / F_PX) ** 2 + 1)
    np.testing.assert_allclose(lab.depth_m[mask], 10.0 * ray_len, rtol=1e-4)
    assert obj.distance_m == pytest.approx(lab.depth_m[mask].min(), rel=1e-6)
    assert obj.visible_px == obj.amodal_px == mask.sum() and obj.occlusion == 0.0
    assert not obj.truncated and obj.truncation == 0.0
    # Background: class 0, instance 0, far finite depth.
    assert np.all(lab.class_id[~mask] == 0) and np.all(lab.depth_m[~mask] == BACKGROUND_DEPTH_M)
    assert np.all(lab.class_id[mask] == 1)
    assert np.isfinite(lab.depth_m).all() and np.isfinite(lab.planar_depth_m).all()


def test_occlusion_fraction_of_a_box_behind_another():
    back, front, hidden = ((0.0, 12.0, 0.0), 1.5, 1.0), ((-1.2, 6.0, 0.0), 0.6, 0.8), \
        ((-1.2, 20.0, 0.0), 0.3, 0.3)
    scene = make_scene({"back": rect(*back), "front": rect(*front), "hidden": rect(*hidden)})
    table = {"back": (1, "bus"), "front": (2, "pedestrian"), "hidden": (3, "car")}
    lab = render_labels(scene, table, W, H, class_ids=CLASSES)
    m_back, m_front = rect_mask(*back), rect_mask(*front)
    obj = by_id(lab, 1)
    # Pixel-exact oracle (±2 px for centres that fall on an edge).
    assert abs(obj.amodal_px - m_back.sum()) <= 2
    assert abs(obj.visible_px - (m_back & ~m_front).sum()) <= 2
    # Closed form from projected areas: the front rectangle's shadow on the back one.
    fx0, fx1 = (front[0][0] - front[1]) * 12 / 6, (front[0][0] + front[1]) * 12 / 6
    fz = front[2] * 12 / 6
    overlap_x = max(0.0, min(fx1, 1.5) - max(fx0, -1.5))
    overlap_z = 2 * min(fz, 1.0)
    expected = overlap_x * overlap_z / (3.0 * 2.0)
    assert obj.occlusion == pytest.approx(expected, abs=0.04)
    assert obj.bbox_xywh[0] > obj.amodal_bbox_xywh[0]          # its left part is hidden
    # A small box wholly behind the front one: 100 % occluded, listed with its amodal distance.
    hid = by_id(lab, 3)
    assert hid.visible_px == 0 and hid.occlusion == 1.0 and hid.bbox_xywh == (0, 0, 0, 0)
    assert hid.amodal_px > 0 and hid.distance_m == pytest.approx(20.0, rel=0.01)
    assert by_id(lab, 2).occlusion == 0.0


def test_truncation_at_the_border():
    # Crosses the left border: it spans u ≈ −6.7 … 3.9 px.
    cut, inside = ((-3.8, 10.0, 0.0), 0.6, 0.5), ((0.0, 10.0, 0.0), 0.5, 0.5)
    scene = make_scene({"cut": rect(*cut), "in": rect(*inside)})
    lab = render_labels(scene, {"cut": (1, "car"), "in": (2, "car")}, W, H, class_ids=CLASSES,
                        margin_px=16)
    u0, _ = project(cut[0][0] - cut[1], 10.0, 0.0)
    u1, _ = project(cut[0][0] + cut[1], 10.0, 0.0)
    assert u0 < 0 < u1 and u0 > -16                 # crosses the border, ends inside the margin
    obj = by_id(lab, 1)
    assert obj.truncated and obj.bbox_xywh[0] == 0
    assert obj.truncation == pytest.approx(-u0 / (u1 - u0), abs=2 / (u1 - u0))
    assert not by_id(lab, 2).truncated and by_id(lab, 2).truncation == 0.0
    # An object wholly outside the image is not listed.
    scene2 = make_scene({"out": rect((-6.0, 10.0, 0.0), 0.3, 0.3)})
    assert render_labels(scene2, {"out": (1, "car")}, W, H, class_ids=CLASSES).objects == []


def test_instances_get_their_own_ids_and_arrays_round_trip():
    sg = {"type": "shapegroup", "body": {"type": "rectangle"},
          "roof": {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate([0, 0, 0.5])}}
    shapes = {"car_sg": sg}
    table = {}
    for k, x in enumerate((-2.0, 0.0, 2.0)):
        t = mi.ScalarTransform4f().translate([x, 10.0, 0.0]).rotate([1, 0, 0], 90).scale(0.5)
        shapes[f"car_{k}"] = {"type": "instance", "shapegroup": {"type": "ref", "id": "car_sg"},
                              "to_world": t}
        table[f"car_{k}"] = {"instance_id": 10 + k, "class_name": "car"}
    lab = render_labels(make_scene(shapes), table, W, H, class_ids=CLASSES)
    assert [o.instance_id for o in lab.objects] == [10, 11, 12]
    assert len({o.bbox_xywh for o in lab.objects}) == 3
    # The roof is another mesh of the same instance: the object is not occluded by itself.
    assert all(o.occlusion == 0.0 for o in lab.objects)
    back = labels_from_arrays(lab.to_arrays())
    assert back.objects == lab.objects and back.class_names == lab.class_names
    np.testing.assert_array_equal(back.instance_id, lab.instance_id)


def test_layer_cap_is_reported():
    scene = make_scene({"a": rect((0, 5.0, 0), 1, 1), "b": rect((0, 10.0, 0), 1, 1)})
    lab = render_labels(scene, {"a": (1, "car"), "b": (2, "car")}, W, H, class_ids=CLASSES,
                        max_layers=1)
    assert lab.meta["saturated_rays"] > 0
    assert [o.instance_id for o in lab.objects] == [1]


def test_bad_input_is_refused_with_a_clear_message():
    scene = make_scene({"a": rect((0, 10.0, 0), 1, 1)})
    with pytest.raises(ValueError, match="no entry for scene shape"):
        render_labels(scene, {}, W, H, class_ids=CLASSES)
    with pytest.raises(ValueError, match="unknown class 'tank'"):
        render_labels(scene, {"a": (1, "tank")}, W, H, class_ids=CLASSES)
    with pytest.raises(ValueError, match="aspect ratio"):
        render_labels(scene, {"a": (1, "car")}, 64, 64, class_ids=CLASSES)


def test_coco_export_loads_in_pycocotools_and_scores_itself_perfectly(tmp_path):
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    s1 = make_scene({"a": rect((1.0, 10.0, 0.5), 1.0, 0.6), "b": rect((-2.0, 8.0, 0.0), 0.4, 0.9)})
    s2 = make_scene({"c": rect((0.0, 15.0, 0.0), 2.0, 1.0)})
    l1 = render_labels(s1, {"a": (1, "car"), "b": (2, "pedestrian")}, W, H, class_ids=CLASSES)
    l2 = render_labels(s2, {"c": (5, "bus")}, W, H, class_ids=CLASSES)
    coco_dict = labels_to_coco([("f0.png", l1), ("f1.png", l2)], CLASSES)
    path = tmp_path / "coco.json"
    path.write_text(json.dumps(coco_dict))
    coco = COCO(str(path))
    assert sorted(coco.getImgIds()) == [1, 2] and len(coco.getAnnIds()) == 3
    assert {c["name"] for c in coco.loadCats(coco.getCatIds())} == set(CLASSES)
    ann = coco.loadAnns(coco.getAnnIds(imgIds=[1], catIds=[2]))[0]
    np.testing.assert_array_equal(coco.annToMask(ann), (l1.instance_id == 2).astype(np.uint8))
    dets = [dict(image_id=a["image_id"], category_id=a["category_id"], bbox=a["bbox"], score=1.0)
            for a in coco.dataset["annotations"]]
    ev = COCOeval(coco, coco.loadRes(dets), "bbox")
    ev.params.areaRng = [[0, 1e10]] * 4
    ev.evaluate()
    ev.accumulate()
    ev.summarize()
    assert ev.stats[1] == pytest.approx(1.0)        # AP@0.5 of the ground truth on itself


def test_scalar_variant_is_refused():
    import_mitsuba("scalar_spectral")
    try:
        scene = make_scene({"a": rect((0, 10.0, 0), 1, 1)})
        with pytest.raises(ValueError, match="JIT Mitsuba variant"):
            render_labels(scene, {"a": (1, "car")}, W, H, class_ids=CLASSES)
    finally:
        import_mitsuba("llvm_ad_spectral")


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_vectorised_boxes_equal_pycocotools_boxes(seed):
    from pycocotools import mask as mask_utils

    from workbench.render.labels import _boxes
    rng = np.random.default_rng(seed)
    h, w, n = rng.integers(1, 20), rng.integers(1, 20), rng.integers(1, 6)
    inst = rng.integers(0, n + 1, size=(h, w)) * (rng.random((h, w)) < rng.random())
    rr, cc = np.nonzero(inst)
    boxes = _boxes(inst[rr, cc], cc, rr, n + 1)
    for i in range(1, n + 1):
        rle = mask_utils.encode(np.asfortranarray((inst == i).astype(np.uint8)))
        assert tuple(boxes[i]) == tuple(mask_utils.toBbox(rle).astype(int))


def test_one_layer_is_a_single_cast_with_the_loops_results():
    """max_layers=1 without helper shapes casts each ray once instead of tracing the peeling loop:
    every map, object and count equals the loop's; a scene with a helper shape (which rays pass
    through) still takes the loop, and sees what is behind the helper."""
    import workbench.render.labels as labels_module
    shapes = {"a": rect((0, 5.0, 0), 1, 1), "b": rect((0.8, 10.0, 0.3), 1.5, 1), "c": rect((-2.5, 8.0, 0), 0.4, 2)}
    table = {"a": (1, "car"), "b": (2, "bus"), "c": (3, "pedestrian")}
    scene = make_scene(shapes)
    single = render_labels(scene, table, W, H, class_ids=CLASSES, max_layers=1)
    real_peel = labels_module._peel
    try:
        labels_module._peel = lambda *args, helpers: real_peel(*args, helpers=True)   # force the loop
        looped = render_labels(scene, table, W, H, class_ids=CLASSES, max_layers=1)
    finally:
        labels_module._peel = real_peel
    for name in ("depth_m", "planar_depth_m", "class_id", "instance_id"):
        np.testing.assert_array_equal(getattr(single, name), getattr(looped, name))
    assert single.objects == looped.objects and single.meta == looped.meta
    assert single.meta["saturated_rays"] > 0
    fogged = make_scene({**shapes, "fog_box": rect((0, 3.0, 0), 3, 3)})
    through = render_labels(fogged, {**table, "fog_box": None}, W, H, class_ids=CLASSES, max_layers=1)
    np.testing.assert_array_equal(through.instance_id, single.instance_id)
