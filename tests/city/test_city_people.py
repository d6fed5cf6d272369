"""Detailed pedestrians: every segment a closed outward solid, standing on the ground at the
stature of its spec, joints that hold together, poses that differ, a varied crowd, and a detailed
city that generates deterministically."""
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from workbench.scene.city import CityRecipe, build_asset, generate_city, reflectance, variant_names
from workbench.scene.city.materials import BOTTOMS, HAIRS, MATERIAL_WAVELENGTHS_NM, SHOES, TOPS
from workbench.scene.city.people import CYCLISTS, PEDESTRIAN_SPECS, body_parts, skeleton

SPECS = {s.name: s for s in PEDESTRIAN_SPECS}
NAMES = variant_names("pedestrian", "detailed")
WL = MATERIAL_WAVELENGTHS_NM

# (parent segment, child segment, the joint they share)
JOINTS = [("pelvis", "torso", "waist"), ("torso", "neck", "neck"), ("neck", "head", "chin")] + [
    pair for s in "rl" for pair in (
        ("pelvis", f"thigh_{s}", f"hip_{s}"), (f"thigh_{s}", f"shin_{s}", f"knee_{s}"),
        (f"shin_{s}", f"foot_{s}", f"ankle_{s}"), ("torso", f"upper_arm_{s}", f"shoulder_{s}"),
        (f"upper_arm_{s}", f"forearm_{s}", f"elbow_{s}"), (f"forearm_{s}", f"hand_{s}", f"wrist_{s}"))]


def _closed(f):
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    fwd = {tuple(e) for e in edges.tolist()}
    return len(fwd) == len(edges) and all((b, a) in fwd for a, b in fwd)


def _volume(v, f):
    tri = v[f]
    return np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6


def _outside_m(part, point):
    """How far `point` lies outside the convex solid `part` (≤ 0 inside), m."""
    eq = ConvexHull(part[0]).equations
    return float((eq[:, :3] @ point + eq[:, 3]).max())


def test_enough_variants_heights_builds_and_clothes():
    assert len(NAMES) >= 48 and len(set(NAMES)) == len(NAMES)
    assert NAMES == variant_names("pedestrian", "detailed")             # deterministic order
    specs = list(SPECS.values())
    heights = [s.stature_m for s in specs]
    assert min(heights) <= 1.1 and max(heights) >= 1.85 and max(heights) <= 1.95
    assert sum(h < 1.45 for h in heights) >= 4                           # children
    assert {s.build for s in specs} == {"slim", "average", "broad"}
    assert {s.pose for s in specs} >= {"standing", "walk_contact", "walk_midstance", "cycling_power",
                                       "cycling_top"}
    assert 0.08 <= len(CYCLISTS) / len(specs) <= 0.2 and any(SPECS[n].stature_m < 1.45 for n in CYCLISTS)
    outfits = {(s.top, s.bottom, s.shoes, s.skin, s.hair, s.long_sleeves, s.shorts) for s in specs}
    assert len(outfits) == len(specs)                                    # no two dressed alike
    assert {s.top for s in specs} == set(TOPS) and {s.bottom for s in specs} == set(BOTTOMS)
    assert {s.shoes for s in specs} == set(SHOES) and {s.hair for s in specs} == set(HAIRS)


