"""A camera design's numbers: read-outs of one frame, and the standard measurements of the camera
on test charts (camera_metrics), the figures `workbench metrics`, `compare` and `study` report.

frame_readouts(image, signal_rate, sensor, labels): exposure, analog gain, mean electrons per channel, the share of
clipped pixels, and for a city frame the SNR at the road users (the noise model's SNR at each
kept box's mean signal; the median over boxes and the share below SNR 10).

camera_metrics(project): the project's camera (optics, sensor, ISP) in front of charts it builds
from the project: the slanted edge (ISO 12233 e-SFR, flat-fielded by a uniform chart through the same
optics, so lens fall-off cannot lift the curve: on each raw channel's own sites at full resolution
with that plane's Nyquist and the closed form optics × pixel beside it, the demosaiced G plane, the
sRGB luminance; MTF50 with its bootstrap standard deviation, MTF at 0.25 and at Nyquist; and the
optics' MTF from its model and the pixel aperture's, metrics.mtf_model), the uniform
field at a series of exposures (SNR against signal per channel, with the model's; and, for the
headline 'snr_at_10pct_full_well_dB', one capture per channel exposed to put its mean at 10 % of
the electrons at saturation — the full well at analog gain 1, less at higher gain — so no design
is read at another signal than another), and the Macbeth
chart (ΔE2000 per patch of the fitted and of held-out patches, flat-fielded; and the noise of its
six neutral patches per channel). 'dynamic_range_dB' is the sensor's (sensor_dynamic_range: the
electrons at saturation, which analog gain lowers, over the noise floor). Charts are at the
project's scene distance, noise as configured.
Each summary metric's uncertainty is measured: its standard deviation over NOISE_DRAWS more
captures of the same charts with other sensor seeds (other temporal noise and, where the sensor has
it, another unit's fixed-pattern noise; the optics computed once).
"""
from __future__ import annotations

import math

import numpy as np

from workbench.errors import InvalidValueError, ParameterError
from workbench.metrics.bounds import finite_or_none, snr_unbounded_reason
from workbench.metrics.colour import held_out_delta_e, macbeth_delta_e, patch_means
from workbench.metrics.esfr import cfa_plane_nyquist_cy_px, edge_sfr, mtf50, mtf50_spread
from workbench.metrics.mtf_model import optics_mtf, pixel_mtf
from workbench.metrics.noise import snr_model, snr_vs_signal
from workbench.sensor.cfa import channel_index_map
from workbench.sensor.snr import sensor_dynamic_range

ROAD_USERS = ("car", "pedestrian", "bus", "truck")
LOW_SNR = 10.0
SNR_EV_STEPS = tuple(range(-8, 1))     # the uniform field's exposures: auto-exposure × 2^EV
LOW_LIGHT_CD_M2, LOW_LIGHT_EXPOSURE_S = 10.0, 0.01    # the headline SNR: a road at dusk, a 10 ms exposure
LOW_LIGHT_SNR_KEY = "snr_at_10cd_m2_10ms_dB"
COLOUR_CHART_LEVEL = 0.9               # the Macbeth shot's brightest pixels, as a fraction of the swing
NOISE_DRAWS = 4                        # further noise draws of each chart, for the metrics' uncertainty


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


class ChartShots:
    """The pipeline of each chart kind, kept: another noise draw of a design (another sensor seed)
    re-runs only the sensor and the ISP."""

    def __init__(self):
        self._pipelines: dict = {}

    def run(self, chart_project):
        from workbench.pipeline import Pipeline
        pipeline = self._pipelines.get(chart_project.scene.kind)
        if pipeline is None:
            pipeline = self._pipelines[chart_project.scene.kind] = Pipeline(chart_project)
        pipeline.set_project(chart_project)
        return pipeline.run()


MODEL_FREQUENCIES_CY_PX = np.linspace(0.0, 1.0, 101)


