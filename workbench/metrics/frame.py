"""A camera design's numbers: read-outs of one frame, and the standard measurements of the camera
on test charts (camera_metrics), the figures `workbench metrics`, `compare` and `study` report.

frame_readouts(image, signal_rate, sensor, labels): exposure, analog gain, mean electrons per channel, the share of
clipped pixels, and for a city frame the SNR at the road users (the noise model's SNR at each
kept box's mean signal; the median over boxes and the share below SNR 10).

camera_metrics(project): the project's camera (optics, sensor, ISP) in front of charts it builds
from the project: the slanted edge (e-SFR on each raw channel's sites, the demosaiced G plane, the sRGB
luminance and, for comparison, the optical image alone: MTF50 and MTF at Nyquist), the uniform
field at a series of exposures (SNR against signal per channel, with the model's), and the Macbeth
chart (ΔE2000 per patch, and the noise of its six neutral patches per channel). Charts are at the project's scene distance, noise as configured.
"""
from __future__ import annotations

import math

import numpy as np

from workbench.errors import ParameterError
from workbench.metrics.bounds import finite_or_none, snr_unbounded_reason
from workbench.metrics.colour import macbeth_delta_e
from workbench.metrics.esfr import edge_sfr
from workbench.metrics.noise import snr_model, snr_vs_signal
from workbench.sensor.snr import noise_floor_e

ROAD_USERS = ("car", "pedestrian", "bus", "truck")
LOW_SNR = 10.0
SNR_EV_STEPS = tuple(range(-8, 1))     # the uniform field's exposures: auto-exposure × 2^EV
LOW_LIGHT_CD_M2, LOW_LIGHT_EXPOSURE_S = 10.0, 0.01    # the headline SNR: a road at dusk, a 10 ms exposure
LOW_LIGHT_SNR_KEY = "snr_at_10cd_m2_10ms_dB"
COLOUR_CHART_LEVEL = 0.9               # the Macbeth shot's brightest pixels, as a fraction of the swing


def _channel_means(values: np.ndarray, tile: np.ndarray, names) -> dict[str, float]:
    """The mean of `values` (H×W) over the sites of each CFA channel: a strided view per tile
    position, summed in float64 (no index planes, no masked copies)."""
    th, tw = tile.shape
    sums, counts = np.zeros(len(names)), np.zeros(len(names), dtype=np.int64)
    for i in range(th):
        for j in range(tw):
            sites = values[i::th, j::tw]
            sums[tile[i, j]] += sites.sum(dtype=np.float64)
            counts[tile[i, j]] += sites.size
    return {name: float(sums[k] / counts[k]) for k, name in enumerate(names) if counts[k]}


def frame_readouts(image, signal_rate_e_per_s: np.ndarray, sensor, labels=None) -> dict:
    """Read-outs of one frame (a SensorImage, its noise-free signal e⁻/s and, for a city frame,
    its labels): module docstring, plus the pixel signal's dynamic range (the 99.9th over the
    0.1th percentile of the noise-free signal of the sensor's pixels, each in its own CFA channel,
    after the optics, in dB): not the scene's luminance dynamic range that `workbench simulate`
    reports (scene/dynamic_range.py), which reads the radiance before the lens and the CFA."""
    exposure = float(np.mean(image.exposure_s))
    rate = np.asarray(signal_rate_e_per_s, np.float64)
    lo, hi = np.percentile(rate, [0.1, 99.9])
    out = {"exposure_s": exposure, "analog_gain": sensor.analog_gain,
           "clipped_pct": float(100 * np.count_nonzero(image.dn >= image.max_dn) / max(image.dn.size, 1)),
           "mean_electrons": _channel_means(image.electrons, np.asarray(image.cfa_tile), image.channel_names),
           "pixel_signal_dynamic_range_dB": float(20 * np.log10(hi / lo)) if lo > 0 else None}
    if labels is not None:
        snrs = []
        for obj in labels.objects:
            if obj.class_name not in ROAD_USERS or obj.visible_px <= 0:
                continue
            x, y, w, h = (int(v) for v in obj.bbox_xywh)
            box = rate[y:y + max(h, 1), x:x + max(w, 1)]
            if box.size:
                snrs.append(float(snr_model(box.mean() * exposure, sensor, exposure)))
        out["road_users"] = len(snrs)
        out["road_user_snr_median"] = finite_or_none(np.median(snrs)) if snrs else None
        if snrs and out["road_user_snr_median"] is None:
            out["road_user_snr_reason"] = snr_unbounded_reason(sensor)
        out["road_user_low_snr_pct"] = float(100 * np.mean(np.asarray(snrs) < LOW_SNR)) if snrs else None
    return out


def _chart(project, kind: str):
    return project.updated(scene=project.scene.updated(kind=kind, fov_deg=None))


