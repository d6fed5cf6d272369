"""Dynamic range of a view (scene/dynamic_range.py) and of a sensor (sensor.snr.sensor_dynamic_range)
against hand-computed values."""
import numpy as np
import pytest

from workbench.scene.dynamic_range import luminance_dynamic_range, scene_dynamic_range
from workbench.sensor import SENSOR_PRESETS, sensor_dynamic_range
from workbench.spectra import spd_photons_for_luminance


def test_percentile_and_extreme_ratios_of_the_lit_pixels():
    lum = np.concatenate([np.zeros(1000), np.full(5000, 2.0), np.full(5000, 2.0e4), [0.5, 1.0e5]])
    dr = luminance_dynamic_range(lum)
    assert dr["fraction_zero"] == pytest.approx(1000 / lum.size)
    assert dr["low"] == pytest.approx(2.0) and dr["high"] == pytest.approx(2.0e4)   # 0.1 % < 1 of 10,002
    assert dr["ratio"] == pytest.approx(1e4) and dr["dB"] == pytest.approx(80.0)
    assert dr["max_min_ratio"] == pytest.approx(2e5) and dr["max_min_dB"] == pytest.approx(20 * np.log10(2e5))
    assert luminance_dynamic_range(np.zeros(10))["ratio"] is None
    with pytest.raises(ValueError, match="percentiles"):
        luminance_dynamic_range(lum, (50.0, 10.0))


def test_scene_range_is_that_of_its_luminance():
    wl = np.arange(400.0, 701.0, 10.0)
    one = spd_photons_for_luminance(np.ones_like(wl), wl, 1.0)          # 1 cd/m² of an equal-energy white
    radiance = np.stack([one * 3.0, one * 3.0e3])[None]                   # 1×2×Nλ
    dr = scene_dynamic_range(radiance, wl, (0.0, 100.0))
    assert dr["low"] == pytest.approx(3.0) and dr["high"] == pytest.approx(3.0e3) and dr["dB"] == pytest.approx(60.0)


def test_auto_rccc_range_from_its_data_sheet_numbers():
    s = SENSOR_PRESETS["auto_rccc"]                    # 2.8 V swing, 110 µV/e⁻, 1 mV read noise, 10 bits
    dr = sensor_dynamic_range(s)
    assert dr["full_well_e"] == pytest.approx(2.8 / 110e-6)
    assert dr["saturation_e"] == pytest.approx((1023 - 0.5) * 2.8 / 1024 / 110e-6)
    assert dr["read_noise_e"] == pytest.approx(1e-3 / 110e-6)
    assert dr["dynamic_range_dB"] == pytest.approx(20 * np.log10(dr["saturation_e"] / (1e-3 / 110e-6)))
    assert dr["adc_dB"] == pytest.approx(20 * np.log10(1023))
    gained = sensor_dynamic_range(s.updated(analog_gain=4.0, analog_offset_V=0.1))
    assert gained["saturation_e"] == pytest.approx(((1023 - 0.5) * 2.8 / 1024 - 0.1) / (4 * 110e-6))
    quiet = sensor_dynamic_range(s.updated(read_noise_V=0.0))           # no read noise: the ADC step sets the floor
    quantisation_e = 2.8 / 1024 / 110e-6 / np.sqrt(12)
    assert quiet["dynamic_range_dB"] == pytest.approx(20 * np.log10(quiet["saturation_e"] / quantisation_e))
    assert quiet["dynamic_range_limit"] == "quantisation (no read noise)"
    assert sensor_dynamic_range(s.updated(read_noise_V=0.0, bit_depth=0))["dynamic_range_dB"] is None
