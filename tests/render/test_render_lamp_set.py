"""Night light selection per shading point (render/lamp_set.py, NightParams.light_selection
'shading'): the fireflies of night frames are one-bounce indirect light from surfaces lit by a
lamp whose global (flux or per-view) share of next-event samples is small.

Scene: a wall seen above the height of the lamp next to it (a full cut-off lamp does not light
it: the wall is lit only by the ground under the lamp), and 15 far lamps. With per-emitter
selection the near lamp gets 1/16 of the samples by flux, 0.1/16 by view; the lamp set gives it
nearly all of them at the ground under it. Claims checked: the same expected image (4 standard
errors) and a per-pixel variance at least 10× lower than flux and 30× lower than view
selection (measured 2026-11-27 at 64 spp: 22× and 106× scoring every lamp, 20× and 97× with the
candidate grid); day scenes never build the set, and the day data sets keep their fingerprint.

The candidate grid (issue 33: scoring all ~250 lights of a dense night city at every sample made
a night sample 2.7× a day sample): with 200 lamps in a city-sized layout, the set's next-event
value at shading points averages to the sum of Mitsuba's own `spot` emitters' values (every lamp
keeps a positive probability: unbiased), and the sampler's kernel has the same operation count
for 20 lamps as for 200."""
import numpy as np
import pytest

from workbench.render.film import box_bands
from workbench.render.lamps import LAMP_SET_ID, headlight_emitter, night_emitters, spot_emitter, street_lamp_emitter


def _scene(mi, selection: str):
    from workbench.render.lamp_set import lamp_set_emitter
    from workbench.render.lamps import set_view_light_weights
    lamps = {"street_lamp_0": street_lamp_emitter([17.0, 0.0, 6.0], "hps")}
    for i in range(1, 16):
        lamps[f"street_lamp_{i}"] = street_lamp_emitter([-60.0 + 8.0 * i, 80.0 * (-1) ** i, 6.0], "led")
    lamps["headlight_0"] = spot_emitter([-40.0, 10.0, 0.7], [1.0, 0.0, -0.03], "led", 20000.0, 30.0, 10.0)
    emitters = {"lamps": lamp_set_emitter(lamps)} if selection == "shading" else lamps
    grey = {"type": "diffuse", "reflectance": {"type": "spectrum", "value": [(300.0, 0.5), (1100.0, 0.5)]}}
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 3},
        "sensor": {"type": "perspective", "fov": 30.0, "film": box_bands(450, 650, 1).mitsuba_film(24, 16),
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 1.5], target=[20, 0, 13.0], up=[0, 0, 1]),
                   "sampler": {"type": "independent"}},
        **emitters,
        "ground": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(300.0), "bsdf": grey},
        "wall": {"type": "rectangle", "bsdf": grey,
                 "to_world": mi.ScalarTransform4f().translate([20.0, 0.0, 10.0])
                 @ mi.ScalarTransform4f().rotate([0, 1, 0], -90.0) @ mi.ScalarTransform4f().scale([10.0, 40.0, 1.0])}})
    if selection == "view":
        set_view_light_weights(scene, lamps)
    return scene


def _stats(mi, scene, spp=64):
    a, b = (np.array(mi.render(scene, spp=spp, seed=s), dtype=np.float64)[..., 0] for s in (1, 2))
    var = np.mean((a - b) ** 2) / 2                      # per-pixel variance of one render
    return 0.5 * (a.mean() + b.mean()), np.sqrt(var / (2 * a.size)), var


def test_lamp_set_keeps_the_image_and_cuts_the_variance(mi):
    stats = {sel: _stats(mi, _scene(mi, sel)) for sel in ("flux", "view", "shading")}
    m_s, se_s, v_s = stats["shading"]
    for sel in ("flux", "view"):
        m, se, v = stats[sel]
        assert abs(m - m_s) < 4 * np.hypot(se, se_s), (sel, m, m_s, se, se_s)
    assert stats["flux"][2] > 10 * v_s, f"variance flux/shading = {stats['flux'][2] / v_s:.1f}"
    assert stats["view"][2] > 30 * v_s, f"variance view/shading = {stats['view'][2] / v_s:.1f}"


