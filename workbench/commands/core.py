"""`workbench simulate`, `workbench characterize` and `workbench demo`: the headless core jobs."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from workbench.files import json_text


def register(sub) -> None:
    p = sub.add_parser("simulate", help="run scene → optics → sensor → ISP and write every stage")
    p.add_argument("project", help="project file (or the name of a sample project)")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("characterize", help="EMVA 1288 photon-transfer analysis of the project's sensor")
    p.add_argument("project")
    p.add_argument("--out", required=True)
    p.set_defaults(func=cmd_characterize)

    p = sub.add_parser("demo", help="the paper's camera on the test charts, with an exposure-bias sweep")
    p.add_argument("--out", default="demo-output")
    p.set_defaults(func=cmd_demo)


def scene_range_report(result, project) -> dict | None:
    """The scene's dynamic range (scene/dynamic_range.py) of the radiance the optics stage took:
    luminance (cd/m²), or for a city through the full lens model the film's illuminance (lx);
    None when the render holds the sensor's channels instead of a spectrum."""
    from workbench.render.city_frame import uses_full_lens_model
    from workbench.scene.dynamic_range import scene_dynamic_range
    scene = result.scene
    if scene.meta.get("representation") == "sensor":
        return None
    full = project.scene.kind == "city" and uses_full_lens_model(project.optics)
    return {"quantity": "film illuminance (lx)" if full else "luminance (cd/m2)",
            **scene_dynamic_range(scene.radiance_photons, scene.wavelengths_nm)}


def stage_report(result, project) -> dict:
    """Exposure, mean electrons and SNR per channel, clipped fraction, the scene's and the
    sensor's dynamic range, per-stage time."""
    from workbench.sensor import sensor_dynamic_range, snr_dB
    img = result.sensor_image
    exposure_s = float(np.mean(img.exposure_s))
    channels = {}
    for k, name in enumerate(img.channel_names):
        mask = img.channel_mask(k)
        if not mask.any():
            continue
        e_mean = float(img.electrons[mask].mean())
        snr = snr_dB(e_mean, project.sensor, exposure_s)
        channels[name] = {
            "mean_electrons": e_mean,
            "mean_dn": float(img.dn[mask].mean()),
            "snr_dB": None if np.isnan(snr) else snr,
            "fraction_clipped": float((img.dn[mask] >= img.max_dn).mean()),
        }
        if np.isnan(snr):                        # null, and why (metrics.bounds)
            channels[name]["snr_reason"] = ("unbounded (noise off)" if project.sensor.noise_flag < 1
                                            else "undefined (no signal)")
    exposure = img.exposure_s
    scene_range, sensor_range = scene_range_report(result, project), sensor_dynamic_range(project.sensor)
    exceeds = None
    if scene_range is not None and scene_range["dB"] is not None and sensor_range["dynamic_range_dB"] is not None:
        exceeds = scene_range["dB"] > sensor_range["dynamic_range_dB"]
    return {
        "project": project.name,
        "exposure_s": exposure.tolist() if isinstance(exposure, np.ndarray) else float(exposure),
        "channels": channels,
        "fraction_clipped": float((img.dn >= img.max_dn).mean()),
        "fraction_zero": float((img.dn <= 0).mean()),
        "scene_dynamic_range": scene_range,
        "sensor_dynamic_range": sensor_range,
        "scene_exceeds_sensor_range": exceeds,
        "stage_times_s": {k: round(v, 6) for k, v in result.stage_times_s.items()},
        "isp_notes": list(getattr(result.isp, "notes", []) or []),
    }


# Every file `write_outputs` may write; one an earlier run wrote but this run does not is removed.
SIMULATE_OUTPUTS = ("irradiance.png", "labels.png", "raw.png", "linear.png", "srgb.png", "stages.npz",
                    "report.json")


def remove_stale_outputs(out: Path, written: set[str]) -> list[str]:
    """Remove the files of SIMULATE_OUTPUTS in `out` that are not in `written` (left by an earlier,
    different run, e.g. a city's labels.png before a chart run); return their names."""
    stale = [name for name in SIMULATE_OUTPUTS if name not in written and (out / name).is_file()]
    for name in stale:
        (out / name).unlink()
    return stale


