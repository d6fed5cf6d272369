"""Render noise against shot noise for night, tunnel and day samples: core-seconds per frame at the
data sets' criterion, before and after the night light selection per shading point and, in the
tunnels, portal guiding, then the sun carried by the luminaire row (tunnel_sun_share.py), then
the clear coats regularized for rays not from the camera (coat_regularization.py) (part of
`workbench bench render`, and alone as `workbench bench render-noise`).

Each case is a sample project (city_night, city_tunnel, city_tunnel_entrance, and the day data
set city_detection_quick) rendered small: the sensor's rows and columns and the focal length
divided by SCALE (same field of view, same pixel pitch, f-number and exposure, so the same
electrons per pixel), film in the sensor's channels, multijitter sampler (the data sets'
settings). Per frame, a reference at REF_SPP with the 'after' settings (its own noise
stream; every setting has the same expected image but for the regularized coats' stated
bias) and a test render at TEST_SPP per setting
are turned into the experiment sensor's electron rates; experiments.render_noise.noise_ratios
compares them at the lowest EV the project tests (the data-set check's exposure). Columns:
median, p90, edge and power ratios (the reference's own noise taken out: × 1/√(1 + test/ref
spp)), the power ratio of the images as the sensor records them (clipped at its full well: a
lamp face that saturates either way carries no render noise into the data), the power ratio of
the pixels below the reference's 90th percentile (power_dim: the dim surfaces, where fireflies
show; the whole frame's is carried by the edges of lamp faces and bright exits) and how many
of those pixels err by more than 5× their shot noise (fireflies), top_0.1pct (the share of the error
power in the worst 0.1 % of pixels), spp at
the criterion (≤ ⅓ median, ≤ ⅔ p90 and edges; ratios fall as 1/√spp), the process CPU seconds
(all threads: core-seconds) of that frame from t = a + b·spp fitted to the two renders, per
1000 pixels, and that cost over the day frames'."""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from workbench.bench import BenchResult, register_bench

DAY = "day (city_detection_quick)"
GUIDE = "portal_guide"     # a setting's key that is no NightParams field: False renders without portal guiding
SUN_SHARE = "sun_share"    # another: False keeps the sun its own emitter (render/tunnel_sun_share.py)
COATS = "coats_regularized"  # another: False keeps every ray's coat sharp (render/coat_regularization.py)
CASES = (  # (label, sample project, scale, {setting: NightParams updates})
    (DAY, "city_detection_quick", 2, {"before": {}}),
    ("night", "city_night", 4, {"before": {"light_selection": "view"}, "after": {"light_selection": "shading"}}),
    ("tunnel", "city_tunnel", 4, {"before": {GUIDE: False, SUN_SHARE: False, COATS: False},
                                  "guided": {SUN_SHARE: False, COATS: False}, "sharp": {COATS: False},
                                  "after": {}}),
    ("tunnel entrance", "city_tunnel_entrance", 4, {"before": {GUIDE: False, SUN_SHARE: False, COATS: False},
                                                    "guided": {SUN_SHARE: False, COATS: False},
                                                    "sharp": {COATS: False}, "after": {}}),
)


def noise_plan(quick: bool) -> tuple[int, int, int, int]:
    """(frames per case, reference spp, test spp, extra scale factor): 3, 1024, 64, 1, or in
    --quick 1, 64, 16, 2."""
    return (1, 64, 16, 2) if quick else (3, 1024, 64, 1)


