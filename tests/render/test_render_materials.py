"""Procedural materials (scene/city/textures.py, surfaces.py; render/scene_builder.py): oracles.

- Blend: a flat patch, one texture tile, seen straight down by an orthographic camera under a
  constant environment L reads L·ρ̄ (= E·ρ̄/π) in every band, 400–1000 nm: ρ̄ = mean over
  the tile of (1 − w)·ρ_base + w·ρ_layer, with w the baked texture (bilinear filtering of a
  periodic texture keeps its mean); weights 0 and 1 give the pure materials. Tolerance 5
  standard errors of the image mean + 0.3 % (float32, band edges).
- Wet layer: a water film (n = 1.33) over a Lambertian substrate ρ seen at normal incidence reads
  L·[F₀ + (1 − F₀)·ρ(1 − F̄ᵢ)/(1 − ρF̄ᵢ)] (Lekner & Dorf 1988), F̄ᵢ = 1 − (1 − F̄ₑ)/n² from the
  exact Fresnel equations integrated numerically here; within 2 % (Mitsuba fits F̄).
- Textures: deterministic for a seed, in [0, strength], seamless across the wrap, coverage
  masks cover their fraction, brick mortar covers 1 − (215·65)/(225·75) of a wall, slab joints
  1 − (1 − 0.01/1.5)² of a pavement.
- 'uniform' leaves the scene as before (bit-identical render); 'procedural' leaves labels alone.
"""
import numpy as np
import pytest

from workbench.render.film import box_bands
from workbench.render.labels import render_labels
from workbench.render.params import DaylightParams, WorldParams
from workbench.render.scene_builder import (_mesh, build_scene, lambertian_dict, surface_bsdf, texture_dict,
                                            wet_dict)
from workbench.scene.city import generate_city
from workbench.scene.city.materials import city_materials
from workbench.scene.city.recipe import CityRecipe
from workbench.scene.city.surfaces import WATER_IOR, planar_uv_m, procedural_surfaces
from workbench.scene.city.textures import BRICK_M, JOINT_M, KINDS, SLAB_M, bake
from workbench.scene.city.types import CameraPose
from workbench.units import photon_energy_J

N = 48
FILM = box_bands(400.0, 1000.0, 6)            # 100-nm bands, the last two past 800 nm
MATS = city_materials()
SEED = 7


def band_mean_photons(wl, energy):
    """Band means of a piecewise-linear energy spectrum, in photons (exact to the 0.05-nm grid)."""
    fine = np.arange(350.0, 1000.0, 0.05)
    e = np.interp(fine, wl, energy) / photon_energy_J(fine)
    s = np.stack([np.interp(fine, FILM.wavelengths_nm, r, left=0, right=0) for r in FILM.responses])
    return np.trapezoid(s * e, fine, axis=1) / np.trapezoid(s, fine, axis=1)


def render_patch(mi, bsdf, tile_m, spp=16, seed=1):
    """Orthographic view straight down onto a [0, tile]² patch that fills the film; constant
    environment L = 1 W/m²/sr/nm. Returns band-mean photon radiance (N×N×bands)."""
    v = np.array([[0, 0, 0], [tile_m, 0, 0], [tile_m, tile_m, 0], [0, tile_m, 0]], float)
    v, f, uv = planar_uv_m(v, np.array([[0, 1, 2], [0, 2, 3]]))
    c = tile_m / 2
    cam = mi.ScalarTransform4f().look_at(origin=[c, c, 5.0], target=[c, c, 0.0], up=[0, 1, 0])
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 3},
        "sensor": {"type": "orthographic", "to_world": cam @ mi.ScalarTransform4f().scale([c, c, 1.0]),
                   "film": FILM.mitsuba_film(N, N), "sampler": {"type": "independent"}},
        "env": {"type": "constant", "radiance": {"type": "spectrum", "value": [(350.0, 1.0), (1000.0, 1.0)]}},
        "patch": _mesh(mi, "patch", v, f, bsdf, texcoords=uv)})
    return FILM.channels_to_radiance(np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64))


