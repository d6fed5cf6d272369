"""Night lamps, fog and glass (render/lamps.py, fog.py, scene_builder): physical checks.

- Lamps: a white Lambertian plane under a lamp, seen with a V(λ)-weighted film: E_v = π L_v
  must be Φ/(2π d²) (full cut-off) at 1 m and 10 m within 2 % (rated flux, inverse square).
- Fog: an emitter behind d metres of absorbing fog reads L e^{−σd}, σ = 3.912/V, within 4
  standard errors of the binary (transmitted or absorbed) estimator.
- Glass: the pane's reflectance and transmittance against the Fresnel equations.
- Labels: the instance map and boxes are identical with fog and dielectric glass present."""
import numpy as np
import pytest

from workbench.render.demo_scene import plane_mesh
from workbench.render.film import box_bands
from workbench.render.fog import extinction_per_m, fog_box, fog_medium
from workbench.render.labels import render_labels
from workbench.render.lamps import (LAMP_KINDS, RATED_FLUX_LM, lamp_spectrum, luminous_intensity_spectrum,
                                    night_emitters, street_lamp_emitter)
from workbench.render.params import DaylightParams, FogParams, NightParams, WorldParams
from workbench.render.scene_builder import GLASS_IOR, build_scene
from workbench.scene.city.types import CameraPose, City, CityObject, Material, Mesh
from workbench.spectra import luminous_efficiency

FLAT = [(300.0, 1.0), (1100.0, 1.0)]


def _v_film(mi, w, h):
    wl = np.arange(360.0, 831.0, 1.0)
    return {"type": "specfilm", "width": w, "height": h, "rfilter": {"type": "box"},
            "component_format": "float32",
            "v": {"type": "spectrum", "value": list(zip(wl.tolist(), luminous_efficiency(wl).tolist()))}}


def test_lamp_spectra_are_positive_and_calibrated():
    wl = np.arange(300.0, 1100.01, 0.25)
    for kind in LAMP_KINDS + ("halogen", "led_red"):
        s = lamp_spectrum(kind, wl)
        assert np.all(s >= 0) and s.max() > 0
        i = luminous_intensity_spectrum(kind, 100.0, wl)
        assert 683 * np.trapezoid(i * luminous_efficiency(wl), wl) == pytest.approx(100.0, rel=1e-9)
    nir = wl > 780
    share = {k: np.trapezoid(lamp_spectrum(k, wl)[nir], wl[nir]) / np.trapezoid(lamp_spectrum(k, wl), wl)
             for k in LAMP_KINDS}
    assert share["led"] < 0.01 < share["hps"]                   # LEDs emit almost no NIR; sodium does


@pytest.mark.parametrize("kind", LAMP_KINDS)
def test_lamp_illuminance_follows_flux_and_inverse_square(mi, kind):
    for d in (1.0, 10.0):
        spp = 4096 if kind == "lps" else 1024          # a 1-nm line is rarely hit by V(λ)-sampled λ
        lv, sem = _floor_luminance(mi, {"lamp": street_lamp_emitter([0.0, 0.0, d], kind)}, d, spp)
        want = RATED_FLUX_LM[kind] / (2 * np.pi * d ** 2)        # full cut-off: Φ over 2π sr
        assert 4 * np.pi * sem < 0.01 * want, f"{kind} {d} m: the test is too noisy ({np.pi * sem / want:.2%})"
        assert np.pi * lv == pytest.approx(want, rel=0.02), kind          # white Lambertian: E = π L


def _floor_luminance(mi, emitters: dict, height_m: float, spp: int) -> tuple[float, float]:
    """Mean V-weighted luminance (cd/m²) of a white Lambertian floor seen from height_m straight
    above (direct light only), and its standard error."""
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 2},
        "sensor": {"type": "perspective", "fov": 1.0, "film": _v_film(mi, 32, 24),
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, height_m], target=[0, 0, 0],
                                                              up=[0, 1, 0]),
                   "sampler": {"type": "independent"}},
        "ground": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(1000.0),
                   "bsdf": {"type": "diffuse", "reflectance": {"type": "spectrum", "value": FLAT}}},
        **emitters})
    lv = 683.0 * np.array(mi.render(scene, spp=spp, seed=5), dtype=np.float64)[..., 0]
    return lv.mean(), lv.std() / np.sqrt(lv.size)


