"""The spectral scene: what a renderer or an analytic chart hands to the optics."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.errors import InvalidValueError


@dataclass
class Scene:
    """Spectral radiance seen from the camera position.

    radiance_photons: H×W×Nλ float32, photons/s/sr/m²/nm, row 0 at the top of the view.
    wavelengths_nm: Nλ wavelengths of the last axis.
    fov_deg: horizontal field of view spanned by the W columns (pixel centres at ±fov/2 edges).
    distance_m: object distance (for the camera equation's magnification, thin-lens focus).
    depth_m: optional H×W distance map along each pixel ray (m); None for flat charts.
    """

    radiance_photons: np.ndarray
    wavelengths_nm: np.ndarray
    fov_deg: float
    distance_m: float = 10.0
    depth_m: np.ndarray | None = None
    name: str = "scene"
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        rad = np.asarray(self.radiance_photons)
        wl = np.asarray(self.wavelengths_nm, dtype=np.float64)
        if rad.ndim != 3 or rad.shape[2] != wl.size:
            raise InvalidValueError(f"scene '{self.name}': radiance must be H×W×Nλ with Nλ = "
                             f"{wl.size} wavelengths, got shape {rad.shape}")
        if not 0 < self.fov_deg < 180:
            raise InvalidValueError(f"scene '{self.name}': fov_deg must be in (0, 180), got {self.fov_deg}")
        if self.distance_m <= 0:
            raise InvalidValueError(f"scene '{self.name}': distance_m must be > 0, got {self.distance_m}")
        if not np.all(np.isfinite(rad)) or np.any(rad < 0):
            raise InvalidValueError(f"scene '{self.name}': radiance has NaN/Inf or negative values")
        self.radiance_photons = rad.astype(np.float32, copy=False)
        self.wavelengths_nm = wl

    @property
    def shape(self) -> tuple[int, int]:
        return self.radiance_photons.shape[:2]