def check(mi, bsdf, tile_m, rho_energy, label):
    """The patch's mean band radiance against L·ρ̄ (L = 1 W/m²/sr/nm). The Monte Carlo error of
    the mean comes from two independent renders (their per-pixel difference), because the pixels
    also vary with the texture."""
    a, b = render_patch(mi, bsdf, tile_m, seed=1), render_patch(mi, bsdf, tile_m, seed=2)
    expected = band_mean_photons(MATS["asphalt"].wavelengths_nm, rho_energy)
    d = (a - b).reshape(-1, a.shape[-1])
    sem = d.std(axis=0) / np.sqrt(2 * d.shape[0])        # of the two renders' mean
    tol = 5 * sem + 3e-3 * expected
    err = np.abs((a + b).reshape(-1, a.shape[-1]).mean(axis=0) / 2 - expected)
    assert np.all(tol < 0.03 * expected), f"{label}: tolerance {tol / expected} too loose to test anything"
    assert np.all(err <= tol), f"{label}: rel err {err / expected} > tol {tol / expected}"
    return a, b


@pytest.mark.parametrize("weight", [0.0, 1.0])
def test_blend_weights_zero_and_one_give_the_pure_materials(mi, weight):
    bsdf = mi.load_dict({"type": "blendbsdf",
                         "weight": texture_dict(mi, np.full((16, 16), weight, np.float32), 2.0),
                         "below": lambertian_dict(MATS["grass"], FILM.range_nm),
                         "layer": lambertian_dict(MATS["brick"], FILM.range_nm)})
    check(mi, bsdf, 2.0, MATS["brick" if weight else "grass"].reflectance, f"weight {weight}")


@pytest.mark.parametrize("name", ["grass", "concrete_dark", "asphalt", "plaster_white"])
def test_blend_reads_the_texture_weighted_lambertian_radiance(mi, name):
    surface = procedural_surfaces(0.0)[name]
    assert len(surface.layers) == 1
    layer = surface.layers[0]
    w = bake(layer.texture.kind, layer.texture.size_px, SEED, layer.texture.fraction, layer.texture.strength)
    assert 0.05 < w.mean() < 0.95                           # both components really present
    rho = (1 - w.mean()) * MATS[surface.base].reflectance + w.mean() * MATS[layer.material].reflectance
    a, b = check(mi, surface_bsdf(mi, surface, MATS, FILM.range_nm, SEED), layer.texture.tile_m, rho, name)
    # the texture is really there: two renders with independent noise agree pixel by pixel
    k = np.argmax(np.abs(band_mean_photons(MATS["asphalt"].wavelengths_nm,
                                           MATS[layer.material].reflectance - MATS[surface.base].reflectance)))
    assert np.corrcoef(a[..., k].ravel(), b[..., k].ravel())[0, 1] > 0.15


def _fresnel(cos_i, n):
    sin_t = np.sqrt(np.clip(1 - cos_i ** 2, 0, None)) / n
    cos_t = np.sqrt(1 - sin_t ** 2)
    rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    rp = ((n * cos_i - cos_t) / (n * cos_i + cos_t)) ** 2
    return (rs + rp) / 2


def test_wet_layer_darkens_by_lekner_dorf(mi):
    n = WATER_IOR
    th = np.linspace(0.0, np.pi / 2, 200001)
    f_ext = np.trapezoid(_fresnel(np.cos(th), n) * 2 * np.sin(th) * np.cos(th), th)
    f_int = 1 - (1 - f_ext) / n ** 2
    f0 = ((n - 1) / (n + 1)) ** 2
    rho = MATS["asphalt"].reflectance
    wet = f0 + (1 - f0) * rho * (1 - f_int) / (1 - rho * f_int)
    img = render_patch(mi, mi.load_dict(wet_dict(MATS["asphalt"], FILM.range_nm)), 2.0, spp=64)
    expected = band_mean_photons(MATS["asphalt"].wavelengths_nm, wet)
    got = img.reshape(-1, img.shape[-1]).mean(axis=0)
    np.testing.assert_allclose(got, expected, rtol=0.02)
    diffuse = (1 - f0) * rho * (1 - f_int) / (1 - rho * f_int)
    assert np.all(diffuse < 0.6 * rho)                      # water-filled pores: darker substrate


@pytest.mark.parametrize("kind", [k for k in KINDS if not k.startswith(("brick", "slab"))])
def test_noise_textures_are_deterministic_bounded_and_seamless(kind):
    a = bake(kind, 128, 3, 0.2, 0.8)
    assert a.dtype == np.float32 and a.shape == (128, 128)
    np.testing.assert_array_equal(a, bake.__wrapped__(kind, 128, 3, 0.2, 0.8))
    assert not np.array_equal(a, bake(kind, 128, 4, 0.2, 0.8))
    assert a.min() >= 0.0 and a.max() <= 0.8 and a.max() > 0.1
    for t in (a, a.T):              # the step across the wrap is like any other step
        inner = np.abs(np.diff(t, axis=1)).mean()
        wrap = np.abs(t[:, 0] - t[:, -1]).mean()
        assert wrap <= 3 * inner + 1e-6, f"{kind}: seam {wrap} vs interior {inner}"