def test_tail_light_and_sky_glow_follow_their_closed_forms(mi):
    """A tail-light's E = I / r² on a floor facing it (10 cd from 10 m: 0.1 lx) and the night sky
    glow's luminance on a white floor under it (L = E/π = L_sky)."""
    from workbench.render.lamps import spot_emitter
    spot = spot_emitter([0.0, 0.0, 10.0], [0.0, 0.0, -1.0], "led_red", 10.0, cutoff_deg=60.0, beam_deg=20.0)
    lv, sem = _floor_luminance(mi, {"tail": spot}, 10.0, 1024)     # a 18-nm line: V-sampled λ rarely meet it
    assert 4 * sem < 0.01 * lv
    assert np.pi * lv == pytest.approx(10.0 / 10.0 ** 2, rel=0.02)
    sky = night_emitters(type("NoCity", (), {"objects": []})(), NightParams(sky_luminance_cd_m2=0.02))
    lv, sem = _floor_luminance(mi, {"sky": sky["sky"]}, 1.0, 64)
    assert 4 * sem < 0.01 * lv
    assert lv == pytest.approx(0.02, rel=0.02)


def test_fog_transmittance(mi):
    fog = FogParams(visibility_m=60.0, albedo=0.0)
    sigma = extinction_per_m(fog.visibility_m)
    assert sigma == pytest.approx(3.912 / 60.0)
    med = fog_medium(fog)
    d, w, h, spp = 30.0, 16, 12, 256
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "volpath", "max_depth": 4},
        "sensor": {"type": "perspective", "fov": 5.0, "medium": med, "film": box_bands(500, 900, 1).mitsuba_film(w, h),
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 2], target=[1, 0, 2], up=[0, 0, 1]),
                   "sampler": {"type": "independent"}},
        "fog_box": fog_box(med, (-10, -10, 50, 10), 20.0),
        "target": {"type": "rectangle", "exterior": med,
                   "to_world": mi.ScalarTransform4f().look_at(origin=[d, 0, 2], target=[0, 0, 2], up=[0, 0, 1])
                   @ mi.ScalarTransform4f().scale(10.0),
                   "emitter": {"type": "area", "radiance": {"type": "spectrum", "value": FLAT}}}})
    img = np.array(mi.render(scene, spp=spp, seed=3), dtype=np.float64)[..., 0] / 400.0   # band: 400 nm × L=1
    t = np.exp(-sigma * d)
    se = np.sqrt(t * (1 - t) / (w * h * spp * 4))        # binary estimator, ≥ 1 sample per wavelength
    assert abs(img.mean() - t) < 4 * np.sqrt(t * (1 - t) / (w * h * spp)), (img.mean(), t, se)
    assert abs(img.mean() / t - 1) < 0.05


def _fresnel_unpolarized(cos_i, n):
    sin_t = np.sqrt(max(0.0, 1 - cos_i ** 2)) / n
    cos_t = np.sqrt(1 - sin_t ** 2)
    rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    rp = ((n * cos_i - cos_t) / (n * cos_i + cos_t)) ** 2
    return (rs + rp) / 2, rs, rp


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 60.0, 75.0])
def test_glass_pane_reflects_and_transmits_by_fresnel(mi, angle_deg):
    """Thin pane, both faces, incoherent multiple reflections: R = 2r/(1+r), T = 1 − R with r the
    unpolarised Fresnel reflectance of one face (Mitsuba's thindielectric averages the
    polarisations before the slab sum; the exact per-polarisation slab differs by < 1 % of R up
    to 30°, ≈ 3 % at 45° and ≈ 8 % at 60°, measured below and reported)."""
    import drjit as dr
    from workbench.render.scene_builder import _bsdf
    mat = Material("glass_dark", np.array([350.0, 1000.0]), np.array([0.07, 0.07]))
    bsdf = _bsdf(mi, mat, (400.0, 1000.0), "dielectric", pane=True)
    n = 1 << 20
    th = np.radians(angle_deg)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(float(np.sin(th)), 0.0, float(np.cos(th)))
    si.wavelengths = mi.Spectrum(550.0, 700.0, 850.0, 1000.0)
    rng = np.random.default_rng(1)
    bs, weight = bsdf.sample(mi.BSDFContext(), si, mi.Float(rng.random(n)),
                             mi.Point2f(rng.random(n), rng.random(n)))
    refl = np.asarray(bs.wo.z) > 0
    r, rs, rp = _fresnel_unpolarized(np.cos(th), GLASS_IOR)
    want_r = 2 * r / (1 + r)
    assert refl.mean() == pytest.approx(want_r, rel=0.01, abs=3 * np.sqrt(want_r / n))
    assert np.asarray(weight)[0].mean() == pytest.approx(1.0, rel=1e-6)      # lossless: R + T = 1
    exact = (2 * rs / (1 + rs) + 2 * rp / (1 + rp)) / 2
    assert abs(want_r / exact - 1) < {0.0: 1e-9, 30.0: 0.01, 60.0: 0.09, 75.0: 0.2}[angle_deg]