def test_lamp_set_matches_a_lone_spot_at_its_falloff(mi):
    """Inside the beam, in the falloff ring and outside the cut-off, the set's one lamp gives what
    Mitsuba's `spot` gives (within 4 standard errors; direct light only)."""
    spot = spot_emitter([0.0, 0.0, 3.0], [0.0, 0.0, -1.0], "led", 5000.0, 30.0, 10.0)
    from workbench.render.lamp_set import lamp_set_emitter
    grey = {"type": "diffuse", "reflectance": {"type": "spectrum", "value": [(300.0, 0.5), (1100.0, 0.5)]}}
    out = {}
    for name, em in (("spot", spot), ("set", lamp_set_emitter({"s": spot}))):
        scene = mi.load_dict({
            "type": "scene", "integrator": {"type": "path", "max_depth": 2},
            "sensor": {"type": "orthographic", "film": box_bands(450, 650, 1).mitsuba_film(32, 1),
                       "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 1.0], target=[0, 0, 0], up=[0, 1, 0])
                       @ mi.ScalarTransform4f().scale([2.5, 2.5, 1.0]), "sampler": {"type": "independent"}},
            "lamp": em, "ground": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(10.0), "bsdf": grey}})
        out[name] = np.array(mi.render(scene, spp=16, seed=3), dtype=np.float64)[0, :, 0]
    ring = out["spot"] > 0
    assert ring.sum() > 8 and (~ring).sum() > 4                      # lit and unlit pixels both tested
    np.testing.assert_allclose(out["set"], out["spot"], rtol=2e-4, atol=0)


def test_night_emitters_make_one_set_only_when_asked(mi, monkeypatch):
    from workbench.render.params import NightParams
    from workbench.scene.city.generate import generate_city
    from workbench.scene.city.recipe import CityRecipe
    city = generate_city(CityRecipe(n_cars=2, n_pedestrians=0, n_buses=0, n_trucks=0, n_lamps=4))
    view = night_emitters(city, NightParams())
    shading = night_emitters(city, NightParams(light_selection="shading"))
    assert LAMP_SET_ID not in view and sum(e["type"] == "spot" for e in view.values()) >= 4
    assert set(shading) == {LAMP_SET_ID, "sky"}
    spots = sum(e["sampling_weight"] for e in view.values() if e["type"] == "spot")
    assert shading[LAMP_SET_ID]["sampling_weight"] == pytest.approx(spots)
    assert shading["sky"] == view["sky"]


def test_day_projects_keep_their_data_set_fingerprint():
    """The committed standard results were made with this fingerprint: the new option leaves it."""
    import json
    from pathlib import Path
    from workbench.datasets.dataset import dataset_fingerprint
    from workbench.project import load_project
    from workbench.render.city_frame import render_city_frame
    committed = json.loads((Path(__file__).parents[2] / "docs/results/render-noise-standard.json").read_text())
    project = load_project("city_detection_quick")
    assert dataset_fingerprint(project, "float16", render_city_frame) == committed["fingerprint"]


def _city_lamps(n: int, seed: int) -> dict:
    """n street lamps, cone spots and low-beam head-lights (a projection texture) spread over a 200 m square."""
    rng = np.random.default_rng(seed)
    lamps = {}
    for i in range(n):
        x, y = rng.uniform(-100.0, 100.0, 2)
        a = rng.uniform(0, 2 * np.pi)
        if i % 4 == 0:
            lamps[f"street_lamp_{i}"] = street_lamp_emitter([x, y, 6.0], "hps")
        elif i % 4 == 1:
            lamps[f"headlight_{i}"] = headlight_emitter([x, y, 0.7], [np.cos(a), np.sin(a), 0.0], "led", 20000.0)
        else:
            lamps[f"headlight_{i}"] = spot_emitter([x, y, 0.7], [np.cos(a), np.sin(a), -0.03], "led", 20000.0, 30.0, 10.0)
    return lamps


