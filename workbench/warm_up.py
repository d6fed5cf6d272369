"""Load the compiled pixel kernels before the first edit needs them.

numba loads a kernel from its on-disk cache on the kernel's first call in a process: ~8–10 ms
each (measured: ics_maxima 8.9, bright_sums 8.0, srgb_encode_flat 8.0, colour_pixels 10.4 ms),
which a first white-world edit in the window paid twice. warm_up_pixel_kernels runs the pixel
signal, sensor and ISP paths that reach every kernel once on a 4×4 frame of the project's own
sensor, so the kernels are loaded with the argument types a full frame uses.
"""
from __future__ import annotations

import numpy as np

WARM_UP_PX = 4


def warm_up_pixel_kernels(project) -> None:
    """Run the pixel signal, auto-exposure's mean, the sensor read-out and the ISP (white world with 'max'
    normalisation, the default white balance, and the Malvar demosaic: every ISP kernel) once on
    a WARM_UP_PX × WARM_UP_PX frame of `project`'s sensor."""
    from workbench.isp import sensor_image_to_srgb
    from workbench.optics.types import OpticalImage
    from workbench.sensor import auto_exposure, irradiance_to_signal_rate, signal_rate_to_sensor_image
    from workbench.sensor.cfa import SENSOR_SPECTRAL_GRID_NM

    sensor = project.sensor.updated(rows=WARM_UP_PX, cols=WARM_UP_PX)
    wavelengths_nm = np.arange(400.0, 701.0, 20.0)
    irradiance = np.full((WARM_UP_PX, WARM_UP_PX, wavelengths_nm.size), 1e15, dtype=np.float32)
    irradiance_to_signal_rate(OpticalImage(irradiance, wavelengths_nm, sensor.pixel_pitch_um * 1e-6, 4e-3, 4.0),
                              sensor)                               # on the pixel grid: its compiled path
    rate_e_per_s = np.linspace(1e3, 1e6, WARM_UP_PX * WARM_UP_PX, dtype=np.float32).reshape(WARM_UP_PX, WARM_UP_PX)
    auto_exposure(rate_e_per_s, sensor, "mean")                     # its kernels, whatever the project's method
    image = signal_rate_to_sensor_image(rate_e_per_s, sensor, exposure_s=1e-3, rng=np.random.default_rng(0),
                                        wavelengths_nm=SENSOR_SPECTRAL_GRID_NM)
    sensor_image_to_srgb(image, project.isp.updated(illuminant_correction="white_world", normalize="max"))
    sensor_image_to_srgb(image, project.isp.updated(demosaic="malvar2004"))     # its kernel, on a Bayer tile