@pytest.mark.parametrize("angle_deg", [0.0, 45.0, 70.0])
def test_window_on_a_facade_reflects_by_fresnel(mi, angle_deg):
    """Window quads on façades: the glass surface's mirror reflectance is the unpolarised Fresnel
    reflectance of one air–glass face (E[weight · specular] over many BSDF samples)."""
    import drjit as dr
    from workbench.render.scene_builder import _bsdf
    mat = Material("glass_dark", np.array([350.0, 1000.0]), np.array([0.07, 0.07]))
    bsdf = _bsdf(mi, mat, (400.0, 1000.0), "dielectric", pane=False)
    n = 1 << 20
    th = np.radians(angle_deg)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(float(np.sin(th)), 0.0, float(np.cos(th)))
    si.wavelengths = mi.Spectrum(550.0, 700.0, 850.0, 1000.0)
    rng = np.random.default_rng(2)
    bs, weight = bsdf.sample(mi.BSDFContext(), si, mi.Float(rng.random(n)),
                             mi.Point2f(rng.random(n), rng.random(n)))
    delta = (np.asarray(bs.sampled_type) & int(mi.BSDFFlags.DeltaReflection)) != 0
    spec = np.where(delta, np.asarray(weight)[0], 0.0).mean()
    assert spec == pytest.approx(_fresnel_unpolarized(np.cos(th), GLASS_IOR)[0], rel=0.01)


def _box(x0, y0, z0, x1, y1, z1, material):
    v = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return Mesh(v, f, material)


def _car_city():
    wl = np.array([350.0, 1000.0])
    mats = {n: Material(n, wl, np.array([r, r])) for n, r in
            (("white", 0.5), ("paint", 0.3), ("glass_dark", 0.07), ("lens_clear", 0.5), ("lens_red", 0.4))}
    car = CityObject("car", 2, [_box(8, -1, 0.2, 12, 1, 1.0, "paint"), _box(9, -0.9, 1.0, 11, 0.9, 1.5, "glass_dark"),
                                _box(12, -0.8, 0.6, 12.05, -0.5, 0.8, "lens_clear"),
                                _box(12, 0.5, 0.6, 12.05, 0.8, 0.8, "lens_clear"),
                                _box(7.95, -0.8, 0.6, 8, -0.5, 0.8, "lens_red"),
                                _box(7.95, 0.5, 0.6, 8, 0.8, 0.8, "lens_red")])
    person = CityObject("pedestrian", 3, [_box(14, 1.5, 0, 14.5, 2.0, 1.8, "paint")])
    return City([CityObject("ground", 1, [plane_mesh(200.0, 0.0, "white")]), car, person], mats,
                seed=0, extent_m=(-50, -50, 50, 50))