def _centre_roi(shape: tuple[int, int]) -> tuple[slice, slice]:
    """The central square, half the shorter side (even-aligned, so CFA phases keep their sites)."""
    h, w = shape
    size = min(h, w) // 2
    r0, c0 = (h // 2 - size // 2) // 2 * 2, (w // 2 - size // 2) // 2 * 2
    return slice(r0, r0 + size), slice(c0, c0 + size)


def reliable_limit_cy_px(nyquist_cy_px: float, oversample: int) -> float:
    """The highest frequency (cycles/pixel) where a plane's e-SFR is trusted: 1.6 × the plane's own
    Nyquist (measured, noise off: raw R and B of slanted_edge_diffraction_f8 and of its 2 µm f/4
    variant, Nyquist 0.25, keep within 0.014 of their closed form up to 0.4 cy/px and miss by
    0.022–0.035 beyond, where their 2-pixel site lattice aliases; raw G, Nyquist 0.5, within 0.009
    up to 0.5), and no further than the optical image's own Nyquist, 0.5 × the scene oversample
    (the simulation folds the optics' OTF above it), nor 1 cy/px."""
    return min(1.6 * nyquist_cy_px, 0.5 * oversample, 1.0)


def _sfr_row(name: str, image: np.ndarray, flat: np.ndarray, oversample: int, mask: np.ndarray | None = None,
             nyquist_cy_px: float = 0.5) -> dict:
    """e-SFR of the central region, flat-fielded, with MTF50's bootstrap spread; frequencies in
    cycles per sensor pixel (the plane's own Nyquist `nyquist_cy_px` and the limit of trust,
    reliable_limit_cy_px, stated beside them)."""
    roi = _centre_roi(image.shape)
    region, flat, mask = image[roi], flat[roi], None if mask is None else mask[roi]
    sfr = edge_sfr(region, mask=mask, flat=flat)
    keep = sfr.frequency_cy_px <= 1.0
    return {"plane": name, "frequency_cy_px": sfr.frequency_cy_px[keep].tolist(), "mtf": sfr.mtf[keep].tolist(),
            "mtf50_cy_px": sfr.mtf50_cy_px, "mtf50_sd_cy_px": mtf50_spread(region, mask=mask, flat=flat),
            "mtf_nyquist": sfr.mtf_at(0.5), "mtf_0.25": sfr.mtf_at(0.25), "nyquist_cy_px": nyquist_cy_px,
            "reliable_up_to_cy_px": reliable_limit_cy_px(nyquist_cy_px, oversample),
            "edge_angle_deg": sfr.edge_angle_deg}


def _model_row(name: str, frequency: np.ndarray, mtf: np.ndarray, note: str) -> dict:
    return {"plane": name, "frequency_cy_px": frequency.tolist(), "mtf": mtf.tolist(),
            "mtf50_cy_px": mtf50(frequency, mtf), "mtf50_sd_cy_px": None,
            "mtf_nyquist": float(np.interp(0.5, frequency, mtf)), "mtf_0.25": float(np.interp(0.25, frequency, mtf)),
            "note": note}


def uniform_chart(project):
    """The project in front of the uniform chart, its light through the optics as it is (the camera
    equation, πT / (1 + 4N²(1 + |m|)²) on axis: optics.formation.geometry), not rescaled:
    noise_series' chart and the slanted edge's flat field."""
    chart = _chart(project, "uniform")
    return chart.updated(scene=chart.scene.updated(adjust_illuminance_lux=None))


def flat_field(project, shape: tuple[int, int], tile: np.ndarray, uniform=None) -> np.ndarray:
    """The chart's flat field: the noise-free signal rate of the uniform chart through the same optics
    and pixels (a dark-subtracted flat averaged over infinitely many frames; `uniform`: that chart's
    pipeline result when already run), each CFA channel's sites divided by their mean so that only
    the optics' shading (cos⁴ fall-off) is left."""
    from workbench.pipeline import Pipeline
    rate = np.asarray(uniform.signal_rate_e_per_s if uniform is not None
                      else Pipeline(uniform_chart(project)).signal_rate(), np.float64)
    if rate.shape != shape:
        raise InvalidValueError(f"metrics: the flat field is {rate.shape}, the slanted-edge image {shape}")
    th, tw = tile.shape
    flat = np.ones_like(rate)
    for i in range(th):
        for j in range(tw):
            sites = rate[i::th, j::tw]
            flat[i::th, j::tw] = sites / sites.mean() if sites.mean() > 0 else 1.0
    return np.where(flat > 0, flat, 1.0)


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


EDGE_CLIPPED_LIMIT = 1e-3   # share of the e-SFR region's pixels at the top code above which the edge is re-exposed


def _edge_region_clipped(image) -> float:
    """The share of the e-SFR region's pixels (_centre_roi) that read the largest code."""
    dn = np.asarray(image.dn)
    return float(np.mean(dn[_centre_roi(dn.shape)] >= image.max_dn))


def edge_shot(project, shots: ChartShots):
    """The slanted-edge chart's pipeline result and how it was exposed ({'exposure_s', 're_exposed',
    'clipped_pct_at_project_exposure', 'note'}): at the project's exposure where that clips at most
    EDGE_CLIPPED_LIMIT of the e-SFR region, else exposed as ISO 12233 asks (an unclipped edge: its
    brightest pixels at COLOUR_CHART_LEVEL of the swing, as the Macbeth shot): a clipped edge's
    sharp corner lifts the MTF above what the optics and pixels allow (EV +1 on the f/8 chart: raw G
    MTF50 0.42 cy/px against a closed-form limit of 0.25). ParameterError naming the exposure where
    the chart is too dark to hold an edge (check_edge_exposed)."""
    chart = _chart(project, "slanted_edge")
    result = shots.run(chart)
    clipped = _edge_region_clipped(result.sensor_image)
    note = "the project's exposure"
    if clipped > EDGE_CLIPPED_LIMIT:
        result = shots.run(chart.updated(sensor=chart.sensor.updated(
            exposure_s=None, ev_bias=0.0, auto_exposure_method="brightest", auto_exposure_level=COLOUR_CHART_LEVEL)))
        note = (f"re-exposed: at the project's exposure {100 * clipped:.1f} % of the edge region clips, and a clipped "
                f"edge lifts the MTF; measured with the chart's brightest pixels at {COLOUR_CHART_LEVEL:.0%} of the "
                "swing (ISO 12233: an unclipped edge)")
    check_edge_exposed(result.sensor_image, project.sensor)
    return result, {"exposure_s": float(np.mean(result.sensor_image.exposure_s)),
                    "re_exposed": clipped > EDGE_CLIPPED_LIMIT, "clipped_pct_at_project_exposure": 100 * clipped,
                    "note": note}


def system_mtf(project, uniform=None, shots: ChartShots | None = None) -> list[dict]:
    """e-SFR rows of the slanted-edge chart seen by the project's camera (exposed by edge_shot:
    re-exposed where the project's exposure clips it; each measured row's 'exposure' says how),
    flat-fielded by a uniform chart through the same optics: each raw channel on its own sites at
    their full-grid positions (black level removed; its closed form optics × pixel beside it as
    model_mtf when the optics has one), the demosaiced G plane, the sRGB luminance; then the optics from its model (pinhole and
    diffraction_limited; other levels have no closed form and no such row) and the pixel aperture
    alone (metrics.mtf_model). uniform: the uniform chart's pipeline result, when already run;
    shots: the kept chart pipelines of a series of noise draws."""
    from workbench.metrics.esfr import MIN_ROWS
    smallest = 2 * MIN_ROWS                                   # the e-SFR region is the central half (_centre_roi)
    if min(project.sensor.rows, project.sensor.cols) < smallest:
        field = "sensor.rows" if project.sensor.rows < smallest else "sensor.cols"
        raise ParameterError(field, getattr(project.sensor, field.split(".")[1]),
                             f"at least {smallest}: the slanted edge is measured on the central half of the frame, "
                             f"which needs {MIN_ROWS} rows and columns")
    result, exposure = edge_shot(project, shots or ChartShots())
    image, isp, sensor = result.sensor_image, result.isp, project.sensor
    tile = np.asarray(image.cfa_tile)
    names = list(image.channel_names)
    flat = flat_field(project, image.dn.shape, tile, uniform)
    pitch_m, os = sensor.pixel_pitch_um * 1e-6, project.scene.oversample
    dn = np.asarray(image.dn, np.float64) - float(image.meta.get("black_level_dn", 0.0))
    th, tw = tile.shape
    layout = np.tile(tile, (dn.shape[0] // th + 1, dn.shape[1] // tw + 1))[:dn.shape[0], :dn.shape[1]]
    rows = []
    for k, name in enumerate(names):                        # every raw channel, on its own sites
        if not np.any(tile == k):
            continue
        nyquist = cfa_plane_nyquist_cy_px(tile, k)
        try:
            row = _sfr_row(f"raw {name}", dn, flat, os, None if np.all(tile == k) else layout == k, nyquist)
        except InvalidValueError as exc:            # a small sensor's plane holds too few sites: said, not fatal
            rows.append({"plane": f"raw {name}", "frequency_cy_px": [], "mtf": [], "mtf50_cy_px": None,
                         "mtf50_sd_cy_px": None, "mtf_nyquist": None, "mtf_0.25": None, "nyquist_cy_px": nyquist,
                         "note": f"not measured: {exc} (a larger sensor, more rows and columns, is needed)"})
            continue
        optics = optics_mtf(result, k, np.asarray(row["frequency_cy_px"]), pitch_m)
        if optics is not None:
            model = optics * pixel_mtf(sensor, np.asarray(row["frequency_cy_px"]), row["edge_angle_deg"])
            row["model_mtf"] = model.tolist()
            row["model_mtf50_cy_px"] = mtf50(np.asarray(row["frequency_cy_px"]), model)
        rows.append(row)
    green = next((n for n in ("G", "C", "W", "M") if n in names), names[0])
    k = names.index(green)
    rows.append(_sfr_row(f"linear {green}", np.asarray(isp.linear[..., k], np.float64), flat, os))
    lin = np.where(isp.srgb <= 0.04045, isp.srgb / 12.92, ((isp.srgb + 0.055) / 1.055) ** 2.4)
    rows.append(_sfr_row("sRGB luminance", lin @ np.array([0.2126, 0.7152, 0.0722]), flat, os))
    for row in rows:
        row["exposure"] = exposure
    f = MODEL_FREQUENCIES_CY_PX
    optics = optics_mtf(result, k, f, pitch_m)
    if optics is not None:
        rows.append(_model_row("optics (model)", f, optics,
                               f"{result.optical_image.meta.get('model')} optics, {green} channel's spectrum"))
    aperture = ("full pitch (microlens)" if sensor.pixel_aperture == "microlens"
                else f"photodiode √FF = {sensor.aperture_width_px:.3f} pitch")
    rows.append(_model_row("pixel aperture (model)", f, pixel_mtf(sensor, f), aperture))
    return rows


def _central_mean(values: np.ndarray, frac: float = 0.5) -> np.ndarray:
    h, w = values.shape[:2]
    dy, dx = max(1, int(h * frac / 2)), max(1, int(w * frac / 2))
    return values[h // 2 - dy:h // 2 + dy, w // 2 - dx:w // 2 + dx].reshape(-1, values.shape[-1]).mean(axis=0)


def _central_half(shape: tuple[int, int]) -> np.ndarray:
    """Boolean mask of the frame's central half in each direction: where the uniform chart is measured."""
    h, w = shape
    region = np.zeros(shape, bool)
    region[h // 4:3 * h // 4, w // 4:3 * w // 4] = True
    return region


def noise_series(project, uniform=None, shots: ChartShots | None = None) -> tuple[list[dict], float]:
    """SNR against signal on the uniform chart (module docstring), and the chart's transfer from
    scene luminance to sensor-plane illuminance (lux per cd/m²: πT / (1 + 4N²(1 + |m|)²) on axis, the
    camera equation of optics.formation.geometry, less off axis);
    each row also holds its sensor-plane exposure (exposure_lux_s). uniform: the pipeline result of
    uniform_chart(project), when already run; the captures' noise is drawn from the sensor's seed."""
    from workbench.sensor import resolve_exposure
    from workbench.spectra import luminance_from_photons
    result = uniform if uniform is not None else (shots or ChartShots()).run(uniform_chart(project))
    rate = result.signal_rate_e_per_s
    t = float(np.mean(resolve_exposure(rate, project.sensor)))
    region = _central_half(rate.shape)
    oi, scene = result.optical_image, result.scene
    lux = float(luminance_from_photons(_central_mean(np.asarray(oi.irradiance_photons, np.float64)), oi.wavelengths_nm))
    nits = float(luminance_from_photons(_central_mean(np.asarray(scene.radiance_photons, np.float64)), scene.wavelengths_nm))
    rows = snr_vs_signal(rate, project.sensor, [t * 2.0 ** ev for ev in SNR_EV_STEPS], region,
                         seed=project.sensor.seed)
    for row in rows:
        row["exposure_lux_s"] = lux * row["exposure_s"]
    return rows, lux / nits


SNR_POINT_OF_SATURATION = 0.1     # the headline SNR's signal: this share of the electrons at saturation


def snr_at_saturation_share(project, uniform,
                            share: float = SNR_POINT_OF_SATURATION) -> tuple[list[dict], str | None]:
    """SNR of the uniform chart captured, per channel, at the exposure that puts that channel's mean
    at `share` of the electrons at saturation (sensor_dynamic_range: the full well at analog gain 1,
    less at higher gain): one capture per channel, measured as noise_series measures (region_noise
    over the central half), its rows with 'exposure_s' and 'target_e' (SNR None, unbounded, with the
    sensor's noise off: a capture without temporal noise has none to measure). ([], why) where no
    channel can be put there (no signal, or the analog offset fills the swing)."""
    from workbench.metrics.noise import region_noise
    from workbench.sensor import signal_rate_to_sensor_image
    sensor = project.sensor
    sensor_range = sensor_dynamic_range(sensor)
    target = share * sensor_range["saturation_e"]
    if not target > 0:
        return [], sensor_range["dynamic_range_limit"]
    rate = np.asarray(uniform.signal_rate_e_per_s, np.float64)
    region = _central_half(rate.shape)
    channel = channel_index_map(np.asarray(uniform.sensor_image.cfa_tile), *rate.shape)
    rows = []
    for k, name in enumerate(uniform.sensor_image.channel_names):
        sel = region & (channel == k)
        mean_rate = float(rate[sel].mean()) if sel.any() else 0.0
        if not mean_rate > 0:
            continue
        t = target / mean_rate
        image = signal_rate_to_sensor_image(rate, sensor, t, np.random.default_rng([sensor.seed, 1000 + k]))
        row = next((r for r in region_noise(image, sensor, region) if r["channel"] == name), None)
        if row is None:
            continue
        if sensor.noise_flag < 1:        # no temporal noise: what spread is left is the codes' steps over the fall-off
            row.update(snr=None, snr_reason=snr_unbounded_reason(sensor))
        rows.append({**row, "exposure_s": t, "target_e": target,
                     "snr_model": finite_or_none(snr_model(row["mean_e"], sensor, t))})
    return rows, None if rows else "undefined (no signal)"


def exposure_figures(noise: list[dict], sensor, lux_per_cd_m2: float) -> dict:
    """On the noise series' green (or first) channel: electrons per lux·s at the sensor plane
    (measured); the SNR of a road at LOW_LIGHT_CD_M2 seen for LOW_LIGHT_EXPOSURE_S and the
    noise-equivalent exposure (lux·s where SNR = 1), both from the read-out's exact statistics at
    that signal (sensor.readout_stats: the closed form's uniform quantisation error was off by up to
    31 % below ~100 e⁻ with an 8-bit ADC); an analog read-out has no codes and keeps the closed form.

    'standard_error': of both, from the robust standard error of the median electrons per lux·s
    (1.2533 × 1.4826 × MAD / √n over the series' unclipped exposures: how well the series pins the
    sensitivity, quantisation's bias at low signal included) carried through each figure."""
    from workbench.sensor.readout_stats import exact_snr
    names = [r["channel"] for r in noise]
    ch = next((n for n in ("G", "C", "W", "M", "Y") if n in names), names[0])
    rows = sorted((r for r in noise if r["channel"] == ch and r["clipped"] == 0 and r["mean_e"] > 0),
                  key=lambda r: r["exposure_lux_s"])
    ratios = np.array([r["mean_e"] / r["exposure_lux_s"] for r in rows])
    e_per_lux_s = float(np.median(ratios))
    rel_se = float(1.2533 * 1.4826 * np.median(np.abs(ratios - e_per_lux_s)) / math.sqrt(ratios.size)
                   / e_per_lux_s) if e_per_lux_s > 0 else 0.0
    at = lux_per_cd_m2 * LOW_LIGHT_CD_M2 * LOW_LIGHT_EXPOSURE_S

    def snr_at(n_e: float, exposure_s: float) -> float:
        return float(exact_snr(n_e, sensor, exposure_s) if sensor.bit_depth else snr_model(n_e, sensor, exposure_s))

    def snr_db(n_e: float) -> float | None:
        snr = snr_at(n_e, LOW_LIGHT_EXPOSURE_S)
        return 20 * float(np.log10(snr)) if 0 < snr < math.inf else None
    snr = snr_at(e_per_lux_s * at, LOW_LIGHT_EXPOSURE_S)
    snr_low = snr_db(e_per_lux_s * at)
    ends = [snr_db(e_per_lux_s * at * (1 + d)) for d in (-rel_se, rel_se)]
    noise_off = sensor.noise_flag < 1
    n_eq = None if noise_off else noise_equivalent_e(lambda n: snr_at(n, 0.0))
    nee = n_eq / e_per_lux_s if e_per_lux_s > 0 and n_eq is not None else None
    out = {"channel": ch, "electrons_per_lux_s": e_per_lux_s, "low_light_exposure_lux_s": at,
           "snr_low_light_dB": snr_low, "noise_equivalent_exposure_lux_s": nee,
           "standard_error": {"electrons_per_lux_s": rel_se * e_per_lux_s,
                              LOW_LIGHT_SNR_KEY: abs(ends[1] - ends[0]) / 2 if None not in ends else None,
                              "noise_equivalent_exposure_lux_s": None if nee is None else rel_se * nee}}
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


def patch_flat_field(project, layout: np.ndarray, shots: ChartShots | None = None) -> np.ndarray:
    """24×K relative illumination of each Macbeth patch's central part in each sensor channel: the
    noise-free signal of the uniform white field through the same optics and sensor (the limit of
    averaging many flat frames), demosaiced as the ISP does, over 1 at the frame's centre. Dividing
    patch means by it takes the lens's fall-off (cos⁴, vignetting, relative illumination) out."""
    from workbench.isp.process import raw_to_linear
    result = (shots or ChartShots()).run(uniform_chart(project))
    rate = np.asarray(result.signal_rate_e_per_s, np.float64)
    image = result.sensor_image
    flat, _ = raw_to_linear((rate / rate.max()).astype(np.float32), image.cfa_tile, list(image.channel_names),
                            "bilinear")
    return patch_means(flat, layout) / _central_mean(np.asarray(flat, np.float64), 0.1)


def check_neutral_5_seen(srgb: np.ndarray, layout: np.ndarray, sensor) -> None:
    """ParameterError naming what to change when the colour chart's neutral 5 comes out black
    (the chart is exposed with white at 90 % of the swing, so it is the read-out that loses it:
    too few ADC codes, or an analog offset above the patch's signal); ΔE is measured against it."""
    from workbench.metrics.colour import NEUTRAL_5
    if float(np.mean(srgb[layout == NEUTRAL_5])) > 0:
        return
    problem = "the Macbeth chart's neutral 5 reads black through this sensor, so no colour error can be measured"
    if sensor.bit_depth and sensor.bit_depth < 8:
        raise ParameterError("sensor.bit_depth", sensor.bit_depth, f"{problem}: too few codes; raise bit_depth")
    raise ParameterError("sensor.analog_offset_V", sensor.analog_offset_V, f"{problem}; lower analog_offset_V or "
                         "raise the signal (analog_gain, voltage_swing_V)")


def colour_error(project, shots: ChartShots | None = None) -> dict:
    """ΔE2000 of the Macbeth chart through the project's camera, exposed as a colour-checker shot
    is: the brightest pixels at 90 % of the swing, so white 9.5 is not clipped. 'fitted' and
    'held_out' (metrics.colour.held_out_delta_e, None without a fitted colour matrix) on
    flat-fielded patch means (patch_flat_field); 'srgb_output': the sRGB frame as rendered (fitted
    matrix, fall-off and gamut clipping included)."""
    from workbench.scene.charts import macbeth_layout
    shots = shots or ChartShots()
    chart = _chart(project, "macbeth")
    chart = chart.updated(sensor=chart.sensor.updated(exposure_s=None, ev_bias=0.0, auto_exposure_method="brightest",
                                                      auto_exposure_level=COLOUR_CHART_LEVEL))
    result = shots.run(chart)
    layout = macbeth_layout(result.isp.srgb.shape[:2])
    check_neutral_5_seen(result.isp.srgb, layout, project.sensor)
    out = {"srgb_output": macbeth_delta_e(result.isp.srgb, layout), "fitted": None, "held_out": None,
           "flat_field": "patch means divided by the noise-free frame of a uniform white field through the same "
                         "optics and sensor (1 at the centre)"}
    if result.isp.colour_fit is not None:
        image = result.sensor_image
        means = patch_means(result.isp.linear, layout) / patch_flat_field(project, layout, shots)
        out.update(held_out_delta_e(means, result.isp.linear, image.qe, image.wavelengths_nm, chart.isp))
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


def _measure(project, shots: ChartShots) -> dict:
    """The measurements of module docstring for one noise draw, with a summary of the headline numbers."""
    uniform = shots.run(uniform_chart(project))          # run once: the edge's flat field and the noise
    mtf, (noise, lux_per_cd_m2) = system_mtf(project, uniform, shots), noise_series(project, uniform, shots)
    colour = colour_error(project, shots)
    by_plane = {r["plane"]: r for r in mtf}
    srgb = by_plane["sRGB luminance"]
    mid, mid_why = snr_at_saturation_share(project, uniform)
    sensor_range = sensor_dynamic_range(project.sensor)
    pitch_mm = project.sensor.pixel_pitch_um * 1e-3
    expo = exposure_figures(noise, project.sensor, lux_per_cd_m2)
    fitted, held = colour["fitted"] or {}, colour["held_out"] or {}
    mid_snr = [r["snr"] for r in mid]
    summary = {"mtf50_cy_px": srgb["mtf50_cy_px"], "mtf50_sd_cy_px": srgb["mtf50_sd_cy_px"],
               "mtf_nyquist": srgb["mtf_nyquist"],
               "mtf50_lp_mm": None if srgb["mtf50_cy_px"] is None else srgb["mtf50_cy_px"] / pitch_mm,
               "snr_at_10pct_full_well_dB": (float(20 * np.log10(np.mean(mid_snr)))
                                             if mid_snr and None not in mid_snr and np.mean(mid_snr) > 0 else None),
               LOW_LIGHT_SNR_KEY: expo["snr_low_light_dB"],
               "noise_equivalent_exposure_lux_s": expo["noise_equivalent_exposure_lux_s"],
               "delta_e_held_out_mean": held.get("mean"), "delta_e_held_out_max": held.get("max"),
               "delta_e_mean": fitted.get("mean"), "delta_e_max": fitted.get("max"),
               "read_noise_e": project.sensor.read_noise_e, "full_well_e": project.sensor.full_well_e,
               "saturation_e": sensor_range["saturation_e"] if sensor_range["saturation_e"] > 0 else None,
               "dynamic_range_dB": sensor_range["dynamic_range_dB"]}
    reasons = {LOW_LIGHT_SNR_KEY: expo.get("null_reasons", {}).get("snr_low_light_dB"),
               "noise_equivalent_exposure_lux_s": expo.get("null_reasons", {}).get("noise_equivalent_exposure_lux_s"),
               "snr_at_10pct_full_well_dB": next((r.get("snr_reason") for r in mid if r["snr"] is None), mid_why),
               "saturation_e": sensor_range["dynamic_range_limit"],
               "dynamic_range_dB": sensor_range["dynamic_range_limit"]}
    null_reasons = {k: why for k, why in reasons.items() if summary[k] is None and why}
    return {"project": project.name, "summary": summary, "null_reasons": null_reasons, "mtf": mtf, "noise": noise,
            "snr_at_saturation_share": mid, "exposure": expo, "colour": colour}


def camera_metrics(project, noise_draws: int = NOISE_DRAWS) -> dict:
    """The measurements of module docstring, with a summary of the headline numbers and each one's
    'uncertainty': its standard deviation over this capture and `noise_draws` more (sensor seeds
    seed + 1 …), 0 for a noise-free camera or a design parameter, None when a draw lacks it; for
    the figures read through the electrons per lux·s the larger of that and exposure_figures'
    standard error."""
    shots = ChartShots()
    out = _measure(project, shots)
    seed = project.sensor.seed
    summaries = [out["summary"]] + [
        _measure(project.updated(sensor=project.sensor.updated(seed=seed + i)), shots)["summary"]
        for i in range(1, noise_draws + 1)]
    spread = {key: float(np.std([s[key] for s in summaries], ddof=1))
              if len(summaries) > 1 and all(s[key] is not None for s in summaries) else None
              for key in out["summary"]}
    own = out["exposure"]["standard_error"]
    out["uncertainty"] = {key: max((v for v in (sd, own.get(key)) if v is not None), default=None)
                          for key, sd in spread.items()}
    out["noise_draws"] = len(summaries)
    return out