def _sfr_row(name: str, image: np.ndarray, px_per_sample: float) -> dict:
    """e-SFR of a region around the chart's centre; frequencies in cycles per sensor pixel."""
    h, w = image.shape
    size = min(h, w) // 2
    roi = image[h // 2 - size // 2:h // 2 + size // 2, w // 2 - size // 2:w // 2 + size // 2]
    sfr = edge_sfr(roi)
    freq = sfr.frequency_cy_px / px_per_sample
    keep = freq <= 1.0
    mtf50 = sfr.mtf50_cy_px
    return {"plane": name, "frequency_cy_px": freq[keep].tolist(), "mtf": sfr.mtf[keep].tolist(),
            "mtf50_cy_px": None if mtf50 is None else mtf50 / px_per_sample,
            "mtf_nyquist": float(np.interp(0.5, freq, sfr.mtf)), "edge_angle_deg": sfr.edge_angle_deg}


MIN_EDGE_CONTRAST_DN = 4     # codes between the edge's dark and bright side below which no e-SFR can be measured


def check_edge_exposed(image, sensor) -> None:
    """ParameterError naming the exposure when the slanted-edge shot is too dark (or too bright) to
    hold an edge: e.g. an exposure of 1e-12 s collects no electrons, and the e-SFR would find only
    flat rows."""
    dn = np.asarray(image.dn, np.float64)
    lo, hi = np.percentile(dn, [5, 95])
    if sensor.bit_depth:                      # a few codes, or a quarter of a coarse ADC's range (1 bit: 2 codes)
        need = min(MIN_EDGE_CONTRAST_DN, image.max_dn / 4)
    else:                                     # analog: volts, a few electrons' worth
        need = MIN_EDGE_CONTRAST_DN * sensor.conversion_gain_V_per_e * sensor.analog_gain
    if hi - lo >= need:
        return
    exposure_s = float(np.mean(image.exposure_s))
    mean_e = float(np.mean(image.electrons))
    clipped = float(np.mean(dn >= image.max_dn))
    problem = ("saturated" if clipped > 0.5 else "too dark") + (
        f": the slanted-edge chart holds {mean_e:.3g} e⁻ per pixel on average at an exposure of {exposure_s:.3g} s, "
        f"less than {need:.3g} {'codes' if sensor.bit_depth else 'V'} of edge contrast, so no MTF can be measured")
    if sensor.exposure_s is not None:
        raise ParameterError("sensor.exposure_s", sensor.exposure_s, f"{problem}; choose an exposure that exposes the "
                             "chart (or null for auto-exposure)")
    raise ParameterError("sensor.max_exposure_s", sensor.max_exposure_s, f"{problem}; raise max_exposure_s, "
                         "auto_exposure_level or the scene's illuminance")


def system_mtf(project) -> list[dict]:
    """e-SFR rows of the slanted-edge chart seen by the project's camera (module docstring)."""
    from workbench.pipeline import Pipeline
    from workbench.spectra import xyz_cmfs
    result = Pipeline(_chart(project, "slanted_edge")).run()
    image, isp = result.sensor_image, result.isp
    check_edge_exposed(image, project.sensor)
    rows = []
    tile = np.asarray(image.cfa_tile)
    names = list(image.channel_names)
    for k, name in enumerate(names):                        # every raw channel, on its own sites
        if not np.any(tile == k):
            continue
        r0, c0 = map(int, np.argwhere(tile == k)[0])
        step = 1 if np.all(tile == k) else tile.shape[0]    # a monochrome tile: every pixel
        rows.append(_sfr_row(f"raw {name}", np.asarray(image.dn, np.float64)[r0::step, c0::step], step))
    green = next((n for n in ("G", "C", "W", "M") if n in names), names[0])
    k = names.index(green)
    rows.append(_sfr_row(f"linear {green}", np.asarray(isp.linear[..., k], np.float64), 1.0))
    lin = np.where(isp.srgb <= 0.04045, isp.srgb / 12.92, ((isp.srgb + 0.055) / 1.055) ** 2.4)
    rows.append(_sfr_row("sRGB luminance", lin @ np.array([0.2126, 0.7152, 0.0722]), 1.0))
    oi = result.optical_image
    y = np.asarray(oi.irradiance_photons, np.float64) @ xyz_cmfs(oi.wavelengths_nm)[:, 1]
    ratio = project.sensor.pixel_pitch_um * 1e-6 / oi.sample_spacing_m      # samples per pixel
    rows.append(_sfr_row("optics alone", y, 1.0 / ratio))
    return rows


def _central_mean(values: np.ndarray, frac: float = 0.5) -> np.ndarray:
    h, w = values.shape[:2]
    dy, dx = max(1, int(h * frac / 2)), max(1, int(w * frac / 2))
    return values[h // 2 - dy:h // 2 + dy, w // 2 - dx:w // 2 + dx].reshape(-1, values.shape[-1]).mean(axis=0)


def noise_series(project) -> tuple[list[dict], float]:
    """SNR against signal on the uniform chart (module docstring), and the chart's transfer from
    scene luminance to sensor-plane illuminance (lux per cd/m²: πT/4N² on axis, less off axis);
    each row also holds its sensor-plane exposure (exposure_lux_s)."""
    from workbench.pipeline import Pipeline
    from workbench.sensor import resolve_exposure
    from workbench.spectra import luminance_from_photons
    chart = _chart(project, "uniform")         # light through the optics as it is (πT/4N²), not rescaled
    result = Pipeline(chart.updated(scene=chart.scene.updated(adjust_illuminance_lux=None))).run()
    rate = result.signal_rate_e_per_s
    t = float(np.mean(resolve_exposure(rate, project.sensor)))
    h, w = rate.shape
    region = np.zeros(rate.shape, bool)
    region[h // 4:3 * h // 4, w // 4:3 * w // 4] = True
    oi, scene = result.optical_image, result.scene
    lux = float(luminance_from_photons(_central_mean(np.asarray(oi.irradiance_photons, np.float64)), oi.wavelengths_nm))
    nits = float(luminance_from_photons(_central_mean(np.asarray(scene.radiance_photons, np.float64)), scene.wavelengths_nm))
    rows = snr_vs_signal(rate, project.sensor, [t * 2.0 ** ev for ev in SNR_EV_STEPS], region)
    for row in rows:
        row["exposure_lux_s"] = lux * row["exposure_s"]
    return rows, lux / nits


def exposure_figures(noise: list[dict], sensor, lux_per_cd_m2: float) -> dict:
    """On the noise series' green (or first) channel: electrons per lux·s at the sensor plane
    (measured); the SNR of a road at LOW_LIGHT_CD_M2 seen for LOW_LIGHT_EXPOSURE_S and the
    noise-equivalent exposure (lux·s where SNR = 1), both from the read-out's exact statistics at
    that signal (sensor.readout_stats: the closed form's uniform quantisation error was off by up to
    31 % below ~100 e⁻ with an 8-bit ADC); an analog read-out has no codes and keeps the closed form."""
    from workbench.sensor.readout_stats import exact_snr
    names = [r["channel"] for r in noise]
    ch = next((n for n in ("G", "C", "W", "M", "Y") if n in names), names[0])
    rows = sorted((r for r in noise if r["channel"] == ch and r["clipped"] == 0 and r["mean_e"] > 0),
                  key=lambda r: r["exposure_lux_s"])
    e_per_lux_s = float(np.median([r["mean_e"] / r["exposure_lux_s"] for r in rows]))
    at = lux_per_cd_m2 * LOW_LIGHT_CD_M2 * LOW_LIGHT_EXPOSURE_S

    def snr_at(n_e: float, exposure_s: float) -> float:
        return float(exact_snr(n_e, sensor, exposure_s) if sensor.bit_depth else snr_model(n_e, sensor, exposure_s))
    snr = snr_at(e_per_lux_s * at, LOW_LIGHT_EXPOSURE_S)
    noise_off = sensor.noise_flag < 1
    n_eq = None if noise_off else noise_equivalent_e(lambda n: snr_at(n, 0.0))
    out = {"channel": ch, "electrons_per_lux_s": e_per_lux_s, "low_light_exposure_lux_s": at,
           "snr_low_light_dB": 20 * float(np.log10(snr)) if 0 < snr < math.inf else None,
           "noise_equivalent_exposure_lux_s": (n_eq / e_per_lux_s if e_per_lux_s > 0 and n_eq is not None
                                               else None)}
    reasons = {}
    if out["snr_low_light_dB"] is None:
        reasons["snr_low_light_dB"] = snr_unbounded_reason(sensor) if snr == math.inf else "undefined (no signal)"
    if out["noise_equivalent_exposure_lux_s"] is None:
        reasons["noise_equivalent_exposure_lux_s"] = (
            "undefined (noise off)" if noise_off
            else "undefined (SNR 1 is not reached up to 1e6 e⁻)" if n_eq is None else "undefined (no signal)")
    return out | ({"null_reasons": reasons} if reasons else {})


def noise_equivalent_e(snr_of, lo_e: float = 1e-3, hi_e: float = 1e6) -> float | None:
    """The smallest signal (e⁻) where snr_of(signal) reaches 1: a geometric bisection from below on
    the first bracket of a log-spaced scan (the exact SNR need not be monotonic); None when it
    never does up to hi_e."""
    grid = np.geomspace(lo_e, hi_e, 121)
    above = next((i for i, n in enumerate(grid) if snr_of(float(n)) >= 1.0), None)
    if above is None:
        return None
    if above == 0:
        return float(grid[0])
    a, b = float(grid[above - 1]), float(grid[above])
    for _ in range(40):
        mid = math.sqrt(a * b)
        a, b = (mid, b) if snr_of(mid) < 1.0 else (a, mid)
    return math.sqrt(a * b)


def colour_error(project) -> dict:
    """ΔE2000 of the Macbeth chart through the project's camera, exposed as a colour-checker shot
    is: the brightest pixels at 90 % of the swing, so white 9.5 is not clipped."""
    from workbench.pipeline import Pipeline
    from workbench.scene.charts import macbeth_layout
    chart = _chart(project, "macbeth")
    chart = chart.updated(sensor=chart.sensor.updated(exposure_s=None, ev_bias=0.0, auto_exposure_method="brightest",
                                                      auto_exposure_level=COLOUR_CHART_LEVEL))
    result = Pipeline(chart).run()
    layout = macbeth_layout(result.isp.srgb.shape[:2])
    out = macbeth_delta_e(result.isp.srgb, layout)
    out["neutral_noise"] = neutral_patch_noise(result.sensor_image, chart.sensor, layout)
    return out


def neutral_patch_noise(image, sensor, layout: np.ndarray) -> list[dict]:
    """region_noise of the central half of each neutral Macbeth patch (white 9.5 … black 2), per
    channel, with the patch's name."""
    from workbench.metrics.colour import PATCH_NAMES
    from workbench.metrics.noise import region_noise
    rows = []
    for k in range(18, 24):
        ys, xs = np.nonzero(layout == k)
        cy, cx = 0.5 * (ys.min() + ys.max()), 0.5 * (xs.min() + xs.max())
        hy, hx = 0.25 * (ys.max() - ys.min() + 1), 0.25 * (xs.max() - xs.min() + 1)
        region = np.zeros(layout.shape, bool)
        region[int(cy - hy):int(cy + hy) + 1, int(cx - hx):int(cx + hx) + 1] = True
        if region.sum() < 16:
            continue
        for row in region_noise(image, sensor, region & (layout == k)):
            row["patch"] = PATCH_NAMES[k]
            row["snr_model"] = finite_or_none(snr_model(row["mean_e"], sensor, float(np.mean(image.exposure_s))))
            rows.append(row)
    return rows


def camera_metrics(project) -> dict:
    """The measurements of module docstring, with a summary of the headline numbers; a summary
    figure with no finite value (an SNR with the noise off) is None and 'null_reasons' says why."""
    mtf, (noise, lux_per_cd_m2), colour = system_mtf(project), noise_series(project), colour_error(project)
    by_plane = {r["plane"]: r for r in mtf}
    srgb = by_plane["sRGB luminance"]
    mid = [r for r in noise if abs(r["mean_e"] - 0.1 * project.sensor.full_well_e) ==
           min(abs(q["mean_e"] - 0.1 * project.sensor.full_well_e) for q in noise)]
    pitch_mm = project.sensor.pixel_pitch_um * 1e-3
    expo = exposure_figures(noise, project.sensor, lux_per_cd_m2)
    mid_snr = [r["snr"] for r in mid]
    floor_e, floor_why = noise_floor_e(project.sensor)
    summary = {"mtf50_cy_px": srgb["mtf50_cy_px"], "mtf_nyquist": srgb["mtf_nyquist"],
               "mtf50_lp_mm": None if srgb["mtf50_cy_px"] is None else srgb["mtf50_cy_px"] / pitch_mm,
               "snr_at_10pct_full_well_dB": (float(20 * np.log10(np.mean(mid_snr)))
                                             if None not in mid_snr and np.mean(mid_snr) > 0 else None),
               LOW_LIGHT_SNR_KEY: expo["snr_low_light_dB"],
               "noise_equivalent_exposure_lux_s": expo["noise_equivalent_exposure_lux_s"],
               "delta_e_mean": colour["mean"], "delta_e_max": colour["max"],
               "read_noise_e": project.sensor.read_noise_e, "full_well_e": project.sensor.full_well_e,
               "dynamic_range_dB": (float(20 * np.log10(project.sensor.full_well_e / floor_e)) if floor_e > 0
                                    else None)}
    reasons = {LOW_LIGHT_SNR_KEY: expo.get("null_reasons", {}).get("snr_low_light_dB"),
               "noise_equivalent_exposure_lux_s": expo.get("null_reasons", {}).get("noise_equivalent_exposure_lux_s"),
               "snr_at_10pct_full_well_dB": next((r.get("snr_reason") for r in mid if r["snr"] is None),
                                                 "undefined (no signal)"),
               "dynamic_range_dB": floor_why}
    null_reasons = {k: why for k, why in reasons.items() if summary[k] is None and why}
    return {"project": project.name, "summary": summary, "null_reasons": null_reasons, "mtf": mtf, "noise": noise,
            "exposure": expo, "colour": colour}
