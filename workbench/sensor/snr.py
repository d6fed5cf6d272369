"""Signal-to-noise ratio of a pixel under the sensor's noise model (the same terms `expose` draws)."""
from __future__ import annotations

import math

from workbench.sensor.params import SensorParams


def snr_dB(mean_e: float, params: SensorParams, exposure_s: float) -> float:
    """20·log10(signal / noise) of a pixel collecting `mean_e` signal electrons in `exposure_s`.

    Noise (input-referred, e⁻²), as signal_rate_to_sensor_image applies it per noise_flag:
    1: photon shot noise (mean_e); 2: also dark-current shot noise, read noise, DSNU, column
    offset FPN, PRNU and column gain FPN (the fixed patterns count: they vary across pixels).
    NaN where the ratio is undefined: a noise-free sensor (noise_flag ≤ 0) or no signal."""
    if params.noise_flag < 1 or not mean_e > 0:
        return math.nan
    var = float(mean_e)
    if params.noise_flag == 2:
        g = params.conversion_gain_V_per_e
        var += (params.dark_current_e_per_s * exposure_s + params.read_noise_e ** 2
                + (params.dsnu_sigma_V / g) ** 2 + (params.column_fpn_offset_sigma_V / g) ** 2
                + (mean_e * params.prnu_sigma_pct / 100) ** 2
                + (mean_e * params.column_fpn_gain_sigma_pct / 100) ** 2)
    return 10.0 * math.log10(mean_e ** 2 / var)