def test_a_low_beam_in_the_set_gives_what_mitsuba_s_textured_spot_gives(mi):
    """One head-light (render/low_beam.py's pattern as the spot's projection texture) alone in a set: its
    probability is 1, so at every point — the hot spot, the foreground, above the cut-off, beside and
    behind — the set's value is the spot's own."""
    from workbench.render.lamp_set import lamp_set_emitter
    head = headlight_emitter([0.0, 0.0, 0.65], [0.0, 1.0, 0.0], "led", 20000.0)
    points = [[0.9, 25.0, 0.0], [0.0, 2.0, 0.0], [-3.0, 8.0, 0.0], [0.0, 30.0, 0.4], [-0.5, 30.0, 0.65],
              [0.0, 20.0, 3.0], [15.0, 10.0, 0.0], [0.0, -5.0, 0.0]]
    it, u = _receivers(mi, points, 1, 21)
    it.n = it.sh_frame.n = mi.Normal3f(0.0, -1.0, 0.0)
    got = np.array(mi.load_dict({"type": "scene", "l": lamp_set_emitter({"h": head})}).emitters()[0]
                   .sample_direction(it, u)[1], dtype=np.float64)[0]
    want = np.array(mi.load_dict({"type": "scene", "l": head}).emitters()[0].sample_direction(it, u)[1],
                    dtype=np.float64)[0]
    assert (want[:-1] > 0).all() and want[-1] == 0 and want.max() > 100 * want[want > 0].min()
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=0)


def _receivers(mi, points, copies: int, seed: int):
    """Each point (normal +z) `copies` times at 550 nm, and uniform 2-D samples."""
    import drjit as dr
    p = np.repeat(np.asarray(points, np.float32), copies, axis=0)
    it = dr.zeros(mi.SurfaceInteraction3f, len(p))
    it.p = mi.Point3f(*(mi.Float(c) for c in p.T))
    it.n = it.sh_frame.n = mi.Normal3f(0.0, 0.0, 1.0)
    it.wavelengths = mi.UnpolarizedSpectrum(550.0)
    u = np.random.default_rng(seed).random((2, len(p))).astype(np.float32)
    return it, mi.Point2f(mi.Float(u[0]), mi.Float(u[1]))


def test_the_candidate_grid_keeps_every_lamp_s_light(mi):
    from workbench.render.lamp_set import lamp_set_emitter
    lamps = _city_lamps(200, 5)
    points = [[x, y, 0.0] for x, y in np.random.default_rng(6).uniform(-110.0, 110.0, (24, 2))]
    copies = 1 << 14
    it, u = _receivers(mi, points, copies, 7)
    scene = mi.load_dict({"type": "scene", "lamps": lamp_set_emitter(lamps)})
    _, value = scene.emitters()[0].sample_direction(it, u)
    got = np.array(value, dtype=np.float64)[0].reshape(len(points), copies)
    want = np.zeros(len(points))
    one, _ = _receivers(mi, points, 1, 8)
    for em in lamps.values():                              # Mitsuba's own spots, one at a time
        spot = mi.load_dict({"type": "scene", "s": em}).emitters()[0]
        want += np.array(spot.sample_direction(one, mi.Point2f(0.5, 0.5))[1], dtype=np.float64)[0]
    sem = got.std(1) / np.sqrt(copies)
    assert np.all(np.abs(got.mean(1) - want) < 4 * sem + 1e-3 * want), (got.mean(1), want, sem)


def test_the_set_s_sampler_costs_the_same_for_20_and_200_lamps(mi):
    import drjit as dr
    from workbench.render.lamp_set import lamp_set_emitter
    counts = []
    was = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        for n in (20, 200):
            emitter = mi.load_dict({"type": "scene", "lamps": lamp_set_emitter(_city_lamps(n, 9))}).emitters()[0]
            it, u = _receivers(mi, [[1.0, 2.0, 0.0]], 1024, 3)
            dr.eval(it, u)
            dr.kernel_history()
            ds, value = emitter.sample_direction(it, u)
            dr.eval(ds, value)
            counts.append(sum(k["operation_count"] for k in dr.kernel_history() if "operation_count" in k))
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, was)
    assert counts[0] > 0 and abs(counts[0] - counts[1]) <= 0.01 * counts[0], counts   # literals may fold differently


