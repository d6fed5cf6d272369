"""Shared helpers for the sensor tests (imported by name: pytest puts this folder on sys.path)."""
from __future__ import annotations

import numpy as np

from workbench.optics.types import OpticalImage
from workbench.sensor import SENSOR_PRESETS, SensorParams


def make_params(preset: str = "paper_table1", **changes) -> SensorParams:
    """A preset with changes, validated."""
    return SensorParams.model_validate(SENSOR_PRESETS[preset].model_dump() | changes)


def uniform_oi(params: SensorParams, irradiance, wavelengths_nm, spacing_m: float | None = None,
               shape: tuple[int, int] | None = None) -> OpticalImage:
    """Uniform irradiance (photons/s/m²/nm per band) on the pixel grid unless told otherwise."""
    wl = np.asarray(wavelengths_nm, dtype=float)
    h, w = shape or (params.rows, params.cols)
    e = np.broadcast_to(np.asarray(irradiance, dtype=np.float32), (h, w, wl.size)).copy()
    return OpticalImage(e, wl, spacing_m or params.pixel_pitch_um * 1e-6, 4e-3, 4.0)

WL16 = np.linspace(400.0, 700.0, 16)
