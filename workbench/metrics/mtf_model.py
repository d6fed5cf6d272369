"""The camera's MTF in closed form, separated into its factors (the slanted edge measures their product).

    optics_mtf(result, channel, frequency_cy_px)   # from the optics model itself, or None
    pixel_mtf(sensor, frequency_cy_px, angle_deg)  # the pixel aperture (SensorParams.pixel_aperture)

optics: the diffraction-limited level's OTF of a circular pupil at its working f-number,
(2/π)(acos s − s√(1 − s²)), s = f λ N_w, averaged over wavelength with the weights the pixel
sums them by: the scene's mean spectral radiance × the channel's effective QE × band width
(photons → electrons); the pinhole's is 1. Other levels have no closed form here (None).
pixel: a square aperture of side a pitches, |sinc(a f cos θ) · sinc(a f sin θ)| across an edge
leaning θ from vertical. Frequencies in cycles per pixel of the sensor.
"""
from __future__ import annotations

import math

import numpy as np

from workbench.units import band_widths_nm

MODELS_WITH_CLOSED_FORM = ("pinhole", "diffraction_limited")


def spectral_weights(result, channel: int) -> np.ndarray:
    """Per wavelength of the optical image: the share of channel `channel`'s electrons (sums to 1)
    for the scene's mean spectrum."""
    scene, image = result.scene, result.sensor_image
    radiance = np.asarray(scene.radiance_photons, np.float64).reshape(-1, scene.radiance_photons.shape[-1]).mean(0)
    w = radiance * np.asarray(image.qe, np.float64)[:, channel] * band_widths_nm(image.wavelengths_nm)
    return w / w.sum()


def optics_mtf(result, channel: int, frequency_cy_px: np.ndarray, pixel_pitch_m: float) -> np.ndarray | None:
    """The optics' MTF from its model, weighted by channel `channel`'s spectrum (module docstring);
    None for a level without a closed form here."""
    from workbench.optics.formation.diffraction import diffraction_mtf
    oi = result.optical_image
    model = oi.meta.get("model")
    f = np.asarray(frequency_cy_px, np.float64)
    if model == "pinhole":
        return np.ones_like(f)
    if model != "diffraction_limited":
        return None
    weights = spectral_weights(result, channel)
    wl_m = np.asarray(result.sensor_image.wavelengths_nm, np.float64) * 1e-9
    n_w = float(oi.meta["working_f_number"])
    return sum(wt * diffraction_mtf(f / pixel_pitch_m, lam, n_w) for wt, lam in zip(weights, wl_m))


def pixel_mtf(sensor, frequency_cy_px: np.ndarray, angle_deg: float = 0.0) -> np.ndarray:
    """|sinc| of the pixel's square aperture (sensor.aperture_width_px pitches) across an edge
    leaning angle_deg from vertical."""
    a = sensor.aperture_width_px
    f = np.asarray(frequency_cy_px, np.float64)
    t = math.radians(angle_deg)
    return np.abs(np.sinc(a * f * math.cos(t)) * np.sinc(a * f * math.sin(t)))
