"""`workbench bench render`: spectral render time and error against a high-spp reference.

For each resolution × spp × spectral representation (box bands of several counts, a smooth
basis, the camera's own channels) we time a warm render and measure its error against a
reference render (30 × 10-nm bands, many spp, made of two independent halves so that its own
noise can be subtracted). Errors are relative RMS over the image:
  broadband — of the sum of three camera channels (Gaussian RGB QE, 460/540/610 nm, σ 35 nm);
  channel   — mean over those camera channels;
  band      — per output wavelength against the reference re-binned / interpolated onto it.
Then: frames per hour and core-minutes per 640×480 frame at 2 % broadband error (spp = (c/0.02)²
with c measured here; that frame is rendered and timed, or in --quick extrapolated), peak
memory, stored bytes per frame; and the cost at 320×240 and 640×480 (48×36 and 96×72 in --quick)
of every scene type and feature switched on alone (render_features.py; extra['features_2pct']); and
the night, tunnel and day samples' core-seconds per frame at the data sets' render-noise
criterion, before and after the night light selection per shading point (render_noise_scenes.py;
extra['scene_noise']).
"""
from __future__ import annotations

import gc
import io
import os
import resource

import numpy as np

from workbench.bench import BenchResult, register_bench
from workbench.bench.render_features import WL_RANGE_NM
from workbench.bench.render_features import bench_qe as _qe
from workbench.bench.timing import timed
from workbench.files import atomic_write_bytes

PAPER_CORE_MIN_PER_FRAME = 160.0     # iset3d/PBRT: ~10 min per 640×480 frame on 16 cores
TARGET_BROADBAND = 0.02


def _bench_scene():
    """(city, pose, description): the generated city when it can be made, else the demo scene."""
    try:
        from workbench.scene.city.generate import generate_city
        from workbench.scene.city.poses import sample_camera_poses
        from workbench.scene.city.recipe import CityRecipe, PoseParams
        city = generate_city(CityRecipe())
        pose = sample_camera_poses(city, PoseParams(), 1, seed=0)[0]
        n = sum(len(o.meshes) for o in city.objects)
        return city, pose, f"generated city (default CityRecipe, {len(city.objects)} objects, {n} meshes)"
    except (ImportError, TypeError, ValueError) as exc:      # city generator missing or broken
        from workbench.render.demo_scene import demo_city, demo_pose
        return demo_city(), demo_pose(), f"demo scene (city generator unavailable: {exc})"


def _camera(radiance: np.ndarray, film) -> np.ndarray:
    """H×W×3 QE-weighted mean radiance of each camera channel, from any representation."""
    if film.kind == "sensor":
        return radiance
    if film.kind == "bands":
        fine = np.arange(WL_RANGE_NM[0], WL_RANGE_NM[1] + 1e-9, 0.05)
        s = np.stack([np.interp(fine, film.wavelengths_nm, r) for r in film.responses])
        w = np.trapezoid(s[:, None, :] * _qe(fine)[None], fine, axis=2)        # bands × 3
    else:
        wl = film.output_wavelengths_nm
        tw = np.gradient(wl) * np.where((wl == wl[0]) | (wl == wl[-1]), 0.5, 1.0)
        w = (_qe(wl) * tw).T
    return radiance @ (w / w.sum(axis=0))


def _rel_rms(x: np.ndarray, ref: np.ndarray, ref_var: np.ndarray | float) -> tuple[float, float]:
    """(raw, corrected) relative RMS error; corrected subtracts the reference's own variance."""
    mean = ref.mean()
    raw2 = np.mean((x - ref) ** 2)
    return float(np.sqrt(raw2) / mean), float(np.sqrt(max(raw2 - np.mean(ref_var), 0.0)) / mean)


def _band_error(scene_wl, rad, ref_wl, ref, ref_var) -> float:
    """Mean per-wavelength corrected relative error against the reference on the row's grid."""
    idx = np.searchsorted(ref_wl, scene_wl)
    if np.all(np.abs(ref_wl[np.clip(idx, 0, ref_wl.size - 1)] - scene_wl) < 1e-6):
        on, var = ref[..., idx], ref_var[..., idx]
    else:                                    # re-bin (bands aligned with the 10-nm reference)
        k = ref_wl.size // scene_wl.size
        if ref_wl.size % scene_wl.size == 0 and np.allclose(ref_wl.reshape(-1, k).mean(1), scene_wl):
            on = ref.reshape(*ref.shape[:2], -1, k).mean(-1)
            var = ref_var.reshape(*ref.shape[:2], -1, k).sum(-1) / k ** 2
        else:                                # smooth basis output: interpolate the reference
            on = np.stack([np.interp(scene_wl, ref_wl, p) for p in ref.reshape(-1, ref_wl.size)])
            on = on.reshape(*ref.shape[:2], -1)
            var = np.zeros_like(on)
    errs = [_rel_rms(rad[..., j], on[..., j], var[..., j])[1] for j in range(scene_wl.size)]
    return float(np.mean(errs))