@pytest.mark.parametrize("variant", ["lamp_arm_8m", "lamp_arm_6m"])
def test_a_city_street_lamp_shines_from_under_its_head_not_from_its_foot(mi, variant):
    """The city's lamp asset (assets._lamp) merges the pole's dark foot and the luminaire head into
    one 'metal_dark' mesh; the point emitter belongs 2 cm under the head, just under the lens,
    not 2 cm under the foot (inside the sidewalk, 0.13 m up: where it lit the pavement round the
    pole at ~10⁵ lx and leaked as the night frames' fireflies). Fails on the foot."""
    from workbench.scene.city.catalog import VARIANTS
    build, *args = VARIANTS["lamp"][variant]
    asset = build(*args)
    meshes = [Mesh(m.vertices + np.array([20.0, 0.0, 0.15]), m.faces, m.material) for m in asset.meshes()]
    city = _car_city()
    city = City(city.objects + [CityObject("lamp", 9, meshes)], city.materials, 0, city.extent_m)
    (lamp,) = [e for k, e in night_emitters(city, NightParams()).items() if k.startswith("street_lamp")]
    p = np.asarray(lamp["to_world"].translation())
    lens = np.concatenate([m.vertices for m in meshes if m.material == "lens_clear"])
    head = np.concatenate([m.vertices for m in meshes if m.material == "metal_dark"])
    assert lens.min(0)[0] < p[0] < lens.max(0)[0] and lens.min(0)[1] < p[1] < lens.max(0)[1]   # under the lens
    assert lens[:, 2].max() - 0.03 < p[2] < lens[:, 2].min()                                     # just below it
    assert p[2] == pytest.approx(head[head[:, 2] > lens[:, 2].max(), 2].min() - 0.02)           # 2 cm under the head

def test_labels_exact_with_fog_and_glass(mi):
    city = _car_city()
    pose = CameraPose(np.array([0.0, 0.0, 1.5]), pan_deg=0.0, tilt_deg=-3.0, roll_deg=0.0)
    film = box_bands(400, 1000, 2)
    base, ids = build_scene(city, pose, 60.0, 64, 48, film, DaylightParams())
    ref = render_labels(base, ids, 64, 48)
    world = WorldParams(fog=FogParams(visibility_m=100.0, model="volumetric"), glass="dielectric")
    foggy, ids_f = build_scene(city, pose, 60.0, 64, 48, film, DaylightParams(), world=world)
    got = render_labels(foggy, ids_f, 64, 48)
    np.testing.assert_array_equal(got.instance_id, ref.instance_id)
    assert [(o.instance_id, o.bbox_xywh, o.amodal_bbox_xywh) for o in got.objects] == \
        [(o.instance_id, o.bbox_xywh, o.amodal_bbox_xywh) for o in ref.objects]
    assert {o.instance_id for o in ref.objects} == {1, 2, 3}
    np.testing.assert_allclose(got.depth_m, ref.depth_m, rtol=1e-5)
    from workbench.render.spectral import depth_map_m
    np.testing.assert_allclose(depth_map_m(foggy), depth_map_m(base), rtol=1e-5)   # the box is sky


def test_night_emitters_and_render(mi):
    city = _car_city()
    em = night_emitters(city, NightParams())
    heads = sorted(k for k in em if k.startswith("headlight"))
    tails = sorted(k for k in em if k.startswith("taillight"))
    assert len(heads) == 2 and len(tails) == 2 and "sky" in em
    street = City(city.objects + [CityObject("lamp", 9, [_box(20, 0, 0, 20.1, 0.1, 6, "white"),
                                                         _box(19.8, -0.2, 6, 20.4, 0.2, 6.2, "metal_dark"),
                                                         _box(19.8, -0.2, 5.99, 20.4, 0.2, 6.0, "lens_clear")])],
                  {**city.materials, "metal_dark": city.materials["white"]}, 0, city.extent_m)
    em2 = night_emitters(street, NightParams())
    assert sorted(k for k in em2 if k.startswith("headlight")) == heads          # a lamp's lens is no headlight
    parked = City([CityObject(o.class_name, o.instance_id, o.meshes, o.footprint_xy, {**o.meta, "parked": True})
                   if o.class_name == "car" else o for o in city.objects], city.materials, 0, city.extent_m)
    assert not any(k.startswith(("headlight", "taillight")) for k in night_emitters(parked, NightParams()))
    lamp = [v for k, v in em2.items() if k.startswith("street_lamp")]
    assert len(lamp) == 1 and np.allclose(lamp[0]["to_world"].translation(), [20.1, 0.0, 5.98], atol=1e-6)
    # head-lights sit in front of the car's front face (+x), tail-lights behind the rear (−x)
    assert all(np.asarray(em[k]["to_world"].translation())[0] > 12.0 for k in heads)
    assert all(np.asarray(em[k]["to_world"].translation())[0] < 8.0 for k in tails)
    pose = CameraPose(np.array([20.0, 0.0, 1.2]), pan_deg=180.0, tilt_deg=-2.0, roll_deg=0.0)
    from workbench.jobs import run_job
    from workbench.render.params import RenderParams
    from workbench.render.spectral import render_loaded
    film = box_bands(400, 1000, 2)
    scene, _ = build_scene(city, pose, 60.0, 32, 24, film, DaylightParams(),
                           world=WorldParams(lighting="night"))
    out = run_job(render_loaded(scene, film, RenderParams(spp=4, chunk_spp=4), fov_deg=60.0))
    assert np.all(np.isfinite(out.radiance_photons)) and out.radiance_photons.max() > 0