@pytest.mark.parametrize("name", NAMES)
def test_parts_are_closed_outward_solids_on_the_ground(name):
    spec = SPECS[name]
    parts = body_parts(spec)
    for seg, (_, (v, f)) in parts.items():
        assert _closed(f), seg
        assert _volume(v, f) > 0, seg
        tri = v[f]
        assert (np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) > 1e-8).all()
    a = build_asset("pedestrian", name, "detailed")
    allv = np.concatenate([v for v, _ in a.parts.values()])
    assert allv[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    assert np.allclose((allv[:, :2].min(0) + allv[:, :2].max(0)) / 2, 0.0, atol=1e-9)
    assert all(_closed(f) for _, f in a.parts.values())
    n_tri = sum(len(f) for _, f in a.parts.values())
    assert 300 <= n_tri <= 2100
    if name in CYCLISTS:    # seated on the saddle, above the hip height of standing
        assert spec.stature_m - 0.1 <= a.height_m <= spec.stature_m + 0.06
    elif spec.pose == "standing":
        assert a.height_m == pytest.approx(spec.stature_m, abs=0.02)
    else:   # the pelvis dips in double support (centre-of-mass excursion ~5 cm in gait)
        assert spec.stature_m - 0.06 <= a.height_m <= spec.stature_m + 1e-9


@pytest.mark.parametrize("name", NAMES)
def test_joints_hold_together(name):
    parts, j = body_parts(SPECS[name]), skeleton(SPECS[name])
    for parent, child, joint in JOINTS:
        assert _outside_m(parts[parent][1], j[joint]) < 0.003, (parent, joint)
        assert _outside_m(parts[child][1], j[joint]) < 0.003, (child, joint)


def _feet(name):
    parts = body_parts(SPECS[name])
    return [parts[f"foot_{s}"][1][0] for s in "rl"]


def test_poses_differ_and_feet_touch_the_ground():
    for name in (n for n in NAMES if n not in CYCLISTS):
        pose = SPECS[name].pose
        fr, fl = _feet(name)
        stride = abs(fr[:, 0].mean() - fl[:, 0].mean())
        lows = sorted([fr[:, 2].min(), fl[:, 2].min()])
        if pose == "standing":
            assert stride < 0.01 and lows[1] < 1e-6
        elif pose.startswith("walk_contact"):     # double support: both feet down, a long step
            assert stride > 0.3 * SPECS[name].stature_m and lows[1] < 1e-6
        else:                                      # mid-stance: the swing foot is off the ground
            assert lows[0] < 1e-6 and lows[1] > 0.02
    lengths = {p: max(build_asset("pedestrian", n, "detailed").length_m
                      for n in NAMES if SPECS[n].pose == p) for p in ("standing", "walk_contact")}
    assert lengths["walk_contact"] > lengths["standing"] + 0.3


@pytest.mark.parametrize("name", sorted(CYCLISTS))
def test_cyclists_ride_their_bicycle(name):
    spec = SPECS[name]
    parts, j = body_parts(spec), skeleton(spec)
    tyres = parts["bike_tyres"][1][0]
    lows = [tyres[np.abs(tyres[:, 0] - j[k][0]) < 0.5 * spec.stature_m / 1.75, 2].min()
            for k in ("rear_axle", "front_axle")]
    assert abs(lows[0] - lows[1]) < 1e-3                                  # both wheels on the ground
    assert min(p[0][:, 2].min() for _, p in parts.values()) == pytest.approx(min(lows), abs=1e-9)
    for s in "rl":
        assert _outside_m(parts[f"foot_{s}"][1], j[f"pedal_{s}"]) < 0.003   # feet on the pedals
        assert _outside_m(parts[f"hand_{s}"][1], j[f"grip_{s}"]) < 0.003    # hands on the bar
        knee = np.degrees(np.arccos(np.clip(
            (j[f"knee_{s}"] - j[f"hip_{s}"]) @ (j[f"ankle_{s}"] - j[f"knee_{s}"]) /
            np.linalg.norm(j[f"knee_{s}"] - j[f"hip_{s}"]) / np.linalg.norm(j[f"ankle_{s}"] - j[f"knee_{s}"]),
            -1, 1)))
        assert 20 <= knee <= 130                                             # a pedalling knee
    assert _outside_m(parts["pelvis"][1], j["saddle"]) < 0.003             # seated on the saddle
    a = build_asset("pedestrian", name, "detailed")
    assert 0.95 * spec.stature_m <= a.length_m <= 1.05 * spec.stature_m   # bicycle scaled to its rider
    assert a.length_m > 2.5 * a.width_m


def test_arms_swing_against_the_legs():
    name = next(n for n in NAMES if SPECS[n].pose == "walk_contact")
    j = skeleton(SPECS[name])
    lead = "r" if j["ankle_r"][0] > j["ankle_l"][0] else "l"
    other = "l" if lead == "r" else "r"
    assert j[f"wrist_{other}"][0] > j[f"wrist_{lead}"][0] + 0.1


def _band(name, lo, hi):
    return reflectance(name)[(WL >= lo) & (WL <= hi)].mean()


def test_clothing_spectra():
    dyed = ("cloth_navy", "cloth_blue", "cloth_burgundy", "cloth_beige", "cloth_brown", "cloth_yellow",
            "cloth_pink", "cloth_black", "cloth_denim", "cloth_green", "cloth_red")
    for name in dyed:          # textile dyes are NIR-transparent: bright past ~750 nm
        assert _band(name, 800, 950) >= 0.38 and _band(name, 800, 950) > _band(name, 400, 650)
    for name in ("cloth_navy", "cloth_burgundy", "cloth_black"):
        assert _band(name, 450, 650) < 0.2
    for name in ("cloth_carbon", "leather_black"):       # carbon black stays dark
        assert _band(name, 350, 1000) < 0.08
    assert _band("cloth_hivis_yellow", 520, 600) > 0.8 and _band("cloth_hivis_yellow", 400, 460) < 0.15
    assert _band("cloth_hivis_orange", 600, 680) > 0.75 and _band("cloth_hivis_orange", 450, 530) < 0.1
    assert _band("leather_brown", 800, 950) > 2 * _band("leather_brown", 450, 550)
    for name in HAIRS:          # eumelanin absorbs less at longer wavelengths
        r = reflectance(name)
        assert np.all(np.diff(r) >= -1e-12) and r[-1] > r[0]


def test_detailed_city_is_deterministic_and_labels_whole_people():
    recipe = CityRecipe(blocks_x=1, blocks_y=1, asset_detail="detailed", n_pedestrians=20, n_cars=4)
    a, b = generate_city(recipe), generate_city(recipe)
    peds = [o for o in a.objects if o.class_name == "pedestrian"]
    assert len(peds) == 20 and all(o.meta["variant"] in NAMES for o in peds)
    assert all(len(o.meshes) >= 3 for o in peds)            # one mesh per material: skin, clothes, hair …
    for oa, ob in zip(a.objects, b.objects):
        assert oa.instance_id == ob.instance_id and oa.meta.get("variant") == ob.meta.get("variant")
        for ma, mb in zip(oa.meshes, ob.meshes):
            assert ma.material == mb.material
            assert np.array_equal(ma.vertices, mb.vertices) and np.array_equal(ma.faces, mb.faces)
    simple = generate_city(recipe.model_copy(update={"asset_detail": "simple"}))
    assert all(o.meta["variant"].startswith("person_") for o in simple.objects
               if o.class_name == "pedestrian")


def test_cyclists_ride_along_the_sidewalk_inside_their_footprint():
    city = generate_city(CityRecipe(blocks_x=2, blocks_y=1, asset_detail="detailed", n_pedestrians=80))
    layout = city.meta["layout"]
    riders = [o for o in city.objects if o.class_name == "pedestrian" and o.meta["variant"] in CYCLISTS]
    assert riders
    for o in riders:
        strip = next(r for r in layout.sidewalk_rects
                     if r[0] <= o.meta["position_m"][0] <= r[2] and r[1] <= o.meta["position_m"][1] <= r[3])
        along = 0.0 if strip[2] - strip[0] >= strip[3] - strip[1] else 90.0
        off = (o.meta["heading_deg"] - along) % 180.0
        assert min(off, 180.0 - off) <= 5.0 + 1e-9
        v = np.concatenate([m.vertices for m in o.meshes])
        assert layout.on_sidewalk(v[:, :2]).all()                    # wheels stay on the sidewalk
        fp = o.footprint_xy                                           # every vertex inside the rect
        c = fp.mean(0)
        h = np.radians(o.meta["heading_deg"])
        axes = np.array([[np.cos(h), np.sin(h)], [-np.sin(h), np.cos(h)]])
        local = (v[:, :2] - c) @ axes.T
        half = np.abs((fp - c) @ axes.T).max(0)
        assert (np.abs(local) <= half + 1e-9).all()