def _project(name: str, scale: int, night: dict, spp: int):
    from workbench.project import load_project
    night = {k: v for k, v in night.items() if k not in (GUIDE, SUN_SHARE, COATS)}
    p = load_project(name)
    s, r = p.sensor, p.render
    world = r.world.updated(night=r.world.night.updated(**night)) if night else r.world
    return p.updated(sensor=s.updated(cols=s.cols // scale, rows=s.rows // scale),
                     optics=p.optics.updated(focal_length_mm=p.optics.focal_length_mm / scale),
                     render=r.updated(representation="sensor", sampler="multijitter", spp=spp,
                                      chunk_spp=min(spp, 256), preview_spp=min(spp, 256), target_rel_error=None,
                                      shot_noise_ratio=None, world=world))


def _render(project, index: int, reference: bool, guided: bool = True, sun_share: bool = True,
            coats: bool = True):
    """(electron rate H×W, instance ids, auto exposure s, CPU seconds) of frame `index`; guided
    False: without portal guiding (render/portal_guide.py); sun_share False: the sun its own
    emitter (render/tunnel_sun_share.py); coats False: every ray's coat sharp
    (render/coat_regularization.py)."""
    from contextlib import ExitStack

    from workbench.render.coat_regularization import sharp_coats
    from workbench.render.portal_guide import unguided
    from workbench.render.tunnel_sun_share import separate_sun
    from workbench.detect.data import experiment_sensor
    from workbench.experiments.render_noise import REFERENCE_SEED_TAG
    from workbench.jobs import run_job
    from workbench.render.city_frame import city_optical_image, city_scene_inputs, city_scene_job, project_frame_seeds
    from workbench.sensor import auto_exposure, irradiance_to_signal_rate

    seeds = project_frame_seeds(project, index)
    if reference:
        seeds = replace(seeds, render=int(np.random.SeedSequence([seeds.render, REFERENCE_SEED_TAG]).generate_state(1)[0]))
    t0 = time.process_time()
    with ExitStack() as stack:
        if not guided:
            stack.enter_context(unguided())
        if not sun_share:
            stack.enter_context(separate_sun())
        if not coats:
            stack.enter_context(sharp_coats())
        ren = run_job(city_scene_job(city_scene_inputs(project), seeds))
    cpu = time.process_time() - t0
    sensor = experiment_sensor(project)
    rate = irradiance_to_signal_rate(city_optical_image(ren, project.optics, project.scene.adjust_illuminance_lux), sensor)
    return rate, ren.labels.instance_id, float(auto_exposure(rate, sensor)), cpu


def scene_noise_rows(quick: bool) -> list[dict]:
    """One row per case, setting and frame (module docstring), then the cost over the day's."""
    from workbench.detect.data import experiment_sensor
    from workbench.experiments.render_noise import TAIL_RATIO, TARGET_RATIO, edge_pixels, noise_ratios

    frames, ref_spp, test_spp, extra = noise_plan(quick)
    rows = []
    for label, name, scale, settings in CASES:
        last = list(settings)[-1]
        for index in range(frames):
            ref_project = _project(name, scale * extra, settings[last], ref_spp)
            ref, ids, ae, ref_cpu = _render(ref_project, index, True)
            ev_min = float(min(ref_project.experiment.ev_biases))
            exposure_s = min(ae * 2.0 ** ev_min, ref_project.sensor.max_exposure_s)
            full_well_e = experiment_sensor(ref_project).full_well_e
            for setting, night in settings.items():
                rate, _, _, cpu = _render(_project(name, scale * extra, night, test_spp), index, False,
                                          night.get(GUIDE, True), night.get(SUN_SHARE, True), night.get(COATS, True))
                r = noise_ratios(rate, ref, exposure_s, edge_pixels(ids), full_well_e)
                k = 1 / np.sqrt(1 + test_spp / ref_spp)
                med, p90, edge = (r[key] * k for key in ("median_ratio", "p90_ratio", "edge_ratio"))
                spp = int(np.ceil(test_spp * max((med / TARGET_RATIO) ** 2, (p90 / TAIL_RATIO) ** 2,
                                                 (edge / TAIL_RATIO) ** 2)))
                b = max((ref_cpu - cpu) / (ref_spp - test_spp), cpu / test_spp * 0.5)
                a = max(cpu - b * test_spp, 0.0)
                e2 = np.sort((((rate - ref) * exposure_s) ** 2).ravel())[::-1]
                rows.append({"scene": label, "setting": f"{setting} " + (",".join(f"{k}={v}" for k, v in night.items())
                                                                         or "(sample as is)"),
                             "frame": index, "px": int(ref.size), "mean_e": round(float(ref.mean() * exposure_s), 2),
                             "spp": test_spp, "cpu_s": round(cpu, 2), "median": round(med, 3), "p90": round(p90, 3),
                             "edge": round(edge, 3), "power": round(r["power_ratio"] * k, 3),
                             "power_clipped": round(r["power_ratio_clipped"] * k, 3),
                             "power_dim": round(r["power_ratio_dim"] * k, 3), "fireflies": r["firefly_pixels"],
                             "top_0.1pct": round(float(e2[:max(1, e2.size // 1000)].sum() / max(e2.sum(), 1e-300)), 3),
                             "spp_at_criterion": spp,
                             "core_s_per_kpx_at_criterion": round((a + b * spp) / (ref.size / 1000), 3)})
    day = [r["core_s_per_kpx_at_criterion"] for r in rows if r["scene"] == DAY]
    day_cost = float(np.median(day)) if day else float("nan")
    for r in rows:
        r["x_day_cost"] = round(r["core_s_per_kpx_at_criterion"] / day_cost, 2)
    return rows


def noise_notes(quick: bool) -> list[str]:
    frames, ref_spp, test_spp, extra = noise_plan(quick)
    return [f"render noise / shot noise at the lowest EV of each sample's experiment: {frames} frame(s) per case, "
            f"sensor rows/cols and focal length ÷ {', '.join(sorted({str(c[2] * extra) for c in CASES}))}, "
            f"reference {ref_spp} spp ('after' settings), tests {test_spp} spp; criterion ≤ ⅓ median, ≤ ⅔ p90 and "
            "edges; core-seconds = process CPU time (all threads); x_day_cost over the median day frame."]


@register_bench("render-noise", help="night, tunnel and day samples: core-seconds per frame at the data sets' "
                                     "render-noise criterion, before and after (also part of 'render')")
def bench_render_noise(args) -> BenchResult:
    quick = bool(getattr(args, "quick", False))
    rows = scene_noise_rows(quick)
    return BenchResult("render noise vs shot noise: night, tunnel and day samples", rows, noise_notes(quick),
                       {"scene_noise": rows})