def test_sun_disc_is_dimmed_by_the_fog_in_front_of_it(mi):
    """The composited disc through fog: coverage × e^{−σt}, t the sun ray's path to the layer top."""
    from workbench.render.sun_disc import sun_disc_coverage
    city = City([CityObject("ground", 1, [plane_mesh(200.0, 0.0, "white")])],
                {"white": Material("white", np.array([350.0, 1000.0]), np.array([0.5, 0.5]))},
                seed=0, extent_m=(-200, -200, 200, 200))
    day = DaylightParams(sun_elevation_deg=20.0, sun_azimuth_deg=90.0)
    pose = CameraPose(np.array([0.0, 0.0, 1.5]), pan_deg=0.0, tilt_deg=20.0, roll_deg=0.0)   # yaw 0 = east
    film = box_bands(400, 1000, 2)
    fog = FogParams(visibility_m=500.0, height_m=60.0, model="volumetric")
    clear = sun_disc_coverage(pose, 20.0, 64, 48, day, mi_scene=build_scene(city, pose, 20.0, 64, 48, film, day)[0])
    foggy = sun_disc_coverage(pose, 20.0, 64, 48, day, mi_scene=build_scene(
        city, pose, 20.0, 64, 48, film, day, world=WorldParams(fog=fog))[0])
    assert clear.sum() > 0.5
    t = (60.0 - 1.5) / np.sin(np.radians(20.0))
    assert foggy.sum() / clear.sum() == pytest.approx(np.exp(-extinction_per_m(500.0) * t), rel=1e-3)


def test_exit_distance_and_path_airlight_closed_forms():
    """The layer path of a ray and the in-scattered integral ∫₀^s σe^{−σt} J(z₀ + t d_z) dt against
    closed forms: J constant → J(1 − e^{−σs});
    J = a + b z → a(1−T) + b[z₀(1−T) + d_z(1 − T(1+σs))/σ]."""
    from workbench.render.fog import exit_distance_m, transmittance
    from workbench.render.koschmieder import path_airlight
    lo, hi = np.array([-100.0, -50.0, -1.0]), np.array([100.0, 50.0, 60.0])
    el = np.radians([5.0, 30.0, 90.0])
    dirs = np.stack([np.cos(el), np.zeros(3), np.sin(el)], axis=-1)
    want = np.minimum(100.0 / np.cos(el).clip(1e-12), (60.0 - 1.5) / np.sin(el))
    np.testing.assert_allclose(exit_distance_m([0.0, 0.0, 1.5], dirs, lo, hi), want, rtol=1e-12)
    sigma, z0 = 3.912 / 150.0, 1.5
    s = np.array([[5.0, 40.0, 300.0]])
    dz = np.array([[0.0, 0.2, -0.01]])
    z_m = np.linspace(0.0, 60.0, 8)
    flat = path_airlight(z0, dz, s, sigma, z_m, np.ones((8, 2)) * [2.0, 3.0])
    np.testing.assert_allclose(flat, (1 - transmittance(sigma, s))[..., None] * [2.0, 3.0], rtol=1e-12)
    a, b = 1.0, 0.05
    t = transmittance(sigma, s)
    exact = a * (1 - t) + b * (z0 * (1 - t) + dz * (1 - t * (1 + sigma * s)) / sigma)
    lin = path_airlight(z0, dz, s, sigma, z_m, (a + b * z_m)[:, None])[..., 0]
    np.testing.assert_allclose(lin, exact, rtol=2e-3)          # 16-point quadrature in 1 − e^{−σt}


