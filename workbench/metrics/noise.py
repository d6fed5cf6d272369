"""Noise of the simulated sensor against its signal, per CFA channel, in electrons and DN.

    rows = snr_vs_signal(rate_e_per_s, sensor, exposures_s, region)   # one row per exposure and channel
    snr_model(mean_e, sensor)                                         # shot + read + dark + quantisation

A measurement is one capture of a region the scene fills uniformly (a uniform chart, a Macbeth
patch): per channel, the mean and the standard deviation of its pixels after a fitted quadratic
surface is taken out (vignetting and cos⁴ fall-off are signal, not noise). Electrons are read back from the
digital numbers through the sensor's conversion gain, analog gain and LSB, as a camera engineer
measures them (EMVA 1288's way), so quantisation and clipping are in the figures.
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError
from workbench.metrics.bounds import finite_or_none, measured_snr, snr_unbounded_reason
from workbench.sensor.readout_stats import dn_to_electrons


def _detrended_std(values: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> float:
    """σ about a fitted quadratic surface (cos⁴ fall-off and vignetting are smooth, and radial:
    a plane would leave them in)."""
    y = (ys - ys.mean()) / max(np.ptp(ys), 1)
    x = (xs - xs.mean()) / max(np.ptp(xs), 1)
    a = np.column_stack([np.ones_like(y), y, x, y * y, x * y, x * x])
    coef, *_ = np.linalg.lstsq(a, values, rcond=None)
    return float(np.std(values - a @ coef, ddof=a.shape[1]))


def region_noise(image, sensor, region: np.ndarray) -> list[dict]:
    """Per channel of a SensorImage over a boolean region: mean and σ in DN and e⁻, SNR (None, with
    'snr_reason', where σ is zero: metrics.bounds)."""
    region = np.asarray(region, bool)
    if region.shape != image.dn.shape or region.sum() < 16:
        raise InvalidValueError("noise: the region must match the image and hold at least 16 pixels")
    tile = np.asarray(image.cfa_tile)
    rr, cc = np.indices(image.dn.shape)
    channel = tile[rr % tile.shape[0], cc % tile.shape[1]]
    rows = []
    for k, name in enumerate(image.channel_names):
        sel = region & (channel == k)
        if sel.sum() < 8:
            continue
        ys, xs = np.nonzero(sel)
        dn = np.asarray(image.dn, np.float64)[sel]
        e = dn_to_electrons(dn, sensor)
        mean_e, std_e = float(e.mean()), _detrended_std(e, ys, xs)
        clipped = float(np.mean(dn >= image.max_dn))
        row = {"channel": name, "mean_dn": float(dn.mean()), "std_dn": _detrended_std(dn, ys, xs),
               "mean_e": mean_e, "std_e": std_e, "snr": measured_snr(mean_e, std_e),
               "clipped": clipped, "pixels": int(sel.sum())}
        if row["snr"] is None:                    # no variation: null in JSON, and why
            row["snr_reason"] = snr_unbounded_reason(sensor) if mean_e > 0 else "undefined (no signal, no noise)"
        rows.append(row)
    return rows


def snr_model(mean_e, sensor, exposure_s: float = 0.0) -> np.ndarray:
    """SNR the noise model predicts at a mean signal (e⁻): shot √N, read noise, dark-current shot
    noise and the ADC's quantisation (LSB/√12 in e⁻); inf where there is no noise."""
    n = np.asarray(mean_e, np.float64)
    dark = sensor.dark_current_e_per_s * exposure_s if sensor.noise_flag == 2 else 0.0
    read = sensor.read_noise_e if sensor.noise_flag == 2 else 0.0
    quant = (sensor.lsb_V / (sensor.conversion_gain_V_per_e * sensor.analog_gain)) / np.sqrt(12.0) \
        if sensor.bit_depth else 0.0
    shot = n if sensor.noise_flag >= 1 else 0.0
    noise = np.sqrt(shot + dark + read ** 2 + quant ** 2)
    return np.where(noise > 0, n / np.where(noise > 0, noise, 1.0), np.inf)


def snr_vs_signal(rate_e_per_s: np.ndarray, sensor, exposures_s, region: np.ndarray,
                  seed: int = 0) -> list[dict]:
    """One capture per exposure (sensor.expose from the noise-free rate), measured over `region`:
    rows of region_noise plus 'exposure_s' and the model's SNR at the measured mean."""
    from workbench.sensor import signal_rate_to_sensor_image
    rows = []
    for i, t in enumerate(np.atleast_1d(exposures_s)):
        image = signal_rate_to_sensor_image(rate_e_per_s, sensor, float(t), np.random.default_rng([seed, i]))
        for row in region_noise(image, sensor, region):
            row["exposure_s"] = float(t)
            row["snr_model"] = finite_or_none(snr_model(row["mean_e"], sensor, float(t)))
            rows.append(row)
    return rows
