"""Image sensor: pixel, CFA, spectral QE, noise, exposure and auto-exposure, ADC; EMVA 1288 checks.

    rate = irradiance_to_signal_rate(oi, params)               # mean e⁻/s per pixel (cacheable)
    t = auto_exposure(rate, params)                             # or params.exposure_s
    img = signal_rate_to_sensor_image(rate, params, t, rng)    # one noisy frame → SensorImage
    img = irradiance_to_sensor_image(oi, params, seed)         # all of the above
"""
from workbench.sensor.auto_exposure import AUTO_EXPOSURE_METHODS, auto_exposure, register_auto_exposure, \
    resolve_exposure
from workbench.sensor.cfa import cfa_layout, channel_index_map, channel_qe
from workbench.sensor.compute import irradiance_to_sensor_image
from workbench.sensor.expose import fixed_patterns, signal_rate_to_sensor_image
from workbench.sensor.image import SensorImage
from workbench.sensor.params import CFA_PATTERNS, MAX_PIXELS, SENSOR_PRESETS, SensorParams
from workbench.sensor.signal import REGRID_METHODS, channel_weights, irradiance_to_signal_rate
from workbench.sensor.snr import sensor_dynamic_range, snr_dB

__all__ = [
    "AUTO_EXPOSURE_METHODS", "CFA_PATTERNS", "MAX_PIXELS", "REGRID_METHODS", "SENSOR_PRESETS",
    "SensorImage", "SensorParams", "auto_exposure", "cfa_layout", "channel_index_map", "channel_qe",
    "channel_weights", "fixed_patterns", "irradiance_to_sensor_image", "irradiance_to_signal_rate",
    "register_auto_exposure", "resolve_exposure", "sensor_dynamic_range", "signal_rate_to_sensor_image", "snr_dB",
]
