"""Signal-to-noise ratio of a pixel under the sensor's noise model (the same terms `expose` draws) and
the sensor's own dynamic range."""
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


def noise_floor_e(params: SensorParams) -> tuple[float, str]:
    """(electrons, what sets it) of the dark noise floor a dynamic range is measured against: the
    read noise; with none, the ADC's quantisation noise LSB/√12 (EMVA 1288's σ_q, in electrons at
    the analog gain); (0, 'unbounded …') for an analog read-out without read noise."""
    if params.read_noise_e > 0:
        return params.read_noise_e, "read noise"
    if params.bit_depth:
        return params.lsb_V / (params.conversion_gain_V_per_e * params.analog_gain) / math.sqrt(12.0), \
            "quantisation (no read noise)"
    return 0.0, "unbounded (no read noise and an analog read-out)"


def sensor_dynamic_range(params: SensorParams) -> dict:
    """The sensor's electrons at saturation and its dynamic range.

    saturation_e: the fewest signal electrons whose pixel reads the largest code: volts
    e·g·gain + offset reach (max_dn − ½)·LSB, where rounding gives max_dn (for an analog read-out,
    the voltage swing). full_well_e: swing / conversion gain. dynamic_range_dB:
    20·log10(saturation / noise floor) (noise_floor_e: the read noise in electrons, added before the
    analog gain, so at gain 1 the full well over the read noise, less by the gain above it; with no
    read noise the ADC's quantisation; None when unbounded, 'dynamic_range_limit' says why);
    adc_dB: 20·log10(max_dn) of the code range (None for an analog read-out)."""
    g = params.conversion_gain_V_per_e * params.analog_gain
    clip_V = (params.max_dn - 0.5) * params.lsb_V if params.bit_depth else params.voltage_swing_V
    clip_V = min(clip_V, params.voltage_swing_V)
    saturation_e = (clip_V - params.analog_offset_V) / g
    floor_e, limit = noise_floor_e(params)
    if saturation_e <= 0:
        limit = "undefined (the analog offset fills the swing: no signal reaches the ADC)"
    return {"full_well_e": params.full_well_e, "saturation_e": saturation_e, "read_noise_e": params.read_noise_e,
            "dynamic_range_dB": 20.0 * math.log10(saturation_e / floor_e) if floor_e > 0 and saturation_e > 0
            else None, "dynamic_range_limit": limit,
            "bit_depth": params.bit_depth, "max_dn": params.max_dn,
            "adc_dB": 20.0 * math.log10(params.max_dn) if params.bit_depth else None}
