"""`workbench bench optics`: time and error of every optics level of detail against the full model.

The camera is the paper's (f = 2.376 mm, 44° over 640 columns) with the shipped automotive
wide-angle prescription scaled to that focal length, at f/4. For each scene every level runs
twice (cold: including one-off set-up such as tracing the PSF grid; warm: cached), and its
output is compared with the full model (charts: 'raytrace' with many rays per sample; the city
frame: the lens traced inside Mitsuba for every camera ray, render.lens_camera):
  rel_rms_error = RMS(level − reference) / RMS(reference) over the whole frame (all bands);
  mtf50 (cycles/mm on the sensor) from the ISO 12233 slanted edge, and its relative error.
Scenes: a slanted edge near the axis at the paper's 3 µm sampling; the same edge across the
full 44° field at coarser sampling; and a rendered demo city frame (Mitsuba) when rendering
works here. The selector's pick for each scene is listed too. A speed-versus-error plot goes
to --out.
"""
from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from workbench.bench import BenchResult, register_bench
from workbench.bench.timing import timed
from workbench.files import atomic_write_bytes
from workbench.optics.formation import mtf
from workbench.optics.params import OpticsParams
from workbench.optics.types import OPTICS_MODELS
from workbench.scene.types import Scene

LENS = "automotive.2.4mm"
F_NUMBER = 4.0
LEVELS = ("pinhole", "diffraction_limited", "thin_lens", "psf_grid", "raytrace")


def _camera() -> OpticsParams:
    return OpticsParams(lens_file=LENS, scale_lens_to_focal_length=True, f_number=F_NUMBER)


def _edge_scene(cols: int, spacing_um: float | None, fov_deg: float | None) -> Scene:
    from workbench.scene.charts import slanted_edge_scene
    cam = _camera()
    if fov_deg is None:
        d = 1.0 / (1.0 / cam.focal_length_m - 1.0 / 10.0)
        fov_deg = math.degrees(2 * math.atan(cols * spacing_um * 1e-6 / 2 / d))
    rows = cols * 3 // 4
    return slanted_edge_scene(angle_deg=5.0, contrast=0.8, size=(rows, cols), fov_deg=fov_deg, distance_m=10.0)


def _city_scenes(cols: int, spp: int) -> tuple[Scene | None, tuple | None, list[str]]:
    """The demo city rendered twice from the same pose: through a pinhole (radiance, the levels'
    input) and through the lens inside Mitsuba (the full model: irradiance, the reference).
    Returns (scene, (reference OpticalImage, its render time, noise-floor OpticalImage) or None,
    notes). Both focus on the pinhole render's median depth, which every level then uses too.
    Both are independent Monte Carlo renders at `spp`, so the errors against the reference carry
    both renders' noise (the noise-floor row measures it: about 0.25·√(64/spp) on this frame)."""
    notes = []
    try:
        from workbench.jobs import run_job
        from workbench.render.demo_scene import demo_city, demo_pose
        from workbench.render.params import RenderParams
        from workbench.render.spectral import render_spectral
        rows = cols * 3 // 4
        params = RenderParams(spp=spp, band_count=8)
        scene, took = timed(lambda: run_job(render_spectral(demo_city(), demo_pose(), params, width=cols,
                                                            height=rows, fov_deg=44.0, name="demo city")))
        notes.append(f"demo city rendered by Mitsuba through a pinhole ({cols}×{rows}, {spp} spp, 8 bands, "
                     f"{took.wall_ms * 1e-3:.2f} s): the levels' input")
    except Exception as exc:  # noqa: BLE001  (any render failure: report it and go on)
        return None, None, [f"city frame skipped: rendering failed here ({type(exc).__name__}: {exc})"]
    try:
        from workbench.optics.formation.full_model import full_model_camera, full_model_optical_image
        from workbench.optics.formation.geometry import scene_geometry
        from workbench.render.lens_camera import lens_sensor_dict
        from workbench.render.scene_builder import pinhole_sensor
        optics = _camera().updated(model="raytrace", focus_distance_m=scene.distance_m)
        camera = full_model_camera(optics, scene_geometry(scene, optics))
        to_world = pinhole_sensor(demo_pose(), 44.0)["to_world"]
        images, times = [], []
        for seed in (0, 1):
            sensor = lens_sensor_dict(camera.lens, {"width": cols, "height": rows}, to_world, camera.sensor_width_mm)
            full, took = timed(lambda: run_job(render_spectral(
                demo_city(), demo_pose(), params.model_copy(update={"seed": seed}), width=cols, height=rows,
                fov_deg=camera.fov_deg, lens_sensor=sensor, name="demo city, full model")))
            images.append(full_model_optical_image(full.radiance_photons, full.wavelengths_nm, camera, optics))
            times.append(took.wall_ms * 1e-3)
        notes.append(f"reference = the full model: the lens traced inside Mitsuba for every camera ray "
                     f"({spp} spp, focused at {scene.distance_m:.2f} m, diffraction added as for raytrace); "
                     "its time is a whole render, the levels' times exclude their pinhole render; the "
                     "'another seed' row is the reference's own Monte Carlo noise floor (×√2)")
        return scene, (images[0], times[0], images[1]), notes
    except Exception as exc:  # noqa: BLE001  (report why the full model failed and go on)
        notes.append(f"city frame: the Mitsuba full model failed here ({type(exc).__name__}: {exc}); "
                     "reference = raytrace, which maps every ray onto one plane at the scene distance")
        return scene, None, notes