def _stored_bytes(radiance: np.ndarray) -> tuple[int, int, float]:
    """Compressed npz bytes as float32 and as float16 (scaled into range), and float16's rel error."""
    def size(**arrays):
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        return buf.tell()
    scale = float(radiance.max()) / 6.0e4 if radiance.max() > 0 else 1.0
    f16 = (radiance / scale).astype(np.float16)
    err = float(np.abs(f16.astype(np.float64) * scale - radiance).max() / max(radiance.max(), 1e-30))
    return size(radiance=radiance.astype(np.float32)), size(radiance=f16, scale=np.float64(scale)), err


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


@register_bench("render", help="spectral render: time and error vs resolution, spp, bands, representation")
def bench_render(args) -> BenchResult:
    from workbench.jobs import run_job
    from workbench.render.film import box_bands, raised_cosine_basis, sensor_channels
    from workbench.render.params import RenderParams
    from workbench.render.scene_builder import build_scene
    from workbench.render.spectral import render_loaded
    from workbench.render.variants import select_variant

    quick = bool(getattr(args, "quick", False))
    variant = select_variant()
    city, pose, scene_desc = _bench_scene()
    fov = 44.0
    qe_wl = np.arange(WL_RANGE_NM[0], WL_RANGE_NM[1] + 1e-9, 5.0)
    reps = {"bands6": box_bands(*WL_RANGE_NM, 6), "bands15": box_bands(*WL_RANGE_NM, 15),
            "bands30": box_bands(*WL_RANGE_NM, 30), "basis6": raised_cosine_basis(*WL_RANGE_NM, 6),
            "sensor3": sensor_channels(qe_wl, _qe(qe_wl), ["B", "G", "R"])}
    if quick:
        resolutions, spps, ref_half_spp, repeats = [(96, 72)], [4, 32], 128, 1
        cost_reps, cost_spps = ("sensor3",), (2, 8)
        reps.pop("bands15")
    else:
        resolutions, spps, ref_half_spp, repeats = [(160, 120), (320, 240)], [4, 16, 64], 256, 2
        cost_reps, cost_spps = ("bands30", "basis6", "sensor3"), ()
    daylight = RenderParams().daylight
    scenes, rows = {}, []

    def render(film, w, h, spp, seed, repeat=1):
        """(radiance, min wall time over `repeat` runs, wavelengths) of one warm render."""
        if (w, h, id(film)) not in scenes:
            scenes[(w, h, id(film))] = build_scene(city, pose, fov, w, h, film, daylight, max_depth=6)[0]
            render(film, w, h, 1, 7)                      # warm-up: JIT trace/compile excluded
        p = RenderParams(spp=spp, chunk_spp=spp, preview_spp=spp, seed=seed)
        best_ms = np.inf
        for _ in range(repeat):
            s, took = timed(lambda: run_job(render_loaded(scenes[(w, h, id(film))], film, p, fov_deg=fov)))
            best_ms = min(best_ms, took.wall_ms)
        return s.radiance_photons.astype(np.float64), best_ms * 1e-3, s.wavelengths_nm

    for w, h in resolutions:
        ref_film = reps["bands30"]
        r1, _, ref_wl = render(ref_film, w, h, ref_half_spp, 1001)
        r2, _, _ = render(ref_film, w, h, ref_half_spp, 1002)
        ref = 0.5 * (r1 + r2)
        ref_var = (r1 - r2) ** 2 / 4                      # variance of the mean of two halves
        c1, c2 = _camera(r1, ref_film), _camera(r2, ref_film)
        ref_cam, ref_cam_var = 0.5 * (c1 + c2), (c1 - c2) ** 2 / 4
        ref_bb_var = (c1 - c2).sum(-1) ** 2 / 4
        for name, film in reps.items():
            for spp in spps:
                rad, dt, wl = render(film, w, h, spp, 11, repeats)
                cam = _camera(rad, film)
                bb_raw, bb = _rel_rms(cam.sum(-1), ref_cam.sum(-1), ref_bb_var)
                ch = np.mean([_rel_rms(cam[..., k], ref_cam[..., k], ref_cam_var[..., k])[1] for k in range(3)])
                rows.append({"res": f"{w}x{h}", "repr": name, "K": len(film.names), "spp": spp,
                             "time_s": round(dt, 3), "Msamples_s": round(w * h * spp / dt / 1e6, 3),
                             "err_broadband": round(bb, 4), "err_broadband_raw": round(bb_raw, 4),
                             "err_channel": round(float(ch), 4),
                             "err_band": (round(_band_error(wl, rad, ref_wl, ref, ref_var), 4)
                                          if film.kind != "sensor" else ""),
                             "c_broadband": round(bb * np.sqrt(spp), 3),
                             "peak_rss_MB": round(_peak_rss_mb(), 1)})
    notes = [f"scene: {scene_desc}; variant {variant}; {os.cpu_count()} CPU threads; max depth 6; "
             f"reference: 30 × 10-nm bands, 2 × {ref_half_spp} spp (its variance subtracted); "
             f"times: min of {repeats} warm run(s), depth pass included."]
    extra = {"scene": scene_desc, "variant": variant, "cost_640x480_2pct": []}
    last = f"{resolutions[-1][0]}x{resolutions[-1][1]}"
    for name in cost_reps:
        film = reps[name]
        c = float(np.median([r["c_broadband"] for r in rows if r["repr"] == name and r["res"] == last]))
        spp = int(np.ceil((c / TARGET_BROADBAND) ** 2))
        if quick:                                         # extrapolate t = a + b·spp from two short renders
            t_lo = render(film, 640, 480, cost_spps[0], 21)[1]
            rad, t_hi, _ = render(film, 640, 480, cost_spps[1], 21)
            b = (t_hi - t_lo) / (cost_spps[1] - cost_spps[0])
            b = b if b > 0 else t_hi / cost_spps[1]       # timing noise: count all time as per-sample
            t, err = max(t_hi - b * cost_spps[1], 0.0) + b * spp, None
        else:                                             # render the 2 % frame itself, twice
            rad, t1, _ = render(film, 640, 480, spp, 21)
            rad2, t2, _ = render(film, 640, 480, spp, 22)
            t = min(t1, t2)
            sa, sb = _camera(rad, film).sum(-1), _camera(rad2, film).sum(-1)
            err = float(np.sqrt(np.mean((sa - sb) ** 2) / 2) / (0.5 * (sa.mean() + sb.mean())))
        f32, f16, f16_err = _stored_bytes(rad.astype(np.float32))
        item = {"repr": name, "c_broadband": round(c, 3), "spp_for_2pct": spp,
                "err_broadband_measured": None if err is None else round(err, 4), "s_per_frame": round(t, 1),
                "frames_per_hour": round(3600 / t, 1),
                "core_min_per_frame": round(t / 60 * (os.cpu_count() or 1), 2),
                "paper_core_min_per_frame": PAPER_CORE_MIN_PER_FRAME,
                "npz_float32_MB": round(f32 / 1e6, 2), "npz_float16_MB": round(f16 / 1e6, 2),
                "float16_max_rel_err": f"{f16_err:.1e}"}
        extra["cost_640x480_2pct"].append(item)
        notes.append("640x480 @2% broadband: " + ", ".join(f"{k}={v}" for k, v in item.items()))
    from workbench.bench.render_features import feature_costs, feature_notes, feature_plan
    scenes.clear()          # live scenes' shapes and emitters enter every later kernel's calls (and its compile)
    gc.collect()
    f_res, f_spps = feature_plan(quick)
    extra["features_2pct"] = feature_costs(reps["sensor3"], fov, f_res, f_spps)
    for item in extra["features_2pct"]:
        notes.append("feature @2% broadband: " + ", ".join(f"{k}={v}" for k, v in item.items()))
    notes += feature_notes(variant, f_res, f_spps)
    from workbench.bench.render_noise_scenes import noise_notes, scene_noise_rows
    extra["scene_noise"] = scene_noise_rows(quick)
    for item in extra["scene_noise"]:
        notes.append("scene noise: " + ", ".join(f"{k}={v}" for k, v in item.items()))
    notes += noise_notes(quick)
    notes.append(f"spp = (c/0.02)² with c from the {last} rows; "
                 + (f"--quick: time extrapolated from {cost_spps} spp at 640x480, bytes of that noisier "
                    "frame (an upper bound); " if quick else
                    "the 640x480 frame rendered at that spp (min of 2 seeds), its broadband error measured "
                    "from the two seeds (σ = rms(a−b)/√2); ")
                 + f"core-minutes = wall × all {os.cpu_count()} CPU threads; peak RSS "
                 f"{_peak_rss_mb():.0f} MB (whole process).")
    if getattr(args, "out", None):
        _plot(rows, args.out)
    return BenchResult("spectral render: time and error vs a high-spp reference", rows, notes, extra)


def _plot(rows: list[dict], out: str) -> None:
    from matplotlib.figure import Figure
    os.makedirs(out, exist_ok=True)
    fig = Figure(figsize=(6, 4))                      # its own Agg canvas: no pyplot, no global backend
    ax = fig.subplots()
    for key in sorted({(r["res"], r["repr"]) for r in rows}):
        sel = [r for r in rows if (r["res"], r["repr"]) == key]
        ax.loglog([r["time_s"] for r in sel], [max(r["err_broadband"], 1e-4) for r in sel], "o-", label=" ".join(key))
    ax.set_xlabel("render time (s)")
    ax.set_ylabel("broadband relative RMS error")
    ax.legend(fontsize=7)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, dpi=120, format="png")
    atomic_write_bytes(os.path.join(out, "bench_render.png"), buf.getvalue())
