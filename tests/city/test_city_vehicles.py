"""Detailed vehicles (scene/city/vehicles.py): closed outward parts, spec dimensions, the cues a
detector uses (wheels that show through arches, lights at regulation heights, mirrors, plates),
a modest triangle budget, and night lights found on them."""
import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from workbench.scene.city import CityRecipe, build_asset, generate_city, variant_names
from workbench.scene.city.assets import BUS_SPECS, CAR_SPECS, PAINT, TRUCK_SPECS
from workbench.scene.city.materials import material_names

SPECS = {"car": {s.name: s for s in CAR_SPECS}, "bus": {s.name: s for s in BUS_SPECS},
         "truck": {s.name: s for s in TRUCK_SPECS}}
ALL = [(c, v) for c in SPECS for v in variant_names(c, "detailed")]
MAX_TRIANGLES = {"car": 3000, "bus": 4000, "truck": 4000}
MIRROR_REACH_M = {"car": 0.12, "bus": 0.25, "truck": 0.30}


def _components(v, f):
    n = len(v)
    adj = coo_matrix((np.ones(3 * len(f)), (np.r_[f[:, 0], f[:, 1], f[:, 2]], np.r_[f[:, 1], f[:, 2], f[:, 0]])),
                     shape=(n, n))
    k, label = connected_components(adj, directed=False)
    return [f[label[f[:, 0]] == c] for c in range(k)]


def _closed(f):
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    fwd = {tuple(e) for e in edges.tolist()}
    return len(fwd) == len(edges) and all((b, a) in fwd for a, b in fwd)


def _first_hit(asset, origin, direction):
    """Material of the first triangle a ray meets (Möller–Trumbore), or None."""
    best, hit = np.inf, None
    o, d = np.asarray(origin, float), np.asarray(direction, float)
    for mat, (v, f) in asset.parts.items():
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        e1, e2 = b - a, c - a
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1 / np.where(ok, det, 1), 0)
        s = o - a
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        w = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        m = ok & (u >= 0) & (w >= 0) & (u + w <= 1) & (t > 1e-9)
        if m.any() and t[m].min() < best:
            best, hit = t[m].min(), mat
    return hit


