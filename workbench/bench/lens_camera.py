"""`workbench bench lens-camera`: cost per camera ray of the Mitsuba lens camera against the
built-in perspective camera, and its on-axis irradiance against the numpy estimator."""
from __future__ import annotations

import math

import numpy as np

from workbench.bench import BenchResult, register_bench
from workbench.bench.timing import best_wall_ms, timed


@register_bench("lens-camera", help="Mitsuba lens camera vs perspective: time per camera ray")
def bench_lens_camera(args) -> BenchResult:
    from workbench.render.variants import import_mitsuba
    mi = import_mitsuba()
    from workbench.optics.lens import irradiance_per_radiance, load_lens, paraxial
    from workbench.render.lens_camera import lens_sensor_dict
    from workbench.render.lens_camera.kernels import is_dispersive

    w, h, spp, repeats = (128, 96, 8, 2) if args.quick else (512, 384, 16, 3)
    film = {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "luminance"}
    sampler = {"type": "independent", "sample_count": spp}
    box = mi.cornell_box()
    setups = {  # scene name → (objects, integrator, camera transform, horizontal fov in degrees)
        "environment": ({"env": {"type": "constant", "radiance": {"type": "uniform", "value": 1.0}}},
                        {"type": "path", "max_depth": 2},
                        mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0]), 44.0),
        "cornell box": ({k: v for k, v in box.items() if k not in ("type", "integrator", "sensor")},
                        box["integrator"], box["sensor"]["to_world"], 44.0)}
    rows = []
    lenses = {name: load_lens(name) for name in ("automotive.2.4mm", "dgauss.50mm")}
    for scene_name, (objects, integrator, cam, fov) in setups.items():
        sensors = {"perspective": {"type": "perspective", "fov": fov, "fov_axis": "x", "to_world": cam,
                                   "film": film, "sampler": sampler}}
        setup_s = {}
        for name, lens in lenses.items():
            width_mm = 2 * paraxial(lens).efl_mm * math.tan(math.radians(fov / 2))
            sensors[name], setup = timed(lambda: lens_sensor_dict(lens, film, cam, width_mm, sampler=sampler))
            setup_s[name] = setup.wall_ms * 1e-3
            if is_dispersive(lens):    # also once at the d line for all four wavelengths
                sensors[f"{name} (d line)"] = lens_sensor_dict(lens, film, cam, width_mm, sampler=sampler,
                                                               dispersion=False)
        images, renders = {}, {}
        for kind, sd in sensors.items():
            scene = mi.load_dict({"type": "scene", "integrator": integrator, "sensor": sd, **objects})

            def render(scene=scene, kind=kind, images=images):
                images[kind] = np.array(mi.render(scene))[..., 0]
            renders[kind] = render
        times = {kind: ms * 1e-3 for kind, ms in best_wall_ms(renders, repeats).items()}
        for name, lens in lenses.items():
            row = {"lens": name, "scene": scene_name, "variant": mi.variant(), "film": f"{w}x{h}", "spp": spp,
                   "pupil_setup_s": setup_s[name], "perspective_s": times["perspective"], "lens_s": times[name],
                   "lens_Mrays_per_s": w * h * spp / times[name] / 1e6,
                   "ratio_lens_vs_perspective": times[name] / times["perspective"],
                   "ratio_no_dispersion": times.get(f"{name} (d line)", math.nan) / times["perspective"]}
            if scene_name == "environment":
                c = np.s_[h // 2 - 8:h // 2 + 8, w // 2 - 8:w // 2 + 8]   # within 0.2° of the axis
                row["centre_E_over_L"] = float(images[name][c].mean() / images["perspective"][c].mean())
                row["numpy_E_over_L"] = irradiance_per_radiance(lens)
            rows.append(row)
    notes = [("environment: a constant sky only, so the scene costs almost nothing and the ratio is the "
              "worst case; cornell box: Mitsuba's test scene, path tracing to depth 8."),
             ("Time = best of repeated warm renders, interleaved (first render pays the JIT); one "
              "perspective time per scene serves both lenses."),
             "ratio_no_dispersion: a dispersive lens traced once at the d line (dispersion=False).",
             ("centre_E_over_L: 16² centre pixels at this spp (a few % Monte Carlo noise); "
              "numpy_E_over_L: the traced camera-equation integral (analysis.irradiance_per_radiance).")]
    return BenchResult("Mitsuba lens camera vs perspective (cost per camera ray)", rows, notes)
