"""Portal guiding (render/portal_guide.py): inside a tunnel by day the light comes in through the
two open ends, which a cosine-weighted bounce finds rarely; the wrapped BSDF sends half its samples
toward them.

Oracle: a floor inside a tunnel with black walls and roof under a uniform sky L. Its irradiance
is L times the projected solid angle of the two portals (Lambert's polygon formula, computed here
independently), so its radiance is ρ L PSA / π, against the radiance L of the sky itself seen
through the same film. Claims checked: that value (2 % at 256 samples on each of 256 pixels),
the unguided BSDF's estimate agreeing within its own noise, and a per-estimate variance ≥ 15×
lower at equal samples (measured 2026-11-27: 31×, the guided mean 0.4 % from the formula; 25×
since a share aims past the sky-lit mouths, 2026-11-28); the sampling density that `pdf` reports is the one `sample` draws from (E[1/p] = 2π over the
hemisphere, and pdf(ω) = the sample's pdf); a BSDF with a delta lobe keeps its expected value;
scenes without a tunnel, and night scenes, are not wrapped; with the sun shining into a portal the
guide aims past the sunlit mouth (tunnel_portals' insets) and finds its light; a share aimed past
the sky-lit mouth finds the light the floor near the portals sends deep inside; without Russian
roulette (a tunnel city's integrator by day) the deep bounces that reach the sky through a portal
are no longer boosted: same mean, the heaviest estimates about half as heavy."""
import numpy as np
import pytest

from workbench.render.film import box_bands

BOX = ((-5.0, -30.0, 0.0), (5.0, 30.0, 6.0))      # x across, y along, z up (m)
Y_FLOOR = 10.0                                     # the floor point: 40 m and 20 m from the portals


def _polygon_psa(p, poly, n):
    """Projected solid angle (sr) of a planar polygon above the horizon of normal n at p
    (Lambert: ½ Σ θ_i n·(v_i × v_{i+1})/|v_i × v_{i+1}|, v_i unit vectors to the corners)."""
    v = [(q - p) / np.linalg.norm(q - p) for q in poly]
    total = 0.0
    for a, b in zip(v, v[1:] + v[:1]):
        c = np.cross(a, b)
        total += np.arccos(np.clip(a @ b, -1, 1)) * (n @ c) / np.linalg.norm(c)
    return abs(total) / 2


def _portal_psa(p):
    (x0, y0, z0), (x1, y1, z1) = BOX
    return sum(_polygon_psa(p, [np.array(c, dtype=float) for c in
                                ((x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1))], np.array([0.0, 0.0, 1.0]))
               for y in (y0, y1))