def _rel_rms(image: np.ndarray, reference: np.ndarray) -> float:
    """RMS(image − reference) / RMS(reference) over the whole frame (all bands)."""
    ref = reference.astype(np.float64)
    return float(np.sqrt(np.mean((image.astype(np.float64) - ref) ** 2)) / np.sqrt(np.mean(ref ** 2)))


def _timed(level: str, scene: Scene, params: OpticsParams):
    p = params.model_copy(update={"model": level})
    oi, took = timed(lambda: OPTICS_MODELS[level](scene, p))
    return oi, took.wall_ms * 1e-3


def _mtf50_per_mm(image: np.ndarray, spacing_m: float) -> float:
    try:
        res = mtf.slanted_edge_mtf(image)
    except ValueError:
        return float("nan")
    return res.mtf50_cyc_per_sample / (spacing_m * 1e3)


def _bench_scene(name: str, scene: Scene, ref_rays: int, fast_rays: int, has_edge: bool,
                 cam: OpticsParams | None = None, full_model: tuple | None = None) -> list[dict]:
    """Rows for one scene. full_model: (reference OpticalImage, its time, a second render of it) to
    compare against instead of raytrace with ref_rays (which then becomes one more level)."""
    from workbench.optics.formation.selector import compare_to_reference, select_level
    cam = cam or _camera()
    ref_label = f"raytrace ({ref_rays} rays, reference)"
    extra = []
    if full_model is None:
        ref, ref_t = _timed("raytrace", scene, cam.model_copy(update={"rays_per_sample": ref_rays}))
    else:
        ref, ref_t, second = full_model
        ref_label = "full model (Mitsuba lens camera, reference)"
        extra = [("raytrace", cam.model_copy(update={"rays_per_sample": ref_rays}))]
    ref_img = ref.irradiance_photons
    ref_mtf50 = _mtf50_per_mm(ref_img, ref.sample_spacing_m) if has_edge else float("nan")
    rows = []
    runs = ([(lvl, cam) for lvl in LEVELS[:-1]] + [("raytrace", cam.model_copy(update={"rays_per_sample": fast_rays}))]
            + extra)
    for level, params in runs:
        oi, cold = _timed(level, scene, params)
        _, warm = _timed(level, scene, params)
        err = compare_to_reference(oi.irradiance_photons, ref_img) if has_edge else None
        rel = err["rel_rms_error"] if err else _rel_rms(oi.irradiance_photons, ref_img)
        m50 = _mtf50_per_mm(oi.irradiance_photons, oi.sample_spacing_m) if has_edge else float("nan")
        label = level if level != "raytrace" else f"raytrace ({params.rays_per_sample} rays)"
        rows.append({"scene": name, "level": label, "time_s": cold, "warm_time_s": warm, "rel_rms_error": rel,
                     "mtf50_cyc_per_mm": m50,
                     "mtf50_error": abs(m50 - ref_mtf50) / ref_mtf50 if has_edge else float("nan")})
    rows.append({"scene": name, "level": ref_label, "time_s": ref_t,
                 "warm_time_s": float("nan"), "rel_rms_error": 0.0, "mtf50_cyc_per_mm": ref_mtf50,
                 "mtf50_error": 0.0})
    if full_model is not None:
        rows.append({"scene": name, "level": "full model, another seed (noise floor)", "time_s": ref_t,
                     "warm_time_s": float("nan"), "rel_rms_error": _rel_rms(second.irradiance_photons, ref_img),
                     "mtf50_cyc_per_mm": float("nan"), "mtf50_error": float("nan")})
    (chosen, _), took = timed(lambda: select_level(scene, cam))
    rows.append({"scene": name, "level": f"auto → {chosen}", "time_s": took.wall_ms * 1e-3,
                 "warm_time_s": float("nan"), "rel_rms_error": float("nan"), "mtf50_cyc_per_mm": float("nan"),
                 "mtf50_error": float("nan")})
    return rows


