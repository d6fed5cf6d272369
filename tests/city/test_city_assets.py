"""Procedural assets: enough variants, realistic dimensions, closed outward solids, on the ground."""
import numpy as np
import pytest

from workbench.scene.city import build_asset, variant_names
from workbench.scene.city.assets import PAINT
from workbench.scene.city.catalog import VARIANTS
from workbench.scene.city.materials import material_names

ALL = [(c, v) for c in VARIANTS for v in variant_names(c)]


def test_variant_counts():
    assert len(variant_names("car")) >= 12
    assert len(variant_names("pedestrian")) >= 24
    assert len(variant_names("bus")) >= 2
    assert len(variant_names("truck")) >= 1


@pytest.mark.parametrize("name", variant_names("car"))
def test_car_dimensions(name):
    a = build_asset("car", name)
    assert 4.2 <= a.length_m <= 5.0 and 1.8 <= a.width_m <= 2.0 and 1.4 <= a.height_m <= 1.7


def test_people_and_bus_dimensions():
    heights = [build_asset("pedestrian", n).height_m for n in variant_names("pedestrian")]
    assert min(heights) >= 1.5 and max(heights) <= 1.95 and max(heights) - min(heights) > 0.35
    for n in variant_names("pedestrian"):
        a = build_asset("pedestrian", n)
        assert 0.3 <= a.width_m <= 0.6 and a.length_m <= 0.8
    for n in variant_names("bus"):
        a = build_asset("bus", n)
        assert 11.5 <= a.length_m <= 12.5 and 2.5 <= a.width_m <= 2.6 and 3.0 <= a.height_m <= 3.4
    assert len({(a.length_m, a.width_m, a.height_m) for a in
                (build_asset("car", n) for n in variant_names("car"))}) == len(variant_names("car"))


def _closed(f):
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    fwd = {tuple(e) for e in edges.tolist()}
    return len(fwd) == len(edges) and all((b, a) in fwd for a, b in fwd)


@pytest.mark.parametrize("cls,variant", ALL)
def test_assets_are_sound(cls, variant):
    a = build_asset(cls, variant)
    allv = np.concatenate([v for v, _ in a.parts.values()])
    assert np.all(np.isfinite(allv))
    assert allv[:, 2].min() == pytest.approx(0.0, abs=1e-9)           # stands on the ground
    if cls == "lamp":                                                  # origin at the pole
        pole = np.concatenate([v for v, _ in a.parts.values()])
        assert np.abs(pole[pole[:, 2] < 1.0, :2]).max() < 0.2
    else:
        assert np.allclose((allv[:, :2].min(0) + allv[:, :2].max(0)) / 2, 0.0, atol=1e-9)
    known = set(material_names()) | {PAINT}
    for mat, (v, f) in a.parts.items():
        assert mat in known
        assert f.min() >= 0 and f.max() < len(v)
        tri = v[f]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        assert area.min() > 1e-8                                        # no degenerate triangles
        if _closed(f):   # closed solids must enclose positive volume (outward winding)
            vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
            assert vol > 0
    mesh_mats = {m.material for m in a.meshes("paint_red")}
    assert PAINT not in mesh_mats


def test_open_glass_faces_outward():
    for cls in ("bus", "truck"):
        for n in variant_names(cls):
            v, f = build_asset(cls, n).parts["glass_dark"]
            tri = v[f]
            normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            centre = tri.mean(1) - np.array([0.0, 0.0, 1.5])
            centre[:, 2] = 0.0
            assert np.all(np.einsum("ij,ij->i", normal, centre) > 0)


def test_solid_materials_closed():
    for cls, variant in ALL:
        a = build_asset(cls, variant)
        for mat, (v, f) in a.parts.items():
            if mat not in ("glass_dark", "lens_clear") or cls == "car":
                assert _closed(f), (cls, variant, mat)


def test_errors():
    with pytest.raises(ValueError, match="unknown car variant 'tank'"):
        build_asset("car", "tank")
    with pytest.raises(ValueError, match="no assets of class 'dragon'"):
        variant_names("dragon")
    with pytest.raises(ValueError, match="needs a paint"):
        build_asset("car", "coupe").meshes()


def test_overhead_parts_clear_the_tallest_vehicle():
    tallest = max(build_asset(c, n).height_m for c in ("car", "bus", "truck") for n in variant_names(c))
    for n in variant_names("tree"):
        v, _ = build_asset("tree", n).parts["leaves"]
        assert v[:, 2].min() > tallest + 0.1          # canopies may overhang the kerb lane
    for n in variant_names("lamp"):
        a = build_asset("lamp", n)
        v = np.concatenate([v for v, _ in a.parts.values()])
        assert v[v[:, 0] > 0.3, 2].min() > tallest + 1.0   # the arm over the road


def test_detail_level_falls_back_to_simple_builders_and_refuses_unknown_levels():
    from workbench.scene.city.catalog import DETAILED_BUILDERS

    for cls in VARIANTS:
        if cls not in DETAILED_BUILDERS:
            assert variant_names(cls, "detailed") == variant_names(cls)
    with pytest.raises(ValueError, match="asset detail 'fancy'"):
        variant_names("car", "fancy")