def test_koschmieder_apply_is_beer_lambert_without_source():
    from workbench.render.koschmieder import KoschmiederFog
    rng = np.random.default_rng(0)
    rad = rng.random((4, 5, 3))
    path = rng.random((4, 5)) * 200.0
    fog = KoschmiederFog(0.02, path, np.zeros((4, 5, 3)), np.zeros(2), np.zeros((2, 3)), np.zeros(2), np.zeros((2, 3)))
    np.testing.assert_allclose(fog.apply(rad), rad * np.exp(-0.02 * path)[..., None], rtol=1e-12)


@pytest.mark.parametrize("albedo", [0.0, 1.0])
def test_source_profile_of_an_empty_layer(mi, albedo):
    """Under a uniform sky over a white ground, a conservative medium (albedo 1) is in equilibrium
    with the sky: J = L_sky at every height and along rising rays (a solution of the transfer
    equation); an absorbing one (albedo 0) scatters nothing: J = 0."""
    from workbench.render.koschmieder import airlight_profile, upward_airlight
    film = box_bands(500, 700, 1)
    sky = {"sky": {"type": "constant", "radiance": {"type": "spectrum", "value": FLAT}}}
    white = {"type": "spectrum", "value": FLAT}
    fog = FogParams(visibility_m=60.0, height_m=20.0, albedo=albedo, phase_g=0.85)
    z, j = airlight_profile(film, fog, sky, white, 30.0, max_depth=256, spp=64)
    from workbench.units import energy_to_photons
    l_sky = np.trapezoid(energy_to_photons(np.ones(201), np.arange(500.0, 701.0)), np.arange(500.0, 701.0)) / 200
    assert z.shape == (j.shape[0],) and np.all(np.diff(z) > 0) and 0 < z[0] and z[-1] < 20.0
    el, up = upward_airlight(film, fog, sky, white, 1.5, 30.0, 20.0, max_depth=256, spp=16)
    assert el.shape == (up.shape[0],) and 0 < el[0] and el[-1] < 20.0
    if albedo == 0.0:
        assert np.all(j == 0.0)
        assert np.abs(up).max() < 0.05 * l_sky                 # fog = T·clear up to the tracker's noise
    else:
        np.testing.assert_allclose(j[:, 0], l_sky, rtol=0.05)
        assert j.mean() == pytest.approx(l_sky, rel=0.02)
        np.testing.assert_allclose(up[:, 0], l_sky, rtol=0.05)


def test_koschmieder_matches_the_volumetric_fog_where_its_assumptions_hold(mi):
    """A small grey board 15 m away in conservative fog under a uniform sky over a white ground (no
    sun): the source function is uniform, so Koschmieder's law is the transfer equation's solution
    and the clear render + KoschmiederFog must equal the volumetric render (within its noise and
    the board's own small shadow on the fog, isotropic scattering: with forward-peaked droplet
    scattering the fog in front of a dark object is lit mostly from behind it, i.e. by it, and
    Koschmieder's airlight there is too bright)."""
    from workbench.jobs import run_job
    from workbench.render.koschmieder import koschmieder_fog
    from workbench.render.params import RenderParams
    from workbench.render.spectral import render_loaded
    wl = np.array([350.0, 1000.0])
    mats = {"white": Material("white", wl, np.array([1.0, 1.0])), "grey": Material("grey", wl, np.array([0.2, 0.2]))}
    city = City([CityObject("ground", 1, [plane_mesh(400.0, 0.0, "white")]),
                 CityObject("building", 2, [_box(15, -1, 0.5, 15.2, 1, 2.5, "grey")])], mats,
                seed=0, extent_m=(-50, -50, 50, 50))
    pose = CameraPose(np.array([0.0, 0.0, 1.5]), pan_deg=0.0, tilt_deg=0.0, roll_deg=0.0)
    day = DaylightParams(sun_scale=0.0)
    fog = FogParams(visibility_m=90.0, height_m=30.0, albedo=1.0, phase_g=0.0)
    film = box_bands(500, 700, 1)
    w, h = 32, 24

    def render(world, spp, depth):
        scene, ids = build_scene(city, pose, 30.0, w, h, film, day, max_depth=depth, world=world)
        out = run_job(render_loaded(scene, film, RenderParams(spp=spp, chunk_spp=spp), fov_deg=30.0))
        return scene, ids, out.radiance_photons[..., 0].astype(np.float64)

    clear, ids, l0 = render(WorldParams(fog=fog), 16, 8)
    labels = render_labels(clear, ids, w, h)
    kf = koschmieder_fog(clear, labels.depth_m, city, pose.pan_deg, film, day, WorldParams(fog=fog),
                         max_depth=64, airlight_spp=64)
    k = kf.apply(l0[..., None])[..., 0]
    _, _, vol = render(WorldParams(fog=fog.updated(model="volumetric")), 256, 64)
    wall = labels.instance_id == 2
    assert wall.sum() > 40 and np.all(labels.depth_m[wall] < 20)
    ground = labels.instance_id == 1
    assert np.ptp(labels.depth_m[ground]) > 10                # the ground spans distances
    for part in (wall, ground):            # model tolerance 4 %: the board shadows the fog before it
        assert k[part].mean() == pytest.approx(vol[part].mean(), rel=0.04)
    assert k.mean() == pytest.approx(vol.mean(), rel=0.04)