def _plot(rows: list[dict], out_dir: str) -> str:
    from matplotlib.figure import Figure
    fig = Figure(figsize=(12, 4.8))                   # its own Agg canvas: no pyplot, no global backend
    axes = fig.subplots(1, 2)
    for ax, key, label in ((axes[0], "rel_rms_error", "relative RMS error"), (axes[1], "mtf50_error", "MTF50 error")):
        for scene in dict.fromkeys(r["scene"] for r in rows):
            pts = [r for r in rows if r["scene"] == scene and math.isfinite(r["warm_time_s"])
                   and math.isfinite(r[key]) and r[key] > 0]
            if not pts:
                continue
            line = ax.loglog([r["warm_time_s"] for r in pts], [r[key] for r in pts], "o", label=scene)[0]
            for r in pts:
                ax.annotate(r["level"].replace("diffraction_limited", "diffraction"), (r["warm_time_s"], r[key]),
                            fontsize=7, color=line.get_color(), xytext=(3, 3), textcoords="offset points")
        ax.set_xlabel("time per frame, warm (s)")
        ax.set_ylabel(f"{label} vs ray-traced reference")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"Optics levels of detail: {LENS}, f/{F_NUMBER:g}")
    path = Path(out_dir) / "optics_speed_vs_error.png"
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, dpi=110, format="png")
    atomic_write_bytes(path, buf.getvalue())
    return str(path)


@register_bench("optics", help="time and error of each optics level against ray tracing")
def bench_optics(args) -> BenchResult:
    quick = bool(getattr(args, "quick", False))
    edge_cols, field_cols, city_cols = (48, 64, 64) if quick else (96, 160, 128)
    ref_rays, fast_rays = (64, 4) if quick else (256, 16)
    notes = [f"camera: {LENS} scaled to f = {_camera().focal_length_mm} mm, f/{F_NUMBER:g}; "
             f"chart reference = raytrace with {ref_rays} rays/sample; errors over the whole frame",
             "raytrace adds diffraction as traced spot ⊛ Airy: where the spot is about the Airy size "
             "(this lens at 3 µm) that counts aberrations twice, so errors there are pessimistic; "
             "the selector ('auto') then takes the wave-optical psf_grid as its full model",
             "raytrace maps every ray onto one plane at the scene distance (depth is ignored; thin_lens "
             "and psf_grid use it), which is where it departs from the full model on a city frame"]
    rows = _bench_scene("edge, axis, 3 µm", _edge_scene(edge_cols, 3.0, None), ref_rays, fast_rays, True)
    rows += _bench_scene(f"edge, 44° field, {field_cols} cols", _edge_scene(field_cols, None, 44.0),
                         ref_rays, fast_rays, True)
    city, full_model, city_notes = _city_scenes(city_cols, 1024 if quick else 4096)
    notes += city_notes
    if city is not None:
        cam = _camera().model_copy(update={"focus_distance_m": city.distance_m})
        rows += _bench_scene(f"city frame, {city_cols} cols", city, ref_rays, fast_rays, False, cam, full_model)
    extra = {}
    if getattr(args, "out", None):
        extra["plot"] = _plot(rows, args.out)
        notes.append(f"plot: {extra['plot']}")
    return BenchResult("Optics levels of detail: time and error against the ray-traced lens", rows, notes, extra)
