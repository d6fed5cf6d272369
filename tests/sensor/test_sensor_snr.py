"""snr_dB against the noise the sensor actually draws: a flat field's measured SNR (across pixels,
input-referred, before quantisation) matches the formula for every noise_flag; and an analog
read-out (lsb_V = 1) outputs its volts as DN."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sensor_helpers import make_params
from workbench.sensor import signal_rate_to_sensor_image, snr_dB


@pytest.mark.parametrize("flag, changes", [
    (1, {}),
    (2, {}),
    (2, {"prnu_sigma_pct": 3.0, "dsnu_sigma_V": 2e-3, "column_fpn_offset_sigma_V": 3e-3,
         "column_fpn_gain_sigma_pct": 2.0, "analog_gain": 2.0}),
])
def test_flat_field_snr_matches_the_noise_model(flag, changes):
    p = make_params(rows=400, cols=400, noise_flag=flag, bit_depth=0, analog_offset_V=0.0, **changes)
    exposure_s, mean_e = 0.05, 2000.0
    img = signal_rate_to_sensor_image(np.full((p.rows, p.cols), mean_e / exposure_s, np.float32), p, exposure_s,
                                      np.random.default_rng(3))
    e_in = img.volts.astype(np.float64) / (p.analog_gain * p.conversion_gain_V_per_e)   # input-referred e⁻
    assert np.all(img.volts < p.voltage_swing_V)                                         # nothing clipped
    signal = e_in.mean() - (p.dark_current_e_per_s * exposure_s if flag == 2 else 0.0)
    measured = 20 * math.log10(signal / e_in.std())
    assert snr_dB(mean_e, p, exposure_s) == pytest.approx(measured, abs=0.15)


def test_snr_is_undefined_without_noise_or_signal_and_the_report_follows_noise_flag():
    assert math.isnan(snr_dB(1000.0, make_params(noise_flag=0), 0.01))
    assert math.isnan(snr_dB(1000.0, make_params(noise_flag=-1), 0.01))
    assert math.isnan(snr_dB(0.0, make_params(noise_flag=2), 0.01))
    shot = snr_dB(1000.0, make_params(noise_flag=1), 0.01)
    assert shot == pytest.approx(30.0)                                                   # √1000 → 30 dB
    assert snr_dB(1000.0, make_params(noise_flag=2, read_noise_V=5e-3), 0.01) < shot


def test_analog_read_out_codes_are_volts():
    p = make_params(rows=8, cols=8, noise_flag=0, bit_depth=0)
    assert p.lsb_V == 1.0 and p.max_dn == p.voltage_swing_V
    img = signal_rate_to_sensor_image(np.full((8, 8), 1e5, np.float32), p, 0.01)
    np.testing.assert_array_equal(img.dn, img.volts)                                    # DN = volts
    assert 0 < img.volts.mean() < 1.0                                                    # not rounded to 0/1 V
    digital = make_params(rows=8, cols=8, noise_flag=0, bit_depth=10)
    assert digital.lsb_V == pytest.approx(digital.voltage_swing_V / 1024)
