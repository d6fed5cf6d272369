"""The optical image (sensor-plane irradiance) and the optics-model interface."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from workbench.registry import Registry


@dataclass
class OpticalImage:
    """Spectral irradiance on the sensor plane.

    irradiance_photons: H×W×Nλ float32, photons/s/m²/nm, row 0 at the top of the image
        (already flipped upright: the lens inversion is undone, as ISETCam does).
    wavelengths_nm: Nλ wavelengths.
    sample_spacing_m: distance between sample centres on the sensor plane (square samples).
    focal_length_m, f_number: of the optics that formed it (image distance for the pinhole).
    """

    irradiance_photons: np.ndarray
    wavelengths_nm: np.ndarray
    sample_spacing_m: float
    focal_length_m: float
    f_number: float
    depth_m: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        return self.irradiance_photons.shape[:2]

    @property
    def width_m(self) -> float:
        return self.shape[1] * self.sample_spacing_m

    @property
    def height_m(self) -> float:
        return self.shape[0] * self.sample_spacing_m


OPTICS_MODELS: Registry[Callable] = Registry("optics.model", "optics model")
"""The optics levels of detail: name → fn(scene, params, camera=None) -> OpticalImage
(filled by optics.formation); camera: the CameraGeometry the scene was sampled for. The image's
irradiance is a new array the caller may change (stages.optics scales it in place)."""
register_optics = OPTICS_MODELS.register