def write_outputs(result, project, out: Path) -> dict:
    """PNG previews, stages.npz (arrays with units and wavelengths) and report.json, written as one
    group (files.atomic_write_files: all or none, the report last); outputs of an earlier run that
    this one does not replace are removed (named in report['removed_stale']). The caller holds
    the folder's lock (compute.folder_lock)."""
    import io

    from workbench.files import atomic_write_files, prepare_output_folder
    from workbench.previews import channels_to_rgb, irradiance_preview, png01, png_bytes
    prepare_output_folder(out)
    oi, img, isp = result.optical_image, result.sensor_image, result.isp
    preview = irradiance_preview(oi.irradiance_photons, oi.wavelengths_nm, oi.meta)
    files = {out / "irradiance.png": png_bytes(png01(preview))}
    labels = getattr(result, "labels", None)
    if labels is not None:
        from workbench.commands.render import label_overlay
        files[out / "labels.png"] = png_bytes(label_overlay(preview, labels))
    files[out / "raw.png"] = png_bytes(png01(isp.raw))
    files[out / "linear.png"] = png_bytes(png01(channels_to_rgb(isp.linear, img.channel_names)))
    files[out / "srgb.png"] = png_bytes(png01(isp.srgb))
    units = {
        "scene_radiance": "photons/s/sr/m^2/nm", "wavelengths": "nm",
        "irradiance": "photons/s/m^2/nm", "signal_rate": "electrons/s per pixel (noise-free)",
        "electrons": "electrons", "volts": "V", "dn": "digital numbers" if project.sensor.bit_depth else "V",
        "raw": "mosaic / max_dn", "linear": "demosaiced sensor channels, [0,1]",
        "srgb": "sRGB encoded, [0,1]", "sample_spacing_m": "m",
    }
    arrays = dict(scene_radiance=result.scene.radiance_photons, wavelengths=oi.wavelengths_nm,
                  irradiance=oi.irradiance_photons, signal_rate=result.signal_rate_e_per_s,
                  electrons=img.electrons, volts=img.volts, dn=img.dn, raw=isp.raw,
                  linear=isp.linear, srgb=isp.srgb, sample_spacing_m=np.float64(oi.sample_spacing_m),
                  channel_names=np.array(img.channel_names), units=np.array(json.dumps(units)))
    npz = io.BytesIO()
    np.savez_compressed(npz, **arrays)
    files[out / "stages.npz"] = npz.getvalue()
    report = stage_report(result, project)
    written = set(SIMULATE_OUTPUTS) - ({"labels.png"} if labels is None else set())
    if labels is not None:
        counts: dict[str, int] = {}
        for o in labels.objects:
            if o.visible_px:
                counts[o.class_name] = counts.get(o.class_name, 0) + 1
        report["visible_objects"] = counts
    report["removed_stale"] = [name for name in SIMULATE_OUTPUTS if name not in written and (out / name).is_file()]
    files[out / "report.json"] = (json_text(report, indent=2) + "\n").encode()
    atomic_write_files(files)                         # the report last: it describes the others
    remove_stale_outputs(out, written)
    return report


def warn_long_render(project) -> None:
    """Print render.city_frame.long_render_note on stderr when there is one."""
    from workbench.render.city_frame import long_render_note
    note = long_render_note(project)
    if note:
        print(note, file=sys.stderr, flush=True)


def cmd_simulate(args: argparse.Namespace) -> int:
    from workbench.jobs import run_job, tqdm_progress
    from workbench.pipeline import Pipeline
    from workbench.project import load_project
    from workbench.compute.folder_lock import hold_folder_lock
    from workbench.files import prepare_output_folder
    project = load_project(args.project)
    prepare_output_folder(args.out)          # refuse a bad --out before the run, not after
    warn_long_render(project)
    with hold_folder_lock(args.out, "workbench simulate"):     # a second run here is refused, not mixed in
        bar = tqdm_progress("simulate")
        try:
            result = run_job(Pipeline(project).run_job(), bar)
        finally:
            bar.close()
        report = write_outputs(result, project, Path(args.out))
    print(json_text({k: report[k] for k in ("exposure_s", "fraction_clipped", "stage_times_s")}, indent=2))
    scene_range, sensor_range = report["scene_dynamic_range"], report["sensor_dynamic_range"]
    if report["scene_exceeds_sensor_range"] is not None:          # both ranges known
        print(f"scene dynamic range {scene_range['dB']:.1f} dB (p{scene_range['percentiles'][1]:g}/"
              f"p{scene_range['percentiles'][0]:g} {scene_range['quantity']}), sensor "
              f"{sensor_range['dynamic_range_dB']:.1f} dB (saturation / read noise); "
              f"{100 * report['fraction_clipped']:.2f} % of pixels clipped")
    extra = " labels.png" if result.labels is not None else ""
    for name in report["removed_stale"]:
        print(f"removed {args.out}/{name}: left by an earlier run, not written by this one")
    print(f"wrote {args.out}/: irradiance.png{extra} raw.png linear.png srgb.png stages.npz report.json")
    return 0


