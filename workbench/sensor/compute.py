"""The whole sensor stage: optical image → SensorImage (ISETCam sensorCompute)."""
from __future__ import annotations

import numpy as np

from workbench.optics.types import OpticalImage
from workbench.sensor.auto_exposure import resolve_exposure
from workbench.sensor.expose import signal_rate_to_sensor_image
from workbench.sensor.image import SensorImage
from workbench.sensor.params import SensorParams
from workbench.sensor.signal import colour_wavelengths_nm, irradiance_to_signal_rate


def irradiance_to_sensor_image(oi: OpticalImage, params: SensorParams, seed: int | None = None) -> SensorImage:
    """Irradiance → mean e⁻/s per pixel → exposure (auto if params.exposure_s is None) → one frame.

    seed: temporal-noise seed (default params.seed); the fixed patterns always follow params.seed,
    so frames with different seeds are different captures by the same sensor."""
    rate = irradiance_to_signal_rate(oi, params)
    exposure_s = resolve_exposure(rate, params)
    rng = np.random.default_rng([params.seed if seed is None else seed, 2])
    image = signal_rate_to_sensor_image(rate, params, exposure_s, rng, wavelengths_nm=colour_wavelengths_nm(oi))
    image.meta["mean_signal_rate_e_per_s"] = float(rate.mean(dtype=np.float64))
    return image
