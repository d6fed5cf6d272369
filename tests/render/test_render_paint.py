"""Clear-coat paint (WorldParams.paint 'clearcoat', scene_builder._bsdf): physical checks.

Oracle: a flat coated plate under a constant environment of radiance L, seen at angle θ. The
coat reflects L·R(θ) (R: the Fresnel reflectance of n = 1.5, 4 % at normal incidence), and
with the linear internal-scattering model the base of reflectance ρ adds L·ρ·(1 − R(θ)): light
entering the coat is either absorbed in the base or leaves again, and reciprocity,
η²(1 − R_int) = 1 − R_ext (diffuse Fresnel reflectances inside and outside), makes the two
transmissions and the internal reflections cancel to (1 − R(θ)). Both read against a white
Lambertian plate, which reads L. The coat's small roughness (α = 0.02) averages R over a degree
or two and masks < 1 % at these angles; Mitsuba's roughplastic keeps 98.6 % of the base's share
at this α (1.4 % lost, mitsuba3 #1155): tolerance 3 % of the coat term, 2 % overall."""
import numpy as np
import pytest

from workbench.render.film import box_bands
from workbench.render.scene_builder import PAINT_COAT_IOR, _bsdf
from workbench.scene.city.types import Material

W, H = 16, 12


def _fresnel(cos_i, n):
    sin_t = np.sqrt(max(0.0, 1 - cos_i ** 2)) / n
    cos_t = np.sqrt(1 - sin_t ** 2)
    rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    rp = ((n * cos_i - cos_t) / (n * cos_i + cos_t)) ** 2
    return (rs + rp) / 2


def _plate_reading(mi, bsdf, view_deg, film, spp=64):
    th = np.radians(view_deg)
    origin = [float(np.sin(th)), 0.0, float(np.cos(th))]
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 8},
        "sensor": {"type": "perspective", "fov": 2.0, "film": film.mitsuba_film(W, H),
                   "to_world": mi.ScalarTransform4f().look_at(origin=origin, target=[0, 0, 0], up=[0, 0, 1]
                                                              if view_deg > 1 else [0, 1, 0]),
                   "sampler": {"type": "independent"}},
        "env": {"type": "constant", "radiance": {"type": "spectrum", "value": [(300.0, 1.0), (1100.0, 1.0)]}},
        "plate": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(100.0), "bsdf": bsdf}})
    img = np.array(mi.render(scene, spp=spp, seed=5), dtype=np.float64)
    return img.reshape(-1, img.shape[-1]).mean(0)


def _material(name, rho_blue, rho_red):
    wl = np.array([350.0, 699.95, 700.05, 1000.0])
    return Material(name, wl, np.array([rho_blue, rho_blue, rho_red, rho_red]))


@pytest.mark.parametrize("view_deg", [0.0, 60.0])
def test_clearcoat_reflects_by_fresnel_over_its_spectral_base(mi, view_deg):
    film = box_bands(400.0, 1000.0, 2)                       # 400–700 and 700–1000 nm
    white = _plate_reading(mi, mi.load_dict({"type": "diffuse", "reflectance": 1.0}), view_deg, film, spp=4)
    r = _fresnel(np.cos(np.radians(view_deg)), PAINT_COAT_IOR)
    eps = 1e-3                                 # (Mitsuba refuses an all-zero base spectrum)
    black = _bsdf(mi, _material("paint_black", eps, eps), (400.0, 1000.0), paint="clearcoat")
    coat = _plate_reading(mi, black, view_deg, film) / white - eps * (1 - r)
    np.testing.assert_allclose(coat, r, rtol=0.03)
    if view_deg == 0.0:
        assert r == pytest.approx(((PAINT_COAT_IOR - 1) / (PAINT_COAT_IOR + 1)) ** 2, rel=1e-12)   # 4 %
    rho = np.array([0.2, 0.7])                                  # blue-ish base, bright in the NIR
    painted = _bsdf(mi, _material("paint_test", *rho), (400.0, 1000.0), paint="clearcoat")
    got = _plate_reading(mi, painted, view_deg, film) / white
    np.testing.assert_allclose(got, r + rho * (1 - r), rtol=0.02)


def test_paint_switch_leaves_other_materials_and_the_default_lambertian(mi):
    mat = _material("paint_red", 0.1, 0.6)
    assert "Diffuse" in str(_bsdf(mi, mat, (400.0, 1000.0)))
    assert "RoughPlastic" in str(_bsdf(mi, mat, (400.0, 1000.0), paint="clearcoat"))
    assert "Diffuse" in str(_bsdf(mi, _material("asphalt", 0.1, 0.1), (400.0, 1000.0), paint="clearcoat"))
    with pytest.raises(ValueError, match="paint must be"):
        _bsdf(mi, mat, (400.0, 1000.0), paint="gloss")