def test_brick_texture_tiles_seamlessly():
    """Mortar is invariant under a shift of one brick along and two courses up, across the wrap
    too (192 px = 8 bricks = 24 courses × 8 px); a brick cut by the wrap keeps one value."""
    mortar = bake("brick_mortar", 192, 3)
    np.testing.assert_array_equal(np.roll(mortar, (16, 24), axis=(0, 1)), mortar)
    var = bake("brick_variation", 192, 3, 0.0, 0.7)
    np.testing.assert_array_equal(var, bake.__wrapped__("brick_variation", 192, 3, 0.0, 0.7))
    assert var.min() >= 0 and var.max() <= 0.7 and len(np.unique(var)) > 100
    inside = (mortar[:, 0] == 0) & (mortar[:, -1] == 0)
    assert inside.sum() > 48
    np.testing.assert_array_equal(var[inside, 0], var[inside, -1])


def test_coverage_and_mortar_fractions():
    for fraction in (0.05, 0.2, 0.5):
        assert bake("puddles", 256, 1, fraction).mean() == pytest.approx(fraction, abs=0.02)
    mortar = 1 - BRICK_M[0] * BRICK_M[1] / ((BRICK_M[0] + JOINT_M) * (BRICK_M[1] + JOINT_M))
    assert bake("brick_mortar", 512, 1).mean() == pytest.approx(mortar, abs=0.01)
    joints = 1 - (1 - JOINT_M / SLAB_M) ** 2
    assert bake("slab_joints", 600, 1).mean() == pytest.approx(joints, abs=0.002)


def test_planar_uv_projects_ground_by_xy_and_walls_by_distance_and_height():
    v = np.array([[1, 2, 0], [3, 2, 0], [3, 5, 0],             # ground triangle
                  [0, 0, 0], [0, 4, 0], [0, 4, 3]], float)     # wall in the x = 0 plane
    vv, f, uv = planar_uv_m(v, np.array([[0, 1, 2], [3, 4, 5]]))
    assert vv.shape == (6, 3) and f.tolist() == [[0, 1, 2], [3, 4, 5]]
    np.testing.assert_allclose(uv[:3], v[:3, :2])
    np.testing.assert_allclose(np.abs(uv[4, 0] - uv[3, 0]), 4.0)      # along the wall
    np.testing.assert_allclose(uv[3:, 1], [0, 0, 3])                   # height


def _small_city():
    return generate_city(CityRecipe(seed=2, blocks_x=1, blocks_y=1, block_size_m=60.0, n_cars=3, n_pedestrians=3,
                                    n_buses=0, n_trucks=0, n_trees=2, n_lamps=2, n_benches=0, n_mailboxes=0))


def _pose():
    return CameraPose(np.array([-6.0, -6.0, 6.0]), pan_deg=45.0, tilt_deg=-12.0, roll_deg=0.0)


def test_uniform_leaves_the_scene_as_before_and_procedural_leaves_labels(mi):
    city, film = _small_city(), box_bands(400.0, 1000.0, 3)
    args = (city, _pose(), 70.0, 32, 24, film, DaylightParams())
    before, ids = build_scene(*args, max_depth=2)
    uniform, ids_u = build_scene(*args, max_depth=2, world=WorldParams(materials="uniform"))
    proc, ids_p = build_scene(*args, max_depth=2, world=WorldParams(materials="procedural", wet_road_fraction=0.3))
    assert ids == ids_u == ids_p
    for s in uniform.shapes():
        assert not s.has_vertex_texcoords() and not str(s.bsdf()).startswith("BlendBSDF")
    np.testing.assert_array_equal(np.array(mi.render(uniform, spp=2, seed=3)), np.array(mi.render(before, spp=2, seed=3)))
    blended = [s for s in proc.shapes() if s.has_vertex_texcoords()]
    assert blended and all(str(s.bsdf()).startswith("BlendBSDF") for s in blended)
    ref, got = render_labels(before, ids, 32, 24), render_labels(proc, ids_p, 32, 24)
    np.testing.assert_array_equal(got.instance_id, ref.instance_id)
    assert [(o.instance_id, o.bbox_xywh, o.amodal_bbox_xywh) for o in got.objects] == \
        [(o.instance_id, o.bbox_xywh, o.amodal_bbox_xywh) for o in ref.objects]