def _lamp_row_scene(mi, weights_from_view: bool):
    """A street seen from 1.5 m: ground and a wall, one lamp over the visible road, ten lamps behind
    the wall (they light nothing the camera sees directly)."""
    from workbench.render.lamps import set_view_light_weights
    lamps = {"street_lamp_0": street_lamp_emitter([12.0, 0.0, 6.0], "led")}
    for i in range(1, 6):
        lamps[f"street_lamp_{i}"] = street_lamp_emitter([10.0 * i, 30.0, 6.0], "led")
        lamps[f"street_lamp_{5 + i}"] = street_lamp_emitter([10.0 * i - 5.0, 40.0, 6.0], "led")
    grey = {"type": "diffuse", "reflectance": {"type": "spectrum", "value": [(300.0, 0.3), (1100.0, 0.3)]}}
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 4},
        "sensor": {"type": "perspective", "fov": 50.0, "film": box_bands(450, 650, 1).mitsuba_film(32, 24),
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 1.5], target=[1, 0, 1.0], up=[0, 0, 1]),
                   "sampler": {"type": "independent"}},
        **lamps,
        "ground": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(200.0), "bsdf": grey},
        "wall": {"type": "rectangle", "bsdf": grey,
                 "to_world": mi.ScalarTransform4f().translate([20.0, 20.0, 10.0])
                 @ mi.ScalarTransform4f().rotate([1, 0, 0], 90.0) @ mi.ScalarTransform4f().scale([200.0, 10.0, 1.0])}})
    weights = set_view_light_weights(scene, lamps) if weights_from_view else None
    return scene, weights


def test_view_light_weights_favour_the_lamp_lighting_the_view(mi):
    from workbench.render.lamps import DEFENSIVE_SHARE
    _, w = _lamp_row_scene(mi, True)
    total = sum(w.values())
    assert w["street_lamp_0"] / total == pytest.approx(1 - DEFENSIVE_SHARE + DEFENSIVE_SHARE / 11, rel=1e-6)
    for k in (f"street_lamp_{i}" for i in range(1, 11)):          # no direct light on the view
        assert w[k] / total == pytest.approx(DEFENSIVE_SHARE / 11, rel=1e-6)


def test_view_light_weights_keep_the_image_and_cut_its_noise(mi):
    """Same expected image with flux and view weights (within 4 standard errors), less noise."""
    def two(scene):
        return [np.array(mi.render(scene, spp=32, seed=s), dtype=np.float64)[..., 0] for s in (1, 2)]
    stats = {}
    for view in (False, True):
        a, b = two(_lamp_row_scene(mi, view)[0])
        var = np.mean((a - b) ** 2) / 2                       # per-pixel variance of one render
        stats[view] = (0.5 * (a.mean() + b.mean()), np.sqrt(var / (2 * a.size)), np.sqrt(var) / a.mean())
    (m0, se0, n0), (m1, se1, n1) = stats[False], stats[True]
    assert abs(m1 - m0) < 4 * np.hypot(se0, se1), (m0, m1, se0, se1)
    assert n1 < 0.5 * n0, (n0, n1)
