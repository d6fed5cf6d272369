"""Automatic level of detail: the cheapest optics model whose error stays within the budget.

`select_level` images a small slanted-edge probe with the scene's sample spacing, wavelengths,
focus and worst defocus (the scene depth with the largest blur circle) through every level up
to the full model, and measures each against the full model on the probe: relative RMS error
and MTF50 error (ISO 12233 slanted edge). Across the field, where the on-axis probe cannot
see, levels without the lens are also charged with
  - the corner illumination error (their cos⁴ against the lens's traced relative illumination),
  - the corner distortion shift in samples (their geometry against the traced chief ray),
  - an estimated corner MTF50 loss from the lens's RMS spot size against Airy and sample pitch
    (Gaussian blur model: MTF50 ∝ 1/σ, σ² = σ_Airy² + σ_spot² + σ_sample², σ_Airy ≈ 0.42 λN).
The full model (see reference_level): with a lens file, 'raytrace' in the geometric regime
and 'psf_grid' (wave-optical PSFs) when the spot is within 2 Airy radii; without one,
'thin_lens' when the scene has defocus, else 'diffraction_limited'. 'auto' runs the chosen level and puts the report in
meta['auto'].
"""
from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict

import numpy as np

from workbench.optics.formation import geometry, lens_setup, mtf, thin_lens
from workbench.optics.params import ErrorBudget, OpticsParams
from workbench.optics.types import OPTICS_MODELS, OpticalImage, register_optics
from workbench.scene.types import Scene

LEVELS_BY_COST = ("pinhole", "diffraction_limited", "thin_lens", "psf_grid", "raytrace")
LENS_LEVELS = ("psf_grid", "raytrace")
PROBE_SIZE = 48
PROBE_BANDS = 5
REFERENCE_RAYS = 256
WAVE_REGIME_SPOTS = 2.0
CACHE_SIZE = 32
_CACHE: OrderedDict = OrderedDict()   # LRU: selection per (params, budget, camera, worst depth, wavelengths)
_CACHE_LOCK = threading.Lock()


def _probe_wavelengths(wavelengths_nm: np.ndarray) -> np.ndarray:
    idx = np.unique(np.round(np.linspace(0, wavelengths_nm.size - 1, min(PROBE_BANDS, wavelengths_nm.size))))
    return wavelengths_nm[idx.astype(int)]


def _worst_depth_m(scene: Scene, f_number: float, camera: geometry.CameraGeometry) -> float:
    """The scene depth (axial, m) with the largest circle of confusion."""
    z = thin_lens.axial_depth_m(scene, camera.sample_spacing_m, camera.image_distance_m)
    coc = thin_lens.circle_of_confusion_m(z, camera.focal_length_m, f_number, camera.focus_distance_m)
    return float(z.flat[int(np.argmax(coc))])


def _probe(scene: Scene, params: OpticsParams,
           camera: geometry.CameraGeometry) -> tuple[Scene, OpticsParams, geometry.CameraGeometry, dict]:
    """A PROBE_SIZE² slanted edge at the worst depth on the scene's sample spacing and focus: the
    probe scene, its optics (no distortion), its camera geometry and what it was made from."""
    from workbench.scene.charts import slanted_edge_scene
    dx, d_img, s_m = camera.sample_spacing_m, camera.image_distance_m, camera.focus_distance_m
    z_worst = _worst_depth_m(scene, params.f_number, camera)
    probe_params = params.model_copy(update={"distortion_k": ()})
    probe_camera = geometry.camera_geometry(probe_params, s_m, (PROBE_SIZE, PROBE_SIZE),
                                            sensor_width_m=PROBE_SIZE * dx)
    probe = slanted_edge_scene(angle_deg=5.0, contrast=0.8, size=(PROBE_SIZE, PROBE_SIZE),
                               fov_deg=probe_camera.hfov_deg, distance_m=z_worst,
                               wavelengths_nm=_probe_wavelengths(scene.wavelengths_nm))
    coc = float(thin_lens.circle_of_confusion_m(np.array([z_worst]), camera.focal_length_m,
                                                params.f_number, s_m)[0])
    return probe, probe_params, probe_camera, {"sample_spacing_um": dx * 1e6, "image_distance_m": d_img,
                                               "worst_depth_m": z_worst, "worst_coc_um": coc * 1e6}