def _scene(mi, guided: bool, floor_bsdf=None, look_up=False, res=16, roof_view=False, mouth_m=None, integrator=None):
    """roof_view: the roof is the floor's (guided) grey too and the camera sees it from below at
    Y_FLOOR, lit by the floor near the portals (one bounce more)."""
    from workbench.render.portal_guide import portal_guided
    (x0, y0, z0), (x1, y1, z1) = BOX
    black = mi.load_dict({"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.0}})
    floor = floor_bsdf or mi.load_dict({"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.5}})
    if guided:
        floor = portal_guided(floor, BOX, mouth_m=mouth_m)
    t = mi.ScalarTransform4f()
    cube = lambda c, h: t.translate(c) @ t.scale(h)   # noqa: E731
    y = 100.0 if look_up else Y_FLOOR                 # the sky: from outside the tunnel, looking up
    target = [0.0, y, 10.0] if look_up else [0.0, y, z1 if roof_view else 0.0]
    return mi.load_dict({
        "type": "scene", "integrator": integrator or {"type": "path", "max_depth": 4 if roof_view else 3},
        "sky": {"type": "constant", "radiance": {"type": "spectrum", "value": 1.0}},
        "floor": {"type": "rectangle", "bsdf": floor,
                  "to_world": t.translate([0.0, 0.0, z0]) @ t.scale([(x1 - x0) / 2, (y1 - y0) / 2, 1.0])},
        "west": {"type": "cube", "bsdf": black, "to_world": cube([x0 - 0.5, 0.0, 3.0], [0.5, (y1 - y0) / 2, 3.6])},
        "east": {"type": "cube", "bsdf": black, "to_world": cube([x1 + 0.5, 0.0, 3.0], [0.5, (y1 - y0) / 2, 3.6])},
        "roof": {"type": "cube", "bsdf": floor if roof_view else black,
                 "to_world": cube([0.0, 0.0, z1 + 0.5], [x1 + 1, (y1 - y0) / 2, 0.5])},
        "sensor": {"type": "perspective", "fov": 0.5, "film": box_bands(450, 650, 1).mitsuba_film(res, res),
                   "to_world": t.look_at(origin=[0.0, y, 1.0], target=target, up=[0, 1, 0]),
                   "sampler": {"type": "independent"}}})


def _render(mi, scene, spp, seed=0):
    return np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)[..., 0]


def test_floor_radiance_matches_lamberts_formula(mi):
    """Guided estimate of ρ L PSA / π within 2 %; unguided within its noise (4 standard errors)."""
    sky = _render(mi, _scene(mi, False, look_up=True, res=2), 4).mean()       # L through the film
    expect = 0.5 * sky * _portal_psa(np.array([0.0, Y_FLOOR, 0.0])) / np.pi
    guided = _render(mi, _scene(mi, True), 256)                               # 16×16 px × 256 = 65k samples
    print(f"guided {guided.mean():.5f}, Lambert {expect:.5f}")
    assert guided.mean() == pytest.approx(expect, rel=0.02), (guided.mean(), expect)
    plain = _render(mi, _scene(mi, False), 256)
    se = plain.std() / np.sqrt(plain.size)
    assert abs(plain.mean() - expect) < 4 * se + 0.02 * expect, (plain.mean(), expect, se)


def test_guiding_cuts_the_variance_at_equal_samples(mi):
    var = {g: _render(mi, _scene(mi, g), 16).var() for g in (False, True)}   # 256 estimates of 16 samples
    ratio = var[False] / var[True]
    print(f"variance unguided / guided = {ratio:.1f}")
    assert ratio > 15, f"variance unguided / guided = {ratio:.1f}"


def _bsdf_samples(mi, guided_bsdf, p, n_samples=200_000):
    """(sampled BSDFSample, weight, pdf re-evaluated for its direction) at point p, normal +z,
    viewed from straight above."""
    import drjit as dr
    si = dr.zeros(mi.SurfaceInteraction3f, n_samples)
    si.p = mi.Point3f(*p)
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(si.n)
    si.wi = mi.Vector3f(0, 0, 1)
    si.wavelengths = mi.Spectrum(550.0)
    rng = np.random.default_rng(1)
    ctx = mi.BSDFContext()
    u1 = mi.Float(rng.random(n_samples))
    u2 = mi.Point2f(rng.random(n_samples), rng.random(n_samples))
    bs, w = guided_bsdf.sample(ctx, si, u1, u2)
    pdf = guided_bsdf.pdf(ctx, si, bs.wo)
    return bs, w, pdf


def test_reported_pdf_is_the_sampling_density(mi):
    from workbench.render.portal_guide import portal_guided
    diffuse = mi.load_dict({"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.5}})
    bs, w, pdf = _bsdf_samples(mi, portal_guided(diffuse, BOX), [0.0, Y_FLOOR, 0.0])
    bs_pdf, pdf = np.array(bs.pdf), np.array(pdf)
    ok = bs_pdf > 0
    assert ok.mean() > 0.999
    np.testing.assert_allclose(pdf[ok], bs_pdf[ok], rtol=1e-4)
    # E[1/p] over the directions drawn = the measure of the support: the upper hemisphere, 2π
    assert np.mean(1 / bs_pdf[ok]) * ok.mean() == pytest.approx(2 * np.pi, rel=0.02)
    # E[weight] = the albedo (∫ f cos dω)
    assert float(np.mean(np.array(w[0]))) == pytest.approx(0.5, rel=0.01)


def test_delta_lobes_keep_their_expected_value(mi):
    """A smooth coat (a delta reflection over a diffuse base) guided and not: same mean."""
    coat = mi.load_dict({"type": "plastic", "diffuse_reflectance": {"type": "spectrum", "value": 0.5}})
    means = []
    for guided in (False, True):
        a = np.stack([_render(mi, _scene(mi, guided, floor_bsdf=coat), 64, seed=s) for s in range(4)])
        means.append((a.mean(), a.std() / np.sqrt(a.size)))
    (m0, s0), (m1, s1) = means
    assert abs(m0 - m1) < 4 * np.hypot(s0, s1) + 0.01 * m1, means


def test_only_tunnel_surfaces_by_day_are_guided(mi):
    from workbench.render.portal_guide import guide_toward_portals, unguided
    diffuse = mi.load_dict({"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.5}})
    pane = mi.load_dict({"type": "thindielectric"})
    assert guide_toward_portals(diffuse, []) is diffuse                  # no tunnel
    assert guide_toward_portals(pane, [(BOX, (0.0, 0.0))]) is pane                     # nothing to aim
    assert guide_toward_portals(diffuse, [(BOX, (0.0, 0.0))]) is not diffuse
    with unguided():
        assert guide_toward_portals(diffuse, [(BOX, (0.0, 0.0))]) is diffuse


def test_bad_box_is_refused(mi):
    from workbench.errors import InvalidValueError
    from workbench.render.portal_guide import portal_guided
    diffuse = mi.load_dict({"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.5}})
    with pytest.raises(InvalidValueError, match="min < max"):
        portal_guided(diffuse, ((0, 0, 0), (1, -1, 1)))
    with pytest.raises(InvalidValueError, match="mouth's depth"):
        portal_guided(diffuse, BOX, mouth_m=40.0)


def _sunlit_mouth_scene(mi, insets):
    """The tunnel with grey walls and floor, no sky, and a sun at 45° shining in through the
    north portal: the only light inside is the sunlit floor and walls of its mouth (6 m deep).
    The camera sees a point of the west wall 20 m further in."""
    from workbench.render.portal_guide import portal_guided
    (x0, y0, z0), (x1, y1, z1) = BOX
    grey = portal_guided(mi.load_dict({"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.5}}),
                         BOX, insets, mouth_m=0.0)
    t = mi.ScalarTransform4f()
    cube = lambda c, h: t.translate(c) @ t.scale(h)   # noqa: E731
    return mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 4},
        "sun": {"type": "directional", "direction": [0.0, -1.0, -1.0],
                "irradiance": {"type": "spectrum", "value": 1.0}},
        "floor": {"type": "rectangle", "bsdf": grey,
                  "to_world": t.translate([0.0, 0.0, z0]) @ t.scale([(x1 - x0) / 2, (y1 - y0) / 2, 1.0])},
        "west": {"type": "cube", "bsdf": grey, "to_world": cube([x0 - 0.5, 0.0, 3.0], [0.5, (y1 - y0) / 2, 3.6])},
        "east": {"type": "cube", "bsdf": grey, "to_world": cube([x1 + 0.5, 0.0, 3.0], [0.5, (y1 - y0) / 2, 3.6])},
        "roof": {"type": "cube", "bsdf": grey, "to_world": cube([0.0, 0.0, z1 + 0.5], [x1 + 1, (y1 - y0) / 2, 0.5])},
        "sensor": {"type": "perspective", "fov": 0.5, "film": box_bands(450, 650, 1).mitsuba_film(16, 16),
                   "to_world": t.look_at(origin=[0.0, Y_FLOOR, 3.0], target=[x0, Y_FLOOR, 3.0], up=[0, 0, 1]),
                   "sampler": {"type": "independent"}}})


def test_aiming_past_the_sunlit_mouth_finds_its_light(mi):
    """Inset by the sun's depth (tunnel_portals: 6 m × |s_y| / s_z = 6 m) the guide's target
    cross-section has the sunlit mouth behind it; at the portal itself it misses the mouth's
    floor, which then only cosine samples find. Same mean, variance ≥ 3× lower (measured
    2026-11-27: 15.6×)."""
    stats = {}
    for insets in ((0.0, 0.0), (0.0, 6.0)):
        a = np.stack([_render(mi, _sunlit_mouth_scene(mi, insets), 16, seed=s) for s in range(4)])
        stats[insets] = (a.mean(), a.std() / np.sqrt(a.size), a.var())
    (m0, s0, v0), (m1, s1, v1) = stats[(0.0, 0.0)], stats[(0.0, 6.0)]
    assert abs(m0 - m1) < 4 * np.hypot(s0, s1), (m0, s0, m1, s1)
    assert v0 > 3 * v1, f"variance portal / inset = {v0 / v1:.1f}"
    print(f"variance portal / inset = {v0 / v1:.1f}; means {m0:.4g} ± {s0:.2g}, {m1:.4g} ± {s1:.2g}")


def test_aiming_past_the_skylit_mouth_finds_its_light(mi):
    """Under a uniform sky, grey floor and roof, black walls: deep in the tunnel the roof's light
    comes through the portals and off the floor of their sky-lit mouths, which the portal target misses; a share β aimed at the cross-sections
    MOUTH_DEPTH_HEIGHTS deep finds them. Same mean; the heaviest estimates (the top 1 % of
    256 × 4 estimates of 16 samples) carry a smaller share of the light, and the variance is lower
    (measured 2026-11-28: variance 1.41× lower, top 1 % share 0.042 → 0.033)."""
    stats = {}
    for mouth in (0.0, None):
        a = np.stack([_render(mi, _scene(mi, True, roof_view=True, mouth_m=mouth), 16, seed=s) for s in range(4)]).ravel()
        top = np.sort(a)[::-1][:a.size // 100].sum() / a.sum()
        stats[mouth] = (a.mean(), a.std() / np.sqrt(a.size), a.var(), top)
    (m0, s0, v0, t0), (m1, s1, v1, t1) = stats[0.0], stats[None]
    print(f"variance portal / mouth = {v0 / v1:.2f}; top 1 % share {t0:.3f} -> {t1:.3f}; "
          f"means {m0:.4g} ± {s0:.2g}, {m1:.4g} ± {s1:.2g}")
    assert abs(m0 - m1) < 4 * np.hypot(s0, s1), (m0, s0, m1, s1)
    assert v0 > 1.2 * v1 and t1 < 0.9 * t0, (v0 / v1, t0, t1)


def test_mouth_target_per_portal(mi):
    """A sun deeper in at one portal than the sky-lit mouth still leaves the other portal its
    mouth target (the plans: sunlit depth or portal, then the mouth's depth with share β)."""
    from workbench.render.portal_guide import MOUTH_SHARE, portal_guided
    diffuse = mi.load_dict({"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.5}})
    mouth = 18.0                                     # 3 heights of BOX, under a third of its 60 m
    assert portal_guided(diffuse, BOX, (19.0, 0.0)).plans == [(19.0, 0.0, pytest.approx(1 - MOUTH_SHARE)),
                                                              (19.0, mouth, MOUTH_SHARE)]
    assert portal_guided(diffuse, BOX, (19.0, 19.0)).plans == [(19.0, 19.0, 1.0)]   # both deeper already
    assert portal_guided(diffuse, BOX, mouth_m=0.0).plans == [(0.0, 0.0, 1.0)]


def test_tunnel_portals_inset_by_the_suns_depth():
    from types import SimpleNamespace

    from workbench.render.params import DaylightParams
    from workbench.render.portal_guide import tunnel_portals
    from workbench.scene.city.tunnel import TunnelFrame
    frame = TunnelFrame(0.0, -75.0, 75.0, 5.5, 0.0, 5.0)
    city = SimpleNamespace(objects=[SimpleNamespace(class_name="tunnel", meta={"frame": frame}),
                                    SimpleNamespace(class_name="car", meta={})])
    (box, insets), = tunnel_portals(city, DaylightParams(sun_elevation_deg=45.0, sun_azimuth_deg=180.0))
    assert box == ((-5.5, -75.0, 0.0), (5.5, 75.0, 5.0))
    assert insets == pytest.approx((5.0, 0.0))          # a southern sun shines in through the south portal
    (_, insets), = tunnel_portals(city, DaylightParams(sun_elevation_deg=30.0, sun_azimuth_deg=90.0))
    assert insets == pytest.approx((0.0, 0.0), abs=1e-9)   # an eastern sun runs across the tunnel
    (_, insets), = tunnel_portals(city, DaylightParams(sky_model="overcast"))
    assert insets == (0.0, 0.0)


def test_without_russian_roulette_deep_bounces_to_the_sky_are_not_boosted(mi):
    """Grey floor and roof under a uniform sky, 6 path vertices: Mitsuba's roulette from depth 5
    multiplies a dim survivor by 1/q, and its next guided bounce reaches the sky, 10²× brighter
    than the interior (the tunnel's white dots, portal_guide.roulette_depth). With rr_depth =
    max_depth: same mean, lower variance, and the heaviest estimate of 16 samples about half as
    far above the mean (measured 2026-11-28 on five seed sets: max/mean 10.0–11.1 → 4.5–5.5,
    variance 1.17–1.38× lower)."""
    stats = {}
    for rr in (5, 6):
        integrator = {"type": "path", "max_depth": 6, "rr_depth": rr}
        a = np.stack([_render(mi, _scene(mi, True, roof_view=True, integrator=integrator), 16, seed=s)
                      for s in range(16)]).ravel()
        stats[rr] = (a.mean(), a.std() / np.sqrt(a.size), a.var(), a.max() / a.mean())
    (m5, s5, v5, x5), (m6, s6, v6, x6) = stats[5], stats[6]
    print(f"roulette on / off: variance {v5 / v6:.2f}, max/mean {x5:.1f} -> {x6:.1f}; means {m5:.4g}, {m6:.4g}")
    assert abs(m5 - m6) < 4 * np.hypot(s5, s6), (m5, s5, m6, s6)
    assert v6 < v5 and x6 < 0.7 * x5, (v5, v6, x5, x6)


def test_a_tunnel_city_by_day_renders_without_russian_roulette(mi):
    from workbench.render.params import DaylightParams, WorldParams
    from workbench.render.portal_guide import MITSUBA_RR_DEPTH, roulette_depth
    from workbench.render.scene_builder import build_scene
    from workbench.scene.city import CameraPose, CityRecipe, TunnelParams, generate_city
    assert roulette_depth([], 6) == MITSUBA_RR_DEPTH and roulette_depth([(BOX, (0.0, 0.0))], 6) == 6
    recipe = CityRecipe(seed=1, block_size_m=120.0, n_cars=0, n_pedestrians=0, n_buses=0, n_trucks=0, n_trees=0,
                        n_lamps=0, n_benches=0, n_mailboxes=0, tunnel=TunnelParams(street_index=1, length_m=100.0))
    cities = {True: generate_city(recipe), False: generate_city(recipe.updated(tunnel=None))}
    frame = cities[True].objects[-1].meta["frame"]
    pose = CameraPose(np.array([frame.x_m, frame.y_north_m - 40.0, 1.5]), pan_deg=90.0, tilt_deg=0.0, roll_deg=0.0)
    film = box_bands(450.0, 650.0, 1)
    for tunnel, night, rr in ((True, False, 7), (True, True, MITSUBA_RR_DEPTH), (False, False, MITSUBA_RR_DEPTH)):
        world = WorldParams(lighting="night" if night else "day")
        scene, _ = build_scene(cities[tunnel], pose, 40.0, 8, 6, film, DaylightParams(), max_depth=7, world=world)
        assert f"rr_depth = {rr}" in str(scene.integrator()), (tunnel, night, str(scene.integrator()))
