"""EMVA 1288 photon-transfer characterisation of a simulated sensor.

A uniform single-wavelength (550 nm) optical image is exposed at a series of irradiance levels
(pairs of frames: temporal variance = var(A − B)/2, free of fixed-pattern noise) with a dark
pair at the same exposure; a series of dark pairs at growing exposure gives the dark current.
From these (EMVA 1288 release 3/4 formulas):
  K (DN/e⁻)       slope of σ²_y − σ²_y.dark against μ_y − μ_y.dark over 0–70 % of saturation
  read noise σ_d  √(σ²_y.dark − σ²_q)/K at the light-series exposure, σ²_q = 1/12 DN²
  dark current    slope of μ_y.dark against exposure time / K
  saturation      μ_e.sat = (μ_y − μ_y.dark)/K at the level of maximum temporal variance
  DR              20·log10(μ_e.sat / μ_e.min), μ_e.min = σ_y.dark/K + 1/2 (SNR = 1)
  DSNU, PRNU      spatial variance of the two-frame mean, corrected for its temporal part.
Only the pixels of one CFA channel (the most sensitive at 550 nm) are analysed.

Quantisation: with few bits the read noise is smaller than one code and its estimate is biased
(EMVA asks σ_y.dark ≥ 0.5 DN). Where the dark noise is at or below the step, the dark pairs are
taken again through a FINE_ADC_BITS ADC of the same swing and gain (the higher-resolution
measurement EMVA 1288 allows) and the read noise comes from those; the result says so
('read_noise_bits', 'adc_step_e', a note). A black-level offset of `black_level_fraction` × swing is
added when the configured offset is smaller, so that dark frames do not clip at zero (as the
standard requires); the saturation capacity then refers to the swing above that offset.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.errors import InvalidValueError, ParameterError
from workbench.optics.types import OpticalImage
from workbench.sensor.cfa import cfa_layout, channel_index_map, channel_qe
from workbench.sensor.expose import signal_rate_to_sensor_image
from workbench.sensor.params import SensorParams
from workbench.sensor.signal import irradiance_to_signal_rate

WAVELENGTH_NM = 550.0
FINE_ADC_BITS = 16          # the ADC a read noise hidden by a coarse one is measured through
LINEAR_FIT_FRACTION = 0.7


def _pair_stats(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> tuple[float, float, float]:
    """(mean, temporal variance, spatial variance of the pair mean) over the masked pixels."""
    a64 = a[mask].astype(np.float64)
    b64 = b[mask].astype(np.float64)
    return float((a64.mean() + b64.mean()) / 2), float(np.var(a64 - b64) / 2), float(np.var((a64 + b64) / 2))


def _characterisation_camera(params: SensorParams, size_px: int, black_level_fraction: float) -> SensorParams:
    if params.noise_flag < 1:
        raise InvalidValueError(f"EMVA characterisation needs noise (noise_flag 1 or 2), got noise_flag={params.noise_flag}")
    offset = max(params.analog_offset_V, black_level_fraction * params.voltage_swing_V)
    return SensorParams.model_validate(params.model_dump() | {
        "rows": size_px, "cols": size_px, "analog_offset_V": offset, "exposure_s": None, "ev_bias": 0.0})


MIN_SATURATION_E = 100.0    # fewer electrons above the black level than this: no photon-transfer curve to fit


MIN_ADC_BITS = 6            # fewer codes than 2^6: too few levels below saturation for the photon-transfer fit


def check_measurable(params: SensorParams, saturation_e: float) -> None:
    """ParameterError unless the swing above the black level holds MIN_SATURATION_E electrons (a
    1 µV swing holds 0.01 e⁻: its 'QE' and 'dynamic range' would be fits to quantisation noise) and
    the ADC has MIN_ADC_BITS (a 1-bit ADC has two codes: the fit did not converge)."""
    if params.bit_depth and params.bit_depth < MIN_ADC_BITS:
        raise ParameterError("sensor.bit_depth", params.bit_depth,
                             f"the photon-transfer test needs an ADC of at least {MIN_ADC_BITS} bits (or 0: analog); "
                             "raise bit_depth")
    if saturation_e < MIN_SATURATION_E:
        raise ParameterError(
            "sensor.voltage_swing_V", params.voltage_swing_V,
            f"the swing above the black level holds {saturation_e:.3g} e⁻ (swing − offset over conversion gain × "
            f"analog gain); the photon-transfer test needs at least {MIN_SATURATION_E:g} e⁻: raise "
            "voltage_swing_V, or lower conversion_gain_uV_per_e, analog_gain or analog_offset_V")


def characterize(params: SensorParams, seed: int = 0, *, size_px: int = 256, n_levels: int = 60,
                 n_dark: int = 12, exposure_s: float = 1e-3, black_level_fraction: float = 0.02) -> dict:
    """Run the photon-transfer measurement on `params` and return the EMVA 1288 quantities.

    Figures in electrons refer to the pixel (before analog gain). The result is plain floats and
    lists (JSON-ready); 'configured' holds the values the parameters imply, for comparison."""
    if size_px < 8 or n_levels < 10 or n_dark < 3:
        raise InvalidValueError(f"characterize needs size_px ≥ 8, n_levels ≥ 10, n_dark ≥ 3; got {size_px}, "
                         f"{n_levels}, {n_dark}")
    cam = _characterisation_camera(params, size_px, black_level_fraction)
    rng = np.random.default_rng([seed, 1288])
    wl = np.array([WAVELENGTH_NM])
    tile, names = cfa_layout(cam.cfa_pattern)
    qe = channel_qe(cam, wl)[0]
    k = int(np.argmax(qe))
    if qe[k] <= 0:
        raise InvalidValueError(f"sensor has no response at {WAVELENGTH_NM} nm; cannot run the photon-transfer test")
    mask = channel_index_map(tile, cam.rows, cam.cols) == k
    unit_oi = OpticalImage(np.ones((cam.rows, cam.cols, 1), dtype=np.float32), wl,
                           cam.pixel_pitch_um * 1e-6, 1e-2, 4.0)
    rate_per_irradiance = irradiance_to_signal_rate(unit_oi, cam)          # e⁻/s per (photon/s/m²/nm)
    to_dn = 1.0 / cam.lsb_V if cam.bit_depth else 1.0              # analog: "DN" are volts
    sat_e = (cam.voltage_swing_V - cam.analog_offset_V) / (cam.conversion_gain_V_per_e * cam.analog_gain)
    check_measurable(params, sat_e)
    e_sat = sat_e / (exposure_s * float(rate_per_irradiance[mask].mean()))
    levels = np.unique(np.concatenate([np.linspace(0.0, 0.9, n_levels // 2, endpoint=False),
                                       np.linspace(0.9, 1.3, n_levels - n_levels // 2)]))

    def frame(rate: np.ndarray, t: float) -> np.ndarray:
        return signal_rate_to_sensor_image(rate, cam, t, rng).dn

    zero = np.zeros_like(rate_per_irradiance)
    dark_pairs = [_pair_stats(frame(zero, exposure_s), frame(zero, exposure_s), mask) for _ in range(4)]
    mu_dark = float(np.mean([d[0] for d in dark_pairs]))
    var_dark = float(np.mean([d[1] for d in dark_pairs]))
    spatial_dark = float(np.mean([d[2] for d in dark_pairs]))

    mu_y, var_y, spatial_y, photons = [], [], [], []
    area = cam.pixel_area_m2
    for f in levels:
        rate = rate_per_irradiance * np.float32(f * e_sat)
        m, v, s = _pair_stats(frame(rate, exposure_s), frame(rate, exposure_s), mask)
        mu_y.append(m), var_y.append(v), spatial_y.append(s)
        photons.append(f * e_sat * area * exposure_s)              # photons on the pixel (1 nm band)
    mu_y, var_y, spatial_y, photons = map(np.asarray, (mu_y, var_y, spatial_y, photons))

    i_sat = int(np.argmax(var_y))
    signal = mu_y - mu_dark
    fit = (signal >= 0) & (signal <= LINEAR_FIT_FRACTION * signal[i_sat]) & (np.arange(levels.size) < i_sat)
    if fit.sum() < 3:
        raise InvalidValueError("too few unsaturated levels for the photon-transfer fit")
    gain_dn_per_e, _ = np.polyfit(signal[fit], var_y[fit] - var_dark, 1)
    if not (np.isfinite(gain_dn_per_e) and gain_dn_per_e > 0):
        raise InvalidValueError("characterize: the temporal noise does not grow with the signal (photon-transfer "
                                f"slope {gain_dn_per_e:.3g} DN/e⁻), so no conversion gain can be measured; give the "
                                "sensor a swing of many electrons (sensor.voltage_swing_V, conversion_gain_uV_per_e) "
                                "and shot noise (noise_flag 1 or 2)")
    quant_var = 1.0 / 12.0 if cam.bit_depth else 0.0
    read_noise_e = float(np.sqrt(max(var_dark - quant_var, 0.0)) / gain_dn_per_e)
    hidden = bool(cam.bit_depth) and var_dark <= 2 * quant_var       # the ADC step hides the read noise
    notes = []
    if hidden and cam.bit_depth < FINE_ADC_BITS:
        fine = cam.updated(bit_depth=FINE_ADC_BITS)
        fine_gain = gain_dn_per_e * 2 ** (FINE_ADC_BITS - cam.bit_depth)          # same swing: K scales with codes
        var_fine = float(np.mean([_pair_stats(signal_rate_to_sensor_image(zero, fine, exposure_s, rng).dn,
                                              signal_rate_to_sensor_image(zero, fine, exposure_s, rng).dn, mask)[1]
                                  for _ in range(4)]))
        read_noise_e = float(np.sqrt(max(var_fine - 1.0 / 12.0, 0.0)) / fine_gain)
        notes.append(f"the dark noise ({np.sqrt(var_dark):.2f} DN) is below the {cam.bit_depth}-bit ADC's step "
                     f"({1 / gain_dn_per_e:.3g} e⁻ per DN), which hides the read noise; it was measured through a "
                     f"{FINE_ADC_BITS}-bit ADC of the same swing and gain (EMVA 1288's higher-resolution "
                     f"measurement; {1 / fine_gain:.3g} e⁻ per DN)")
    elif hidden:
        notes.append(f"the dark noise ({np.sqrt(var_dark):.2f} DN) is at or below the ADC's step "
                     f"({1 / gain_dn_per_e:.3g} e⁻ per DN): the read noise cannot be measured and is a lower bound")
    resp, _ = np.polyfit(photons[fit], signal[fit], 1)              # DN per photon = K·η

    dark_t = np.linspace(0.0, min(0.3 * sat_e / cam.dark_current_e_per_s, 3600.0), n_dark) \
        if cam.dark_current_e_per_s > 0 and cam.noise_flag == 2 else np.linspace(0.0, 1.0, n_dark)
    dark_mu = np.array([_pair_stats(frame(zero, t), frame(zero, t), mask)[0] for t in dark_t])
    dark_slope, _ = np.polyfit(dark_t, dark_mu, 1)

    mu_e = signal / gain_dn_per_e
    sigma_y = np.sqrt(np.maximum(var_y, 1e-30))
    sat_capacity_e = float(mu_e[i_sat])
    mu_e_min = np.sqrt(var_dark) / gain_dn_per_e + 0.5
    half = int(np.argmin(np.abs(signal - 0.5 * signal[i_sat])))
    prnu_var = spatial_y[half] - var_y[half] / 2 - (spatial_dark - var_dark / 2)
    dsnu_var = spatial_dark - var_dark / 2
    k_v_per_e = gain_dn_per_e / to_dn
    qe_measured = float(resp / gain_dn_per_e)
    if not (np.isfinite(qe_measured) and qe_measured > 0) or not sat_capacity_e > mu_e_min:
        raise InvalidValueError(
            f"characterize: the measurement is not physical (quantum efficiency {qe_measured:.3g}, saturation "
            f"{sat_capacity_e:.3g} e⁻ against a dark noise floor of {mu_e_min:.3g} e⁻): the sensor's swing must hold "
            "many electrons above its dark noise; raise sensor.voltage_swing_V or lower read_noise_V, "
            "conversion_gain_uV_per_e or analog_gain")
    result = {
        "channel": names[k],
        "wavelength_nm": WAVELENGTH_NM,
        "exposure_s": exposure_s,
        "analog": cam.bit_depth == 0,
        "conversion_gain_DN_per_e": float(gain_dn_per_e) if cam.bit_depth else None,
        "conversion_gain_uV_per_e": float(k_v_per_e / cam.analog_gain * 1e6),
        "read_noise_e": read_noise_e,
        "dark_current_e_per_s": float(dark_slope / gain_dn_per_e),
        "saturation_capacity_e": sat_capacity_e,
        "dynamic_range_dB": float(20 * np.log10(sat_capacity_e / mu_e_min)),
        "snr_max_dB": float(20 * np.log10(np.max(signal[: i_sat + 1] / sigma_y[: i_sat + 1]))),
        "quantum_efficiency": qe_measured,
        "dsnu_e": float(np.sqrt(max(dsnu_var, 0.0)) / gain_dn_per_e),
        "prnu_pct": float(100 * np.sqrt(max(prnu_var, 0.0)) / max(signal[half], 1e-30)),
        "black_level_V": cam.analog_offset_V,
        "adc_step_e": float(1 / gain_dn_per_e) if cam.bit_depth else None,
        "read_noise_bits": (FINE_ADC_BITS if hidden and cam.bit_depth < FINE_ADC_BITS else cam.bit_depth) or None,
        "read_noise_is_lower_bound": hidden and cam.bit_depth >= FINE_ADC_BITS,
        "notes": notes,
        "configured": {
            "conversion_gain_uV_per_e": params.conversion_gain_uV_per_e,
            "conversion_gain_DN_per_e": (cam.conversion_gain_V_per_e * cam.analog_gain / cam.lsb_V
                                         if cam.bit_depth else None),
            "read_noise_e": params.read_noise_e if params.noise_flag == 2 else 0.0,
            "dark_current_e_per_s": params.dark_current_e_per_s if params.noise_flag == 2 else 0.0,
            "saturation_capacity_e": float(sat_e),
            "full_well_e": params.full_well_e,
            "quantum_efficiency": float(qe[k] * cam.fill_factor),
        },
        "series": {
            "photons": photons.tolist(), "mean_dn": mu_y.tolist(), "temporal_var_dn2": var_y.tolist(),
            "dark_mean_dn": mu_dark, "dark_var_dn2": var_dark, "mean_e": mu_e.tolist(),
            "snr": (np.maximum(signal, 0) / sigma_y).tolist(), "fit_mask": fit.tolist(),
            "saturation_index": i_sat, "dark_exposure_s": dark_t.tolist(), "dark_series_dn": dark_mu.tolist(),
        },
    }
    return result


def plot_photon_transfer(result: dict, path_png: str | Path) -> Path:
    """Photon-transfer curve, SNR curve and dark signal against exposure, as a PNG (Agg), written
    atomically (a full disk leaves no partial file and names it)."""
    import io

    from matplotlib.figure import Figure

    from workbench.files import atomic_write_bytes
    fig = Figure(figsize=(13, 4), layout="constrained")
    draw_photon_transfer(result, fig)
    buf = io.BytesIO()
    fig.savefig(buf, dpi=100, format="png")
    return atomic_write_bytes(path_png, buf.getvalue())


def draw_photon_transfer(result: dict, fig) -> None:
    """Draw the photon-transfer, SNR and dark-signal charts of `result` on a matplotlib Figure."""
    s = result["series"]
    unit = "V" if result["analog"] else "DN"
    mean = np.asarray(s["mean_dn"]) - s["dark_mean_dn"]
    var = np.asarray(s["temporal_var_dn2"]) - s["dark_var_dn2"]
    fit = np.asarray(s["fit_mask"], dtype=bool)
    k = result["conversion_gain_uV_per_e"]
    ax1, ax2, ax3 = fig.subplots(1, 3)
    ax1.plot(mean, var, "o", ms=3, label="measured")
    slope = np.polyfit(mean[fit], var[fit], 1)
    ax1.plot(mean[fit], np.polyval(slope, mean[fit]), "-", label=f"fit (K → {k:.2f} µV/e⁻)")
    ax1.axvline(mean[s["saturation_index"]], ls=":", c="gray", label="saturation")
    ax1.set(xlabel=f"μ_y − μ_dark ({unit})", ylabel=f"σ²_y − σ²_dark ({unit}²)", title="Photon transfer")
    ax1.legend()
    mu_e = np.asarray(s["mean_e"])
    ok = (mu_e >= 1.0) & (np.arange(mu_e.size) <= s["saturation_index"])     # below 1 e⁻ is quantisation
    ax2.loglog(mu_e[ok], np.asarray(s["snr"])[ok], "o", ms=3, label="measured")
    model = mu_e[ok] / np.sqrt(result["read_noise_e"] ** 2 + mu_e[ok])
    ax2.loglog(mu_e[ok], model, "-", label="shot + read noise")
    ax2.set(xlabel="signal (e⁻)", ylabel="SNR", title=f"SNR (max {result['snr_max_dB']:.1f} dB, "
                                                         f"DR {result['dynamic_range_dB']:.1f} dB)")
    ax2.legend()
    ax3.plot(s["dark_exposure_s"], s["dark_series_dn"], "o-", ms=3)
    ax3.set(xlabel="exposure (s)", ylabel=f"dark mean ({unit})",
            title=f"Dark current {result['dark_current_e_per_s']:.3g} e⁻/s")