def reference_level(has_lens: bool, geometry_info: dict, field: dict) -> tuple[str, str]:
    """The full model for this camera and why: with a lens, ray tracing when the geometric spot
    exceeds WAVE_REGIME_SPOTS Airy radii anywhere in the field (geometric regime), else the
    PSF grid, whose PSFs are wave-optical (adding an Airy disk to a traced spot of the same
    size, as raytrace does, counts the aberrations twice); without a lens, the thin lens when
    the scene has defocus, else the diffraction-limited model."""
    if has_lens:
        spots = [v for v in (field["rms_spot_um_axis"], field["rms_spot_um_corner"]) if math.isfinite(v)]
        if not spots:
            return "raytrace", "no spot diagram could be traced; ray tracing is the only full model"
        spot, airy = max(spots), field["airy_radius_um"]
        if spot > WAVE_REGIME_SPOTS * airy:
            return "raytrace", f"geometric regime: RMS spot {spot:.3g} µm > {WAVE_REGIME_SPOTS:g} × Airy radius {airy:.3g} µm"
        return "psf_grid", (f"diffraction matters: RMS spot {spot:.3g} µm ≤ {WAVE_REGIME_SPOTS:g} × Airy radius "
                            f"{airy:.3g} µm, so the wave-optical PSF grid is the full model")
    if geometry_info["worst_coc_um"] > 0.05 * geometry_info["sample_spacing_um"]:
        return "thin_lens", f"no lens file; defocus up to {geometry_info['worst_coc_um']:.3g} µm"
    return "diffraction_limited", "no lens file and no defocus"


def _field_checks(scene: Scene, params: OpticsParams, camera: geometry.CameraGeometry, info: dict) -> dict:
    """Corner illumination, distortion and blur of the lens against the lens-free levels."""
    from workbench.optics.lens import distortion, paraxial, relative_illumination, spot_diagram
    lens, _ = lens_setup.focused_lens(params, camera.focus_distance_m)
    pdata = paraxial(lens)
    rows, cols = scene.shape
    dx, d_img = info["sample_spacing_um"] * 1e-6, info["image_distance_m"]
    r_c = dx * math.hypot(rows, cols) / 2
    theta = math.degrees(math.atan(r_c / d_img))
    wl = float(np.median(scene.wavelengths_nm))
    ri = float(relative_illumination(lens, [r_c * 1e3], wl)[0])
    m = camera.magnification
    cos4 = float(geometry.cos4th_falloff(np.array(r_c), d_img, params.f_number, m, 2 * r_c)) \
        if params.off_axis == "cos4th" else 1.0
    dist = distortion(lens, [theta], wl)
    tan_t = math.tan(math.radians(theta))
    k = tuple(params.distortion_k) + (0.0,) * (3 - len(params.distortion_k))
    r_model = d_img * tan_t * (1 + k[0] * tan_t ** 2 + k[1] * tan_t ** 4 + k[2] * tan_t ** 6)
    r_lens = float(dist.real_height_mm[0]) * 1e-3 if dist.valid[0] else r_model
    spots = []
    for angle in (0.0, theta):
        try:
            spots.append(spot_diagram(lens, angle, wl, n_side=24).rms_um)
        except ValueError:
            spots.append(float("nan"))
    sigma_airy = 0.42 * wl * 1e-3 * pdata.f_number
    sigma_px = info["sample_spacing_um"] / math.sqrt(12)
    corner_spot = spots[1] if math.isfinite(spots[1]) else spots[0]
    sigma_lens = math.sqrt(sigma_airy ** 2 + corner_spot ** 2 + sigma_px ** 2)
    sigma_dl = math.sqrt(sigma_airy ** 2 + sigma_px ** 2)
    return {"corner_field_deg": theta, "corner_ri_lens": ri, "corner_ri_model": cos4,
            "corner_ri_error": abs(cos4 / ri - 1) if ri > 0 else float("inf"),
            "corner_distortion_shift_samples": abs(r_model - r_lens) / dx,
            "rms_spot_um_axis": spots[0], "rms_spot_um_corner": spots[1],
            "airy_radius_um": 1.22 * wl * 1e-3 * pdata.f_number,
            "corner_mtf50_error_estimate": 1 - sigma_dl / sigma_lens}


def _run(level: str, scene: Scene, params: OpticsParams,
         camera: geometry.CameraGeometry) -> tuple[OpticalImage, float]:
    p = params.model_copy(update={"model": level})
    if level == "raytrace":
        p = p.model_copy(update={"rays_per_sample": max(params.rays_per_sample, REFERENCE_RAYS)})
    t0 = time.perf_counter()
    oi = OPTICS_MODELS[level](scene, p, camera)
    return oi, time.perf_counter() - t0