def cmd_characterize(args: argparse.Namespace) -> int:
    from workbench.files import atomic_write_text, prepare_output_folder
    from workbench.project import load_project
    from workbench.sensor.emva import characterize, plot_photon_transfer
    from workbench.compute.folder_lock import hold_folder_lock
    project = load_project(args.project)
    out = prepare_output_folder(args.out)
    with hold_folder_lock(out, "workbench characterize"):     # a second run here is refused, not mixed in
        result = characterize(project.sensor, seed=project.seed)
        atomic_write_text(out / "emva.json", json_text(result, indent=2) + "\n")
        plot_photon_transfer(result, out / "photon_transfer.png")
    summary = {k: v for k, v in result.items() if not isinstance(v, (list, dict))}
    print(json_text(summary, indent=2))
    for note in result.get("notes", []):
        print(f"note: {note}")
    print(f"wrote {out}/emva.json and {out}/photon_transfer.png")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """The paper's camera on the Macbeth chart, the slanted edge and the HDR tunnel, then the
    paper's exposure-bias sweep (EV −4…+4 around the 'mean' auto-exposure at 0.4 of the swing)."""
    from workbench.pipeline import Pipeline
    from workbench.files import prepare_output_folder
    from workbench.project import load_project
    from workbench.compute.folder_lock import hold_folder_lock
    out = prepare_output_folder(args.out)
    base = load_project("paper_camera")
    t0 = time.perf_counter()
    rows = []
    for kind in ("macbeth", "slanted_edge", "hdr_tunnel"):
        project = base.updated(scene=base.scene.updated(kind=kind))
        result = Pipeline(project).run()
        with hold_folder_lock(prepare_output_folder(out / kind), "workbench demo"):
            report = write_outputs(result, project, out / kind)
        rows.append((kind, report))
        print(f"{kind:13s} exposure {1e3 * float(np.mean(report['exposure_s'])):8.3f} ms  "
              f"clipped {100 * report['fraction_clipped']:5.1f} %  -> {out / kind}")
    sweep = ev_sweep(base, out / "ev_sweep")
    print("EV bias sweep (Macbeth chart, 'mean' auto-exposure at 0.4 of the swing):")
    for r in sweep:
        print(f"  EV {r['ev']:+.0f}: exposure {1e3 * r['exposure_s']:8.3f} ms  mean DN {r['mean_dn']:6.1f}  "
              f"clipped {100 * r['fraction_clipped']:5.1f} %")
    print(f"demo done in {time.perf_counter() - t0:.1f} s; open {out}/*/srgb.png")
    return 0


def ev_sweep(project, out: Path) -> list[dict]:
    """The project's EV biases on its frame (workbench.experiments.ev_sweep); sRGB PNG per EV."""
    from workbench.experiments.ev_sweep import ev_sweep_job
    from workbench.jobs import run_job
    from workbench.pipeline import Pipeline
    from workbench.files import prepare_output_folder
    from workbench.previews import save_png
    prepare_output_folder(out)
    pipe = Pipeline(project)
    points = run_job(ev_sweep_job(project, pipe.signal_rate(), pipe.optical_image().wavelengths_nm,
                                  project.experiment.ev_biases, thumbnail_width_px=project.sensor.cols))
    rows = []
    for p in points:
        save_png(out / f"srgb_ev{p.ev:+.0f}.png", p.thumbnail / 255.0)
        rows.append({"ev": p.ev, "exposure_s": p.exposure_s, "mean_dn": p.mean_dn,
                     "fraction_clipped": p.fraction_clipped, "snr_dB": p.snr_dB})
    return rows