def test_a_head_light_lights_the_cell_it_stands_in_ahead_of_the_cells_centre(mi):
    """The grid's cone test (issue 33's remaining night fireflies): a head-light 1 m ahead of its cell's
    centre, aimed away from it, lights the road 2.5 m ahead, inside the same cell. The cell's angular
    radius seen from a lamp inside it is every direction; taken as at most 90° (arctan), the head-light
    was no candidate of its own cell, was picked at that road point only by the 5 % flux share, and the
    point's next-event value had a relative standard deviation of 15 per sample (0.24 with the lamp
    a candidate; measured 2026-11-28)."""
    from workbench.render.lamp_set import CELL_M, GRID_MARGIN_M, lamp_set_emitter
    assert (GRID_MARGIN_M / CELL_M).is_integer()                 # cells edge at multiples of CELL_M here
    lamps = {f"street_lamp_{i}": street_lamp_emitter(p, "hps") for i, p in
             enumerate([[0.0, 0.0, 8.0], [30.0, 10.0, 8.0], [10.0, 30.0, 8.0], [40.0, 40.0, 8.0]])}
    for i in range(12):                                          # other cars' head-lights
        a = 2 * np.pi * i / 12
        lamps[f"headlight_{i + 1}"] = spot_emitter([20.0 + 12 * np.cos(a), 20.0 + 12 * np.sin(a), 0.65],
                                                   [np.cos(a), np.sin(a), -0.03], "led", 20000.0, 30.0, 10.0)
    lamps["headlight_0"] = spot_emitter([13.0, 4.0, 0.65], [1.0, 0.0, -0.03], "led", 20000.0, 30.0, 10.0)
    receiver = [15.5, 4.0, 0.0]                    # cell [8, 16] × [0, 8]: its centre (12, 4) is behind the lamp
    copies = 1 << 14
    it, u = _receivers(mi, [receiver], copies, 11)
    scene = mi.load_dict({"type": "scene", "lamps": lamp_set_emitter(lamps)})
    got = np.array(scene.emitters()[0].sample_direction(it, u)[1], dtype=np.float64)[0]
    one, _ = _receivers(mi, [receiver], 1, 12)
    want = sum(float(np.array(mi.load_dict({"type": "scene", "s": em}).emitters()[0]
                              .sample_direction(one, mi.Point2f(0.5, 0.5))[1], dtype=np.float64)[0, 0])
               for em in lamps.values())
    head = float(np.array(mi.load_dict({"type": "scene", "s": lamps["headlight_0"]}).emitters()[0]
                          .sample_direction(one, mi.Point2f(0.5, 0.5))[1], dtype=np.float64)[0, 0])
    assert head > 0.5 * want                                     # the head-light is the point's main light
    sem = got.std() / np.sqrt(copies)
    assert abs(got.mean() - want) < 4 * sem + 1e-3 * want, (got.mean(), want, sem)
    assert got.std() / want < 0.5, got.std() / want