def compare_to_reference(candidate: np.ndarray, reference: np.ndarray) -> dict:
    """Relative RMS error and MTF50 (cycles/sample) of a candidate against a reference image."""
    diff = candidate.astype(np.float64) - reference.astype(np.float64)
    rel_rms = float(np.sqrt(np.mean(diff ** 2)) / max(np.sqrt(np.mean(reference.astype(np.float64) ** 2)), 1e-300))
    m_c = mtf.slanted_edge_mtf(candidate).mtf50_cyc_per_sample
    m_r = mtf.slanted_edge_mtf(reference).mtf50_cyc_per_sample
    return {"rel_rms_error": rel_rms, "mtf50_cyc_per_sample": m_c,
            "mtf50_error": abs(m_c - m_r) / m_r if m_r > 0 and math.isfinite(m_c) else float("inf")}


def select_level(scene: Scene, params: OpticsParams, budget: ErrorBudget | None = None,
                 camera: geometry.CameraGeometry | None = None) -> tuple[str, dict]:
    """The cheapest level whose error against the full model is within `budget` (default
    params.budget), and a report: per-level time/errors on the probe, field checks, reasons.
    `camera`: the geometry the scene was sampled for (geometry.scene_geometry when None)."""
    budget = budget or params.budget
    camera = geometry.scene_geometry(scene, params, camera)
    probe, probe_params, probe_camera, info = _probe(scene, params, camera)
    key = (params.model_dump_json(exclude={"model"}), budget.model_dump_json(), camera,
           round(info["worst_depth_m"], 9), tuple(probe.wavelengths_nm))
    with _CACHE_LOCK:
        if key in _CACHE:
            _CACHE.move_to_end(key)
            return _CACHE[key]
    field = _field_checks(scene, params, camera, info) if params.lens_file else {}
    reference, reference_why = reference_level(params.lens_file is not None, info, field)
    ref_oi, ref_time = _run(reference, probe, probe_params, probe_camera)
    rows = []
    chosen = reference
    for level in LEVELS_BY_COST[:LEVELS_BY_COST.index(reference)]:
        oi, seconds = _run(level, probe, probe_params, probe_camera)
        row = {"level": level, "time_s": seconds,
               **compare_to_reference(oi.irradiance_photons, ref_oi.irradiance_photons)}
        reasons = []
        if row["rel_rms_error"] > budget.max_rel_rms_error:
            reasons.append(f"RMS error {row['rel_rms_error']:.3g} > {budget.max_rel_rms_error:g}")
        if row["mtf50_error"] > budget.max_mtf50_error:
            reasons.append(f"MTF50 error {row['mtf50_error']:.3g} > {budget.max_mtf50_error:g}")
        if field and level not in LENS_LEVELS:
            if field["corner_ri_error"] > budget.max_rel_rms_error:
                reasons.append(f"corner illumination error {field['corner_ri_error']:.3g} "
                               f"> {budget.max_rel_rms_error:g}")
            if field["corner_distortion_shift_samples"] > budget.max_distortion_shift_samples:
                reasons.append(f"corner distortion {field['corner_distortion_shift_samples']:.3g} samples "
                               f"> {budget.max_distortion_shift_samples:g}")
            if field["corner_mtf50_error_estimate"] > budget.max_mtf50_error:
                reasons.append(f"estimated corner MTF50 loss {field['corner_mtf50_error_estimate']:.3g} "
                               f"> {budget.max_mtf50_error:g}")
        row["passes"] = not reasons
        row["why_not"] = "; ".join(reasons)
        rows.append(row)
        if not reasons:
            chosen = level
            break
    rows.append({"level": reference, "time_s": ref_time, "rel_rms_error": 0.0,
                 "mtf50_cyc_per_sample": mtf.slanted_edge_mtf(ref_oi.irradiance_photons).mtf50_cyc_per_sample,
                 "mtf50_error": 0.0, "passes": True, "why_not": ""})
    why = (f"'{chosen}' is the cheapest level within the budget (RMS ≤ {budget.max_rel_rms_error:g}, "
           f"MTF50 ≤ {budget.max_mtf50_error:g}) against the full model '{reference}'"
           if chosen != reference else
           f"no cheaper level met the budget; using the full model '{reference}'")
    report = {"chosen": chosen, "reference": reference, "reference_why": reference_why, "why": why, "probe": info, "field": field,
              "levels": rows, "budget": budget.model_dump()}
    with _CACHE_LOCK:
        _CACHE[key] = (chosen, report)
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    return chosen, report


def auto_radiance_to_irradiance(scene: Scene, params: OpticsParams,
                                camera: geometry.CameraGeometry | None = None) -> OpticalImage:
    """Run the level `select_level` picks; meta['auto'] holds its report."""
    camera = geometry.scene_geometry(scene, params, camera)
    level, report = select_level(scene, params, camera=camera)
    oi = OPTICS_MODELS[level](scene, params.model_copy(update={"model": level}), camera)
    oi.meta["auto"] = report
    return oi


register_optics("auto")(auto_radiance_to_irradiance)