@pytest.mark.parametrize("cls,variant", ALL)
def test_parts_are_closed_outward_solids_on_the_ground(cls, variant):
    a = build_asset(cls, variant, "detailed")
    allv = np.concatenate([v for v, _ in a.parts.values()])
    assert allv[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    assert np.allclose((allv[:, :2].min(0) + allv[:, :2].max(0)) / 2, 0.0, atol=1e-9)
    assert set(a.parts) <= set(material_names()) | {PAINT}
    for mat, (v, f) in a.parts.items():
        tri = v[f]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        assert area.min() > 1e-8, (mat, area.min())
        if mat == "glass_dark" and cls != "car":
            continue                                   # window panes on bus and truck bodies
        for comp in _components(v, f):
            assert _closed(comp), (mat,)
            t = v[comp]
            vol = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6
            assert vol > 1e-6, (mat, vol)              # wound outward
    assert sum(len(f) for _, f in a.parts.values()) <= MAX_TRIANGLES[cls]


@pytest.mark.parametrize("cls,variant", ALL)
def test_dimensions_match_the_spec(cls, variant):
    a, spec = build_asset(cls, variant, "detailed"), SPECS[cls][variant]
    assert a.length_m == pytest.approx(spec.length_m, abs=0.02)
    assert a.height_m == pytest.approx(spec.height_m, abs=0.02)
    paint = a.parts[PAINT][0] if cls != "truck" else a.parts["paint_white"][0]
    assert np.ptp(paint[:, 1]) == pytest.approx(spec.width_m, abs=0.01)     # the body: spec width
    assert spec.width_m < a.width_m <= spec.width_m + 2 * MIRROR_REACH_M[cls]   # + the mirrors


@pytest.mark.parametrize("cls,variant", ALL)
def test_detector_cues_present(cls, variant):
    a, spec = build_asset(cls, variant, "detailed"), SPECS[cls][variant]
    for mat, count in (("rubber", 4), ("lens_clear", 2), ("lens_red", 2)):
        assert len(_components(*a.parts[mat])) == count, mat
    assert len(_components(*a.parts["metal_galvanized"])) == 8          # rims and hub caps
    plates = [p for m, p in a.parts.items() if m.startswith("plate_")]
    assert sum(len(_components(*p)) for p in plates) == 2
    heads, tails = a.parts["lens_clear"][0], a.parts["lens_red"][0]
    assert heads[:, 0].min() > 0 > tails[:, 0].max()                    # head-lights front, tail-lights rear
    assert 0.5 <= heads[:, 2].min() and heads[:, 2].max() <= 1.2        # ECE R48 heights
    assert 0.35 <= tails[:, 2].min() and tails[:, 2].max() <= 1.5
    black = a.parts["plastic_black"][0]
    for s in (-1, 1):                                                   # a mirror on each side
        assert (s * black[:, 1] > spec.width_m / 2 + 0.05).any()


@pytest.mark.parametrize("cls,variant", ALL)
def test_wheels_show_through_arches_and_the_arches_are_lined(cls, variant):
    a = build_asset(cls, variant, "detailed")
    tyres = _components(*a.parts["rubber"])
    v = a.parts["rubber"][0]
    for comp in tyres:
        t = v[np.unique(comp)]
        if t[:, 1].mean() < 0:
            continue
        x, r = (t[:, 0].min() + t[:, 0].max()) / 2, t[:, 2].max() / 2
        for dz in (0.0, 0.6 * r, -0.6 * r):                            # the hub, above and below it
            assert _first_hit(a, (x, 10.0, r + dz), (0, -1, 0)) in ("rubber", "metal_galvanized"), dz
        gap = r + 0.03                                                  # between tyre and arch
        for ang in (np.radians(60), np.radians(120)):
            hit = _first_hit(a, (x + gap * np.cos(ang), 10.0, r + gap * np.sin(ang)), (0, -1, 0))
            assert hit not in (None, PAINT), ang                       # a liner or chassis, no hole


def test_night_lights_found_on_detailed_vehicles():
    from workbench.render.lamps import _vehicle_light_points
    from workbench.scene.city.types import CityObject

    for cls, variant in ALL:
        a = build_asset(cls, variant, "detailed")
        obj = CityObject(cls, 1, a.meshes("paint_red"))
        heads = _vehicle_light_points(obj, "lens_clear")
        tails = _vehicle_light_points(obj, "lens_red")
        assert len(heads) == len(tails) == 2
        for p, d, _ in heads:
            assert d[0] > 0.99 and abs(p[0] - a.length_m / 2) < 0.1
        for p, d, _ in tails:
            assert d[0] < -0.99 and abs(p[0] + a.length_m / 2) < 0.1


def test_detailed_city_is_deterministic_and_differs_from_simple():
    r = CityRecipe(seed=4, arrangement=2, asset_detail="detailed", n_cars=10, n_pedestrians=6)
    a, b = generate_city(r), generate_city(r)
    assert len(a.objects) == len(b.objects)
    for x, y in zip(a.objects, b.objects):
        assert (x.class_name, x.instance_id) == (y.class_name, y.instance_id)
        for m, n in zip(x.meshes, y.meshes):
            assert m.material == n.material
            assert np.array_equal(m.vertices, n.vertices) and np.array_equal(m.faces, n.faces)
    simple = generate_city(r.model_copy(update={"asset_detail": "simple"}))
    cars = [o for o in a.objects if o.class_name == "car"]
    assert cars and all(any(m.material == "rubber" for m in o.meshes) for o in cars)
    assert sum(len(m.faces) for o in a.objects for m in o.meshes) > \
        sum(len(m.faces) for o in simple.objects for m in o.meshes)
    assert set(a.materials) >= {"plate_white", "plate_yellow", "metal_galvanized"}