def test_a_dim_lamp_that_alone_lights_a_point_is_found_there(mi):
    """The global share's table (issue 33's remaining night fireflies, on dark facades): behind a queue of
    20 head-lights that fill a cell's candidates but light only what lies ahead, a façade point is lit by
    one tail-light alone (10 cd). By flux the table gave the tail-light 9e-5 of its samples (none of
    16,384 found it); with half the table spread evenly over the lamps 0.024, and the relative standard
    deviation per sample is 6.4 (measured 2026-11-28)."""
    from workbench.render.lamp_set import UNIFORM_SHARE, global_table, lamp_set_emitter
    lamps = {f"headlight_{i}": spot_emitter([12.0 + 0.3 * (i % 10), 2.0 + 0.4 * (i // 10), 0.65], [1.0, 0.0, -0.03],
                                            "led", 20000.0, 30.0, 10.0) for i in range(20)}
    lamps["taillight_0"] = spot_emitter([0.0, 0.0, 0.9], [1.0, 0.0, 0.0], "led", 10.0, 60.0, 20.0)   # white: 550 nm
    receiver = [9.0, 4.0, 6.0]          # in the head-lights' cell, behind them, 6 m up: in the tail-light's cone
    copies = 1 << 14
    it, u = _receivers(mi, [receiver], copies, 13)
    it.n = it.sh_frame.n = mi.Normal3f(-1.0, 0.0, 0.0)            # a façade facing the tail-light
    scene = mi.load_dict({"type": "scene", "lamps": lamp_set_emitter(lamps)})
    got = np.array(scene.emitters()[0].sample_direction(it, u)[1], dtype=np.float64)[0]
    one, _ = _receivers(mi, [receiver], 1, 14)
    one.n = one.sh_frame.n = mi.Normal3f(-1.0, 0.0, 0.0)
    tail = mi.load_dict({"type": "scene", "s": lamps["taillight_0"]}).emitters()[0]
    want = float(np.array(tail.sample_direction(one, mi.Point2f(0.5, 0.5))[1], dtype=np.float64)[0, 0])
    assert want > 0
    p_tail = global_table(np.array([e["sampling_weight"] for e in lamps.values()]))[-1]
    assert p_tail > UNIFORM_SHARE / len(lamps) * 0.99
    sem = got.std() / np.sqrt(copies)
    assert abs(got.mean() - want) < 4 * sem, (got.mean(), want, sem)
    assert got.std() / want < 10, got.std() / want


def test_a_red_tail_light_in_front_of_a_facade_is_found_at_its_own_wavelengths(mi):
    """The side- and wavelength-aware candidates (issue 33: city_night frame 0's façade dots). A façade
    facing +y is lit at 625 nm almost only by a red tail-light 18 m in front of it; 20 sodium street
    lamps stand behind the wall (they light its other side). Picked among a cell's candidates by
    luminous bounds blind to the receiving side, the tail-light was no candidate: the table alone
    found it (p ≈ 2.7e-4 in the city frame) and a sample was worth up to ~1,600× the point's mean.
    With candidates per receiving side and per 40-nm band and weights in W/sr/nm at the path's
    wavelengths, the relative standard deviation per sample (diffuse receiver: value × max(cos, 0))
    is 0.31, against 24.5 before (measured 2026-11-28), and the mean is Mitsuba's own spots'."""
    import drjit as dr
    from workbench.render.lamp_set import lamp_set_emitter
    lamps = {f"street_lamp_{i}": street_lamp_emitter([-30.0 + 3.0 * i, -6.0 - 2.0 * (i % 3), 7.8], "hps")
             for i in range(20)}
    lamps["taillight_0"] = spot_emitter([2.0, 18.0, 0.8], [0.0, -1.0, 0.0], "led_red", 10.0, 60.0, 20.0)
    receiver = np.array([0.0, 0.01, 3.0])
    copies = 1 << 14

    def at(n):
        it = dr.zeros(mi.SurfaceInteraction3f, n)
        it.p = mi.Point3f(*(mi.Float(np.full(n, c, np.float32)) for c in receiver))
        it.n = it.sh_frame.n = mi.Normal3f(0.0, 1.0, 0.0)
        it.wavelengths = mi.UnpolarizedSpectrum(625.0)
        return it
    u = np.random.default_rng(31).random((2, copies)).astype(np.float32)
    emitter = mi.load_dict({"type": "scene", "lamps": lamp_set_emitter(lamps)}).emitters()[0]
    ds, value = emitter.sample_direction(at(copies), mi.Point2f(mi.Float(u[0]), mi.Float(u[1])))
    got = np.array(value, dtype=np.float64)[0] * np.maximum(np.array(ds.d.y, dtype=np.float64), 0.0)
    want = 0.0
    for em in lamps.values():
        ds1, v1 = mi.load_dict({"type": "scene", "s": em}).emitters()[0].sample_direction(at(1), mi.Point2f(0.5, 0.5))
        want += float(np.array(v1, dtype=np.float64)[0, 0]) * max(float(np.array(ds1.d.y)[0]), 0.0)
    assert want > 0
    sem = got.std() / np.sqrt(copies)
    assert abs(got.mean() - want) < 4 * sem + 1e-3 * want, (got.mean(), want, sem)
    assert got.std() / want < 2.0, got.std() / want
